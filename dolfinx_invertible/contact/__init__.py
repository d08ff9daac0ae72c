"""Frictionless contact with analytic rigid obstacles that may move, by the IPC barrier.

- :mod:`.motion`: :class:`RigidMotion`, a prescribed rotation and translation in time;
- :mod:`.obstacle`: :class:`Obstacle`, the signed gap, its derivatives and path crossings;
- :mod:`.half_space`, :mod:`.sphere`, :mod:`.cylinder`, :mod:`.cone`: the shapes;
- :mod:`.scene`: :class:`Scene`, several obstacles at once;
- :mod:`.barrier`: :class:`Barrier`, the log barrier b(d), and the rules for d̂ and κ;
- :mod:`.potential`: :class:`BarrierPotential`, Σ wᵢ b(d(xᵢ)) with an SPD Hessian;
- :mod:`.ccd`: continuous collision detection on straight paths;
- :mod:`.boundary`: :class:`BoundaryVertices`, the mesh's boundary vertices and weights;
- :mod:`.term`: :class:`ContactTerm`, the barrier as an energy term of a DOLFINx problem;
- :mod:`.step`: :class:`CollisionFreeStep`, the collision-free Newton step cap.

The modules up to :mod:`.ccd` need only NumPy; the last three need DOLFINx and are imported on
first use of their names.
"""

# The PyPI DOLFINx wheel finds its MPI library only once mpi4py has loaded it: mpi4py first.
import importlib

from mpi4py import MPI  # noqa: F401

from dolfinx_invertible.contact.barrier import (
    DEFAULT_DISTANCE_FRACTION,
    HALF_DISTANCE_CURVATURE,
    Barrier,
    barrier_distance,
    barrier_stiffness,
)
from dolfinx_invertible.contact.ccd import collision_free_step, first_crossing
from dolfinx_invertible.contact.cone import Cone
from dolfinx_invertible.contact.cylinder import Cylinder
from dolfinx_invertible.contact.half_space import HalfSpace
from dolfinx_invertible.contact.motion import RigidMotion
from dolfinx_invertible.contact.obstacle import Obstacle
from dolfinx_invertible.contact.potential import BarrierPotential, project_blocks
from dolfinx_invertible.contact.scene import Scene
from dolfinx_invertible.contact.sphere import Sphere

_LAZY = {
    "BoundaryVertices": "dolfinx_invertible.contact.boundary",
    "ContactTerm": "dolfinx_invertible.contact.term",
    "CollisionFreeStep": "dolfinx_invertible.contact.step",
}


def __getattr__(name: str):
    """Import a name of the DOLFINx layer on first use."""
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'dolfinx_invertible.contact' has no attribute {name!r}")


def __dir__() -> list[str]:
    """List the public names, the lazily imported ones included."""
    return sorted(__all__)


__all__ = [
    "DEFAULT_DISTANCE_FRACTION",
    "HALF_DISTANCE_CURVATURE",
    "Barrier",
    "BarrierPotential",
    "Cone",
    "Cylinder",
    "HalfSpace",
    "Obstacle",
    "RigidMotion",
    "Scene",
    "Sphere",
    "barrier_distance",
    "barrier_stiffness",
    "collision_free_step",
    "first_crossing",
    "project_blocks",
    *_LAZY,
]
