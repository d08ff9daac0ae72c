"""The geometry map at a quadrature point: physical basis gradients, |det J| and F = I + ∇u."""

from __future__ import annotations

import numba

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.fem.kernels.constants import (
    GEOMETRY_NODES_SLOT,
    HEADER_SIZE,
    NODES_SLOT,
    PARAMETER_COUNT,
    POINTS_SLOT,
    WEIGHTS_START,
)

__all__ = ["cell_layout", "physical_gradients", "deformation_gradient", "point_geometry"]


@numba.njit(cache=True)
def physical_gradients(coordinates, geometry, basis, gradients, jacobian, nodes, d):
    """Write the physical basis gradients at one point into ``gradients``; return |det J|.

    ``geometry`` and ``basis`` are this point's reference derivatives, flat (node, direction).
    """
    geometry_nodes = coordinates.shape[0]
    for i in range(d):
        for r in range(d):
            total = 0.0
            for v in range(geometry_nodes):
                total += coordinates[v, i] * geometry[v * d + r]
            jacobian[i, r] = total
    if d == 2:
        determinant = jacobian[0, 0] * jacobian[1, 1] - jacobian[0, 1] * jacobian[1, 0]
        inverse = 1.0 / determinant
        k00 = jacobian[1, 1] * inverse
        k01 = -jacobian[0, 1] * inverse
        k10 = -jacobian[1, 0] * inverse
        k11 = jacobian[0, 0] * inverse
        for a in range(nodes):
            x = basis[2 * a]
            y = basis[2 * a + 1]
            gradients[a, 0] = x * k00 + y * k10
            gradients[a, 1] = x * k01 + y * k11
        return abs(determinant)
    j = jacobian
    c00 = j[1, 1] * j[2, 2] - j[1, 2] * j[2, 1]
    c01 = j[1, 2] * j[2, 0] - j[1, 0] * j[2, 2]
    c02 = j[1, 0] * j[2, 1] - j[1, 1] * j[2, 0]
    determinant = j[0, 0] * c00 + j[0, 1] * c01 + j[0, 2] * c02
    inverse = 1.0 / determinant
    # K = J⁻¹ (rows r: reference direction), from the cofactors.
    k00 = c00 * inverse
    k10 = c01 * inverse
    k20 = c02 * inverse
    k01 = (j[0, 2] * j[2, 1] - j[0, 1] * j[2, 2]) * inverse
    k11 = (j[0, 0] * j[2, 2] - j[0, 2] * j[2, 0]) * inverse
    k21 = (j[0, 1] * j[2, 0] - j[0, 0] * j[2, 1]) * inverse
    k02 = (j[0, 1] * j[1, 2] - j[0, 2] * j[1, 1]) * inverse
    k12 = (j[0, 2] * j[1, 0] - j[0, 0] * j[1, 2]) * inverse
    k22 = (j[0, 0] * j[1, 1] - j[0, 1] * j[1, 0]) * inverse
    for a in range(nodes):
        x = basis[3 * a]
        y = basis[3 * a + 1]
        z = basis[3 * a + 2]
        gradients[a, 0] = x * k00 + y * k10 + z * k20
        gradients[a, 1] = x * k01 + y * k11 + z * k21
        gradients[a, 2] = x * k02 + y * k12 + z * k22
    return abs(determinant)


@numba.njit(cache=True)
def deformation_gradient(displacement, gradients, F, nodes, d):
    """F = I + Σ_a u_a ⊗ ∇φ_a into ``F``."""
    for i in range(d):
        for j in range(d):
            F[i, j] = 1.0 if i == j else 0.0
    for a in range(nodes):
        for i in range(d):
            value = displacement[a * d + i]
            for j in range(d):
                F[i, j] += value * gradients[a, j]


@numba.njit(cache=True)
def cell_layout(c_, w_, coordinates_, d):
    """Return views of the kernel inputs for dimension ``d``, and the element sizes.

    Returns ``(c, nodes, points, basis_start, geometry_start, displacement, coordinates)``.
    """
    header = numba.carray(c_, HEADER_SIZE)
    nodes = int(header[NODES_SLOT])
    points = int(header[POINTS_SLOT])
    geometry_nodes = int(header[GEOMETRY_NODES_SLOT])
    total = HEADER_SIZE + PARAMETER_COUNT + points * (1 + (nodes + geometry_nodes) * d)
    c = numba.carray(c_, total)
    basis_start = WEIGHTS_START + points
    geometry_start = basis_start + points * nodes * d
    displacement = numba.carray(w_, nodes * d)
    coordinates = numba.carray(coordinates_, (geometry_nodes, 3))
    return c, nodes, points, basis_start, geometry_start, displacement, coordinates


@numba.njit(cache=True)
def point_geometry(
    c, q, basis_start, geometry_start, coordinates, displacement, gradients, jacobian, F, d, nodes
):
    """Physical basis gradients and F at point ``q``; returns the weight times |det J|."""
    geometry_nodes = coordinates.shape[0]
    basis = numba.carray(ws.address(c, basis_start + q * nodes * d), nodes * d)
    geometry = numba.carray(
        ws.address(c, geometry_start + q * geometry_nodes * d), geometry_nodes * d
    )
    scale = c[WEIGHTS_START + q] * physical_gradients(
        coordinates, geometry, basis, gradients, jacobian, nodes, d
    )
    deformation_gradient(displacement, gradients, F, nodes, d)
    return scale
