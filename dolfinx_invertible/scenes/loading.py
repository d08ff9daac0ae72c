"""Loading pieces the scenes share: smooth ramps in time and a pressing plate."""

from __future__ import annotations

import math

import dolfinx
import numpy as np
import ufl

__all__ = ["PressingPlate", "smooth_ramp"]


def smooth_ramp(t: float, duration: float) -> float:
    """Return a ramp from 0 at t = 0 to 1 at t = duration with zero rate at both ends."""
    if t <= 0.0:
        return 0.0
    if t >= duration:
        return 1.0
    return 0.5 - 0.5 * math.cos(math.pi * t / duration)


class PressingPlate:
    """A frictionless rigid plate pressing on part of the boundary, then released.

    The plate enforces the normal displacement ``depth(t)`` on the marked facets by a penalty
    potential ½ k ∫ (u·n₀ − depth)² ds with a stiffness k tied to the material
    (``stiffness_factor`` · E / h): stiff enough that the plate is rigid to a fraction of a
    percent, scaled with the material so that the problem stays scale-invariant. Released, the
    stiffness drops to zero and the boundary is free.

    Parameters
    ----------
    mesh
        The mesh.
    facets
        Facets (dimension tdim − 1) the plate touches.
    normal
        The direction the plate pushes (a unit vector, reference configuration).
    youngs_modulus, cell_size
        Scale of the penalty.
    stiffness_factor
        k = stiffness_factor · E / h.
    """

    def __init__(self, mesh, facets, normal, youngs_modulus: float, cell_size: float,
                 stiffness_factor: float = 1.0e3):  # fmt: skip
        tdim = mesh.topology.dim
        tags = dolfinx.mesh.meshtags(mesh, tdim - 1, facets, np.full(len(facets), 7, np.int32))
        self._measure = ufl.Measure("ds", domain=mesh, subdomain_data=tags)(7)
        self._normal = dolfinx.fem.Constant(mesh, np.asarray(normal, dtype=np.float64))
        self._stiffness_value = stiffness_factor * youngs_modulus / cell_size
        self.stiffness = dolfinx.fem.Constant(mesh, self._stiffness_value)
        self.depth = dolfinx.fem.Constant(mesh, 0.0)

    def energy(self, u):
        """Return the penalty potential in ``u`` (UFL)."""
        gap = ufl.dot(u, self._normal) - self.depth
        return 0.5 * self.stiffness * gap * gap * self._measure

    def set(self, depth: float, released: bool) -> None:
        """Set the pressed depth, or release the plate."""
        self.depth.value = depth
        self.stiffness.value = 0.0 if released else self._stiffness_value
