"""The geometry map at a quadrature point: J⁻¹, physical basis gradients, |det J| and F = I + ∇u."""

from __future__ import annotations

import numba

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.fem.kernels.constants import (
    GEOMETRY_NODES_SLOT,
    HEADER_SIZE,
    NODES_SLOT,
    PARAMETER_COUNT,
    POINTS_SLOT,
    WEIGHTS_START,
)

__all__ = [
    "cell_layout",
    "deformation_gradient",
    "gradients_from_reference",
    "inverse_jacobian",
    "physical_gradients",
    "point_geometry",
    "reference_deformation",
]


@compiled_only(forceinline=True)
def inverse_jacobian(coordinates, geometry, jacobian, inverse, geometry_nodes, d):
    """Write J and K = J⁻¹ (rows: reference directions) at one point; return |det J|.

    ``geometry`` holds this point's reference derivatives of the geometry basis, flat
    (node, direction). Inlined into the kernels (as the other helpers here): called out of line,
    every array argument costs a reference-count call and the node loops cannot be unrolled for
    the element at hand.
    """
    for i in range(d):
        for r in range(d):
            total = 0.0
            for v in range(geometry_nodes):
                total += coordinates[v, i] * geometry[v * d + r]
            jacobian[i, r] = total
    j = jacobian
    if d == 2:
        determinant = j[0, 0] * j[1, 1] - j[0, 1] * j[1, 0]
        reciprocal = 1.0 / determinant
        inverse[0, 0] = j[1, 1] * reciprocal
        inverse[0, 1] = -j[0, 1] * reciprocal
        inverse[1, 0] = -j[1, 0] * reciprocal
        inverse[1, 1] = j[0, 0] * reciprocal
        return abs(determinant)
    c00 = j[1, 1] * j[2, 2] - j[1, 2] * j[2, 1]
    c01 = j[1, 2] * j[2, 0] - j[1, 0] * j[2, 2]
    c02 = j[1, 0] * j[2, 1] - j[1, 1] * j[2, 0]
    determinant = j[0, 0] * c00 + j[0, 1] * c01 + j[0, 2] * c02
    reciprocal = 1.0 / determinant
    # From the cofactors.
    inverse[0, 0] = c00 * reciprocal
    inverse[1, 0] = c01 * reciprocal
    inverse[2, 0] = c02 * reciprocal
    inverse[0, 1] = (j[0, 2] * j[2, 1] - j[0, 1] * j[2, 2]) * reciprocal
    inverse[1, 1] = (j[0, 0] * j[2, 2] - j[0, 2] * j[2, 0]) * reciprocal
    inverse[2, 1] = (j[0, 1] * j[2, 0] - j[0, 0] * j[2, 1]) * reciprocal
    inverse[0, 2] = (j[0, 1] * j[1, 2] - j[0, 2] * j[1, 1]) * reciprocal
    inverse[1, 2] = (j[0, 2] * j[1, 0] - j[0, 0] * j[1, 2]) * reciprocal
    inverse[2, 2] = (j[0, 0] * j[1, 1] - j[0, 1] * j[1, 0]) * reciprocal
    return abs(determinant)


@compiled_only(forceinline=True)
def physical_gradients(coordinates, geometry, basis, gradients, jacobian, nodes, d):
    """Write the physical basis gradients at one point into ``gradients``; return |det J|.

    ``geometry`` and ``basis`` are this point's reference derivatives, flat (node, direction).
    """
    inverse = numba.carray(ws.stack_array(9), (d, d))
    scale = inverse_jacobian(coordinates, geometry, jacobian, inverse, coordinates.shape[0], d)
    gradients_from_reference(basis, inverse, gradients, nodes, d)
    return scale


@compiled_only(forceinline=True)
def gradients_from_reference(basis, inverse, gradients, nodes, d):
    """∇φ_a = K ∂φ_a/∂ξ into ``gradients`` (nodes × d), from the reference derivatives."""
    for a in range(nodes):
        for j in range(d):
            total = 0.0
            for r in range(d):
                total += basis[a * d + r] * inverse[r, j]
            gradients[a, j] = total


@compiled_only(forceinline=True)
def reference_deformation(displacement, basis, inverse, F, nodes, d):
    """F = I + (Σ_a u_a ⊗ ∂φ_a/∂ξ) K into ``F``, from the reference derivatives ``basis``.

    Contracting with K = J⁻¹ after the sum over the nodes, rather than forming the physical
    gradients first, saves nodes × d² multiplications per point.
    """
    reference = numba.carray(ws.stack_array(9), (d, d))
    for i in range(d):
        for r in range(d):
            reference[i, r] = 0.0
    for a in range(nodes):
        for i in range(d):
            value = displacement[a * d + i]
            for r in range(d):
                reference[i, r] += value * basis[a * d + r]
    for i in range(d):
        for j in range(d):
            total = 1.0 if i == j else 0.0
            for r in range(d):
                total += reference[i, r] * inverse[r, j]
            F[i, j] = total


@compiled_only(forceinline=True)
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


@compiled_only(forceinline=True)
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


@compiled_only(forceinline=True)
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
