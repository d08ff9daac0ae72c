"""Frictionless contact by the IPC barrier: with analytic rigid obstacles, and between bodies.

- :mod:`.motion`: :class:`RigidMotion`, a prescribed rotation and translation in time;
- :mod:`.obstacle`: :class:`Obstacle`, the signed gap, its derivatives and path crossings;
- :mod:`.half_space`, :mod:`.sphere`, :mod:`.cylinder`, :mod:`.cone`, :mod:`.funnel`: the
  shapes;
- :mod:`.obstacles`: :class:`Obstacles`, several obstacles at once, their path crossings and
  the collision-free step along straight paths;
- :mod:`.barrier`: :class:`Barrier`, the log barrier b(d), and the rules for d̂ and κ;
- :mod:`.potential`: :class:`BarrierPotential`, Σ wᵢ b(d(xᵢ)) with an SPD Hessian;
- :mod:`.friction`: :class:`ObstacleFriction`, lagged Coulomb friction against the obstacles;
- :mod:`.boundary`: :class:`BoundaryVertices`, the mesh's boundary vertices and weights;
- :mod:`.term`: :class:`ContactTerm`, the barrier as an energy term of a DOLFINx problem;
- :mod:`.step`: :class:`CollisionFreeStep`, the collision-free Newton step cap;
- :mod:`.surface`: :class:`GatheredSurface`, a distributed mesh's surface on every rank;
- :mod:`.body_contact`: :class:`BodyContactTerm`, contact between and within the bodies of
  one mesh on IPC Toolkit (``ipctk``), and its step cap :class:`SurfaceCollisionFreeStep`.

The modules up to :mod:`.friction` need only NumPy; the others need DOLFINx (and the last
ipctk) and are imported on first use of their names.
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
from dolfinx_invertible.contact.friction import ObstacleFriction
from dolfinx_invertible.contact.funnel import Funnel
from dolfinx_invertible.contact.half_space import HalfSpace
from dolfinx_invertible.contact.motion import RigidMotion
from dolfinx_invertible.contact.obstacle import Obstacle
from dolfinx_invertible.contact.obstacles import Obstacles
from dolfinx_invertible.contact.potential import BarrierPotential, project_blocks
from dolfinx_invertible.contact.sphere import Sphere

_LAZY = {
    "BodyContactTerm": "dolfinx_invertible.contact.body_contact",
    "GatheredSurface": "dolfinx_invertible.contact.surface",
    "SurfaceCollisionFreeStep": "dolfinx_invertible.contact.body_contact",
    "SurfaceIntersectionError": "dolfinx_invertible.contact.body_contact",
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
    "ObstacleFriction",
    "Obstacles",
    "RigidMotion",
    "Sphere",
    "barrier_distance",
    "barrier_stiffness",
    "project_blocks",
    *_LAZY,
]
