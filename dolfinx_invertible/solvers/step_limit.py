"""Inversion-free step limiting (the classical alternative to an invertible energy).

A plain barrier energy such as Neo-Hookean (+∞ at J ≤ 0) is kept feasible by capping each
Newton step before the energy line search: along u + α δu, the volume ratio at a point is the
polynomial det(F + α δF) in α (quadratic in 2D, cubic in 3D). The cap is the largest α ≤ 1 such
that at no quadrature point the volume falls below ``fraction`` (default 10 %) of its current
value; the energy backtracking then works inside that feasible step.
"""

from __future__ import annotations

from typing import Protocol

from mpi4py import MPI

import dolfinx
import numpy as np
import ufl

from dolfinx_invertible import _compat
from dolfinx_invertible.constitutive.compiled import python_callable
from dolfinx_invertible.constitutive.polynomial import first_root_in_unit_interval
from dolfinx_invertible.fem.forms import default_quadrature_degree

__all__ = ["InversionFreeStep", "StepLimit", "volume_polynomial"]


class StepLimit(Protocol):
    """A cap on Newton steps, applied before the energy line search."""

    def largest_step(self, direction, sign: float = 1.0) -> float:
        """Return the largest α ≤ 1 allowed for the motion ``u + α · sign · direction``."""
        ...


@python_callable
def volume_polynomial(F, D):
    """Coefficients (c₀, c₁, c₂, c₃) of det(F + α D) = c₀ + c₁α + c₂α² + c₃α³."""
    if F.shape[0] == 2:
        c0 = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
        c1 = F[0, 0] * D[1, 1] + D[0, 0] * F[1, 1] - F[0, 1] * D[1, 0] - D[0, 1] * F[1, 0]
        c2 = D[0, 0] * D[1, 1] - D[0, 1] * D[1, 0]
        return c0, c1, c2, 0.0
    c0 = 0.0
    c1 = 0.0
    c2 = 0.0
    c3 = 0.0
    for i in range(3):
        i1 = (i + 1) % 3
        i2 = (i + 2) % 3
        for j in range(3):
            j1 = (j + 1) % 3
            j2 = (j + 2) % 3
            cof_F = F[i1, j1] * F[i2, j2] - F[i1, j2] * F[i2, j1]
            cof_D = D[i1, j1] * D[i2, j2] - D[i1, j2] * D[i2, j1]
            # Expanding along row i counts each term of the determinant once per row.
            if i == 0:
                c0 += F[i, j] * cof_F
                c3 += D[i, j] * cof_D
            c1 += D[i, j] * cof_F
            c2 += F[i, j] * cof_D
    return c0, c1, c2, c3


@python_callable
def _largest_step(gradients, sign, fraction):
    """Largest α ≤ 1 keeping det(F + α δF) > fraction · det F at every point.

    ``gradients`` is (points, 2, d, d): ∇u and ∇(direction); δF = sign · ∇(direction).
    """
    d = gradients.shape[2]
    F = np.empty((d, d))
    D = np.empty((d, d))
    step = 1.0
    for p in range(gradients.shape[0]):
        for i in range(d):
            for j in range(d):
                F[i, j] = gradients[p, 0, i, j] + (1.0 if i == j else 0.0)
                D[i, j] = sign * gradients[p, 1, i, j]
        c0, c1, c2, c3 = volume_polynomial(F, D)
        if not c0 > 0.0:
            # Already degenerate here: no feasible step is known, so take none.
            return 0.0
        # det(F + αD) − fraction · det F reaches 0 first at:
        root = first_root_in_unit_interval((1.0 - fraction) * c0, c1, c2, c3)
        step = min(step, root)
    return step


class InversionFreeStep:
    """Largest step along a direction that keeps every point's volume above a fraction.

    Parameters
    ----------
    u
        The current displacement.
    fraction
        Smallest allowed ratio of new to current volume at a quadrature point, in (0, 1).
    quadrature_degree
        Degree of the rule whose points are checked; default that of the elastic forms.
    """

    def __init__(self, u, fraction: float = 0.1, *, quadrature_degree: int | None = None):
        import basix

        if not (0.0 < fraction < 1.0):
            raise ValueError(f"fraction must lie in (0, 1), got {fraction!r}")
        self.u = u
        self.fraction = float(fraction)
        space = u.function_space
        self.direction = dolfinx.fem.Function(space)
        mesh = space.mesh
        if quadrature_degree is None:
            quadrature_degree = default_quadrature_degree(
                _compat.element_degree(space), mesh.topology.cell_type
            )
        cell_type = _compat.basix_element(space).cell_type
        points, _ = basix.make_quadrature(cell_type, quadrature_degree)
        self.dimension = mesh.geometry.dim
        self._expression = dolfinx.fem.Expression(
            ufl.as_tensor([ufl.grad(u), ufl.grad(self.direction)]), points
        )
        self._cells = np.arange(
            mesh.topology.index_map(mesh.topology.dim).size_local, dtype=np.int32
        )
        self._comm = mesh.comm

    def largest_step(self, direction, sign: float = 1.0) -> float:
        """Largest α ≤ 1 for the motion ``u + α · sign · direction`` (a PETSc Vec), all ranks."""
        direction.copy(_compat.petsc_vector(self.direction))
        self.direction.x.scatter_forward()
        values = _compat.evaluate_expression(
            self._expression, self.u.function_space.mesh, self._cells
        )
        d = self.dimension
        gradients = np.ascontiguousarray(values.reshape(-1, 2, d, d))
        local = _largest_step(gradients, float(sign), self.fraction) if len(gradients) else 1.0
        return self._comm.allreduce(local, op=MPI.MIN)
