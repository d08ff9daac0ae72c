"""The experiments: the paper's figures and engineering benchmarks, one module per scene.

Each scene is a short declarative subclass of :class:`Scene` on the public API; the command
line runs them (``dolfinx-invertible run SCENE``) through :func:`run_scene`, which writes the
XDMF time series, the step log and ``summary.json``; a :class:`RunObserver` watches a run.
:data:`SCENES` lists them by name.
"""

from __future__ import annotations

import importlib

# The PyPI DOLFINx wheel finds its MPI library only once mpi4py has loaded it: mpi4py first.
from mpi4py import MPI  # noqa: F401

from dolfinx_invertible.scenes.observer import RunObserver
from dolfinx_invertible.scenes.parameters import Parameters, make_material
from dolfinx_invertible.scenes.scene import Scene

__all__ = [
    "SCENES",
    "Parameters",
    "Run",
    "RunObserver",
    "Scene",
    "get_scene",
    "make_material",
    "run_scene",
]

#: Scene name -> "module:class"; imported on first use.
SCENES = {
    "collapse": "collapse:Collapse",
    "scatter": "scatter:Scatter",
    "stretch-bar": "stretch_bar:StretchBar",
    "tet-stretch": "tet_stretch:TetStretch",
    "mattress-2d": "mattress_2d:Mattress2D",
    "triangles-2d": "triangles_2d:Triangles2D",
    "cook-membrane": "cook_membrane:CookMembrane",
    "twisting-column": "twisting_column:TwistingColumn",
    "compress-block": "compress_block:CompressBlock",
    "square-inv-free": "square_inv_free:SquareInversionFree",
    "bowl-drop": "bowl_drop:BowlDrop",
    "cubes-in-bowl": "cubes_in_bowl:CubesInBowl",
    "links": "links:Links",
    "ball-hit": "ball_hit:BallHit",
    "tight-tube": "tight_tube:TightTube",
    "gap-squeeze": "gap_squeeze:GapSqueeze",
}


def get_scene(name: str) -> type[Scene]:
    """Return the scene class called ``name``; ``ValueError`` listing the scenes otherwise."""
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}; the scenes are {', '.join(SCENES)}")
    module, _, cls = SCENES[name].partition(":")
    return getattr(importlib.import_module(f"dolfinx_invertible.scenes.{module}"), cls)


def __getattr__(name: str):
    """Import :class:`Run` (which loads DOLFINx) on first use."""
    if name == "Run":
        from dolfinx_invertible.scenes.run import Run

        return Run
    raise AttributeError(f"module 'dolfinx_invertible.scenes' has no attribute {name!r}")


def run_scene(*args, **kwargs):
    """Run a scene (see :func:`dolfinx_invertible.scenes.runner.run_scene`)."""
    from dolfinx_invertible.scenes.runner import run_scene as run

    return run(*args, **kwargs)
