"""Frictionless contact with analytic rigid obstacles that may move, by the IPC barrier.

- :mod:`.motion`: :class:`RigidMotion`, a prescribed rotation and translation in time;
- :mod:`.obstacle`: :class:`Obstacle`, the signed gap, its derivatives and path crossings;
- :mod:`.half_space`, :mod:`.sphere`, :mod:`.cylinder`, :mod:`.cone`, :mod:`.funnel`: the
  shapes;
- :mod:`.obstacles`: :class:`Obstacles`, several obstacles at once, their path crossings and
  the collision-free step along straight paths;
- :mod:`.barrier`: :class:`Barrier`, the log barrier b(d), and the rules for d̂ and κ;
- :mod:`.potential`: :class:`BarrierPotential`, Σ wᵢ b(d(xᵢ)) with an SPD Hessian;
- :mod:`.boundary`: :class:`BoundaryVertices`, the mesh's boundary vertices and weights;
- :mod:`.term`: :class:`ContactTerm`, the barrier as an energy term of a DOLFINx problem;
- :mod:`.step`: :class:`CollisionFreeStep`, the collision-free Newton step cap.

The modules up to :mod:`.potential` need only NumPy; the last three need DOLFINx and are
imported on first use of their names.
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
from dolfinx_invertible.contact.cone import Cone
from dolfinx_invertible.contact.cylinder import Cylinder
from dolfinx_invertible.contact.funnel import Funnel
from dolfinx_invertible.contact.half_space import HalfSpace
from dolfinx_invertible.contact.motion import RigidMotion
from dolfinx_invertible.contact.obstacle import Obstacle
from dolfinx_invertible.contact.obstacles import Obstacles
from dolfinx_invertible.contact.potential import BarrierPotential, project_blocks
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
    "Funnel",
    "HalfSpace",
    "Obstacle",
    "Obstacles",
    "RigidMotion",
    "Sphere",
    "barrier_distance",
    "barrier_stiffness",
    "project_blocks",
    *_LAZY,
]
