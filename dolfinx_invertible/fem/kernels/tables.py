"""Quadrature weights and reference-cell basis derivatives, the data a kernel integrates with."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ReferenceTables"]


@dataclass(frozen=True)
class ReferenceTables:
    """Quadrature and reference-cell basis derivatives a kernel is generated from.

    Attributes
    ----------
    weights
        Quadrature weights on the reference cell, shape (q,).
    basis_derivatives
        ∂φ_a/∂ξ_r of the displacement's scalar basis at the points, shape (q, n, tdim).
    geometry_derivatives
        ∂N_v/∂ξ_r of the coordinate element's basis at the points, shape (q, m, tdim).
    """

    weights: np.ndarray
    basis_derivatives: np.ndarray
    geometry_derivatives: np.ndarray

    @classmethod
    def from_basix(cls, element, geometry_element, quadrature_degree: int) -> ReferenceTables:
        """Tabulate Basix elements (scalar displacement, geometry) at a quadrature degree."""
        import basix

        points, weights = basix.make_quadrature(element.cell_type, quadrature_degree)
        basis = element.tabulate(1, points)[1:, :, :, 0]
        geometry = geometry_element.tabulate(1, points)[1:, :, :, 0]
        return cls(
            weights=np.ascontiguousarray(weights),
            basis_derivatives=np.ascontiguousarray(basis.transpose(1, 2, 0)),
            geometry_derivatives=np.ascontiguousarray(geometry.transpose(1, 2, 0)),
        )
