"""Numba cell kernels with DOLFINx's custom-kernel (ufcx ``tabulate_tensor``) signature.

Three kernels share one quadrature loop and the point functions of
:mod:`~dolfinx_invertible.pointwise`, which also serve the batch API:

* energy: ``A[0] = ∫_cell Ψ(F) dX``;
* residual: ``A[a·d + i] = ∫_cell P_ij ∂φ_a/∂X_j dX``;
* tangent: ``A[a·d + i, b·d + k] = ∫_cell ∂φ_a/∂X_j (dP/dF)_{ij,kl} ∂φ_b/∂X_l dX``,

with F = I + ∇u. Basis derivatives on the reference cell come from Basix and are baked into the
kernel as constants; the kernel maps them to the physical cell with the geometry Jacobian at each
point. Material parameters arrive through the constants array ``c`` (a DOLFINx Constant holding
``Material.parameters``), so changing them needs no recompilation. The coefficient array ``w``
holds the cell's displacement dofs node by node with components interleaved.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from dolfinx_invertible import workspace as ws
from dolfinx_invertible.pointwise import point_energy, point_stress, point_tangent

__all__ = [
    "ReferenceTables",
    "pack_constants",
    "cell_energy",
    "cell_residual",
    "cell_tangent",
    "compile_kernel",
    "kernel_address",
]


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
        """Tables from Basix elements (scalar displacement, geometry) at a quadrature degree."""
        import basix

        points, weights = basix.make_quadrature(element.cell_type, quadrature_degree)
        basis = element.tabulate(1, points)[1:, :, :, 0]
        geometry = geometry_element.tabulate(1, points)[1:, :, :, 0]
        return cls(
            weights=np.ascontiguousarray(weights),
            basis_derivatives=np.ascontiguousarray(basis.transpose(1, 2, 0)),
            geometry_derivatives=np.ascontiguousarray(geometry.transpose(1, 2, 0)),
        )


@numba.njit(cache=True)
def _physical_gradients(coordinates, geometry_derivatives, basis_derivatives, gradients, jacobian):
    """Physical basis gradients at one point into ``gradients``; returns |det J| of the map."""
    d = jacobian.shape[0]
    nodes = geometry_derivatives.shape[0]
    for i in range(d):
        for r in range(d):
            total = 0.0
            for v in range(nodes):
                total += coordinates[v, i] * geometry_derivatives[v, r]
            jacobian[i, r] = total
    if d == 2:
        determinant = jacobian[0, 0] * jacobian[1, 1] - jacobian[0, 1] * jacobian[1, 0]
        k00 = jacobian[1, 1] / determinant
        k01 = -jacobian[0, 1] / determinant
        k10 = -jacobian[1, 0] / determinant
        k11 = jacobian[0, 0] / determinant
        for a in range(basis_derivatives.shape[0]):
            x = basis_derivatives[a, 0]
            y = basis_derivatives[a, 1]
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
    for a in range(basis_derivatives.shape[0]):
        x = basis_derivatives[a, 0]
        y = basis_derivatives[a, 1]
        z = basis_derivatives[a, 2]
        gradients[a, 0] = x * k00 + y * k10 + z * k20
        gradients[a, 1] = x * k01 + y * k11 + z * k21
        gradients[a, 2] = x * k02 + y * k12 + z * k22
    return abs(determinant)


@numba.njit(cache=True)
def _deformation_gradient(displacement, gradients, F):
    d = F.shape[0]
    for i in range(d):
        for j in range(d):
            total = 1.0 if i == j else 0.0
            for a in range(gradients.shape[0]):
                total += displacement[a, i] * gradients[a, j]
            F[i, j] = total


# Layout of the constants array every kernel reads (one DOLFINx Constant): a header, the
# material parameters, then the reference tables. Passing the tables as data rather than baking
# them into the machine code lets one compiled (and disk-cached) kernel serve every element,
# quadrature rule and material; DOLFINx packs constants once per assembly, not per cell.
HEADER = 8  # dimension, nodes, points, geometry nodes, model, extension, positive_only, project
PARAMETER_COUNT = 4  # Material.parameters: [μ, λ, ε, k]
PROJECT_SLOT = 7  # header entry of the projection switch


def pack_constants(tables: ReferenceTables, dimension: int, material, project: bool) -> np.ndarray:
    """The constants array the cell kernels (:func:`kernel_address`) read."""
    points, nodes, _ = tables.basis_derivatives.shape
    header = [
        dimension,
        nodes,
        points,
        tables.geometry_derivatives.shape[1],
        material.model.model_id,
        material.extension_id,
        float(material.positive_only),
        float(project),
    ]
    return np.concatenate(
        [
            np.array(header, dtype=np.float64),
            material.parameters,
            tables.weights,
            tables.basis_derivatives.ravel(),
            tables.geometry_derivatives.ravel(),
        ]
    )


@numba.njit(cache=True)
def _unpack(c_, w_, coordinates_):
    header = numba.carray(c_, HEADER)
    d = int(header[0])
    nodes = int(header[1])
    points = int(header[2])
    geometry_nodes = int(header[3])
    total = HEADER + PARAMETER_COUNT + points * (1 + (nodes + geometry_nodes) * d)
    c = numba.carray(c_, total)
    params = c[HEADER : HEADER + PARAMETER_COUNT]
    start = HEADER + PARAMETER_COUNT
    weights = c[start : start + points]
    start += points
    basis = c[start : start + points * nodes * d]
    start += points * nodes * d
    geometry = c[start : start + points * geometry_nodes * d]
    displacement = numba.carray(w_, (nodes, d))
    coordinates = numba.carray(coordinates_, (geometry_nodes, 3))
    # Scratch for one quadrature point: physical basis gradients, geometry Jacobian, F, P.
    scratch = (np.empty((nodes, d)), np.empty((d, d)), np.empty((d, d)), np.empty((d, d)))
    return d, nodes, points, params, weights, basis, geometry, displacement, coordinates, scratch


@numba.njit(cache=True)
def _quadrature_point(
    q, weights, basis, geometry, coordinates, displacement, gradients, jacobian, F
):
    """Physical basis gradients and F at point ``q``; returns the weight times |det J|."""
    nodes, d = gradients.shape
    geometry_nodes = geometry.shape[0] // (weights.shape[0] * d)
    scale = weights[q] * _physical_gradients(
        coordinates,
        geometry[q * geometry_nodes * d : (q + 1) * geometry_nodes * d].reshape(
            (geometry_nodes, d)
        ),
        basis[q * nodes * d : (q + 1) * nodes * d].reshape((nodes, d)),
        gradients,
        jacobian,
    )
    _deformation_gradient(displacement, gradients, F)
    return scale


@numba.njit(cache=True)
def _ids(c_):
    header = numba.carray(c_, HEADER)
    return int(header[4]), int(header[5]), header[6] != 0.0, header[PROJECT_SLOT] != 0.0


@numba.njit(cache=True)
def cell_energy(A_, w_, c_, coordinates_):
    """Cell energy ∫Ψ(F) dX."""
    d, nodes, points, params, weights, basis, geometry, displacement, coordinates, scratch = (
        _unpack(c_, w_, coordinates_)
    )
    gradients, jacobian, F, P = scratch
    model_id, extension_id, positive_only, _ = _ids(c_)
    work = ws.new_workspace(ws.stack_buffer())
    total = 0.0
    for q in range(points):
        scale = _quadrature_point(
            q, weights, basis, geometry, coordinates, displacement, gradients, jacobian, F
        )
        psi, _ = point_energy(F, model_id, extension_id, positive_only, params, work)
        total += scale * psi
    A_[0] += total


@numba.njit(cache=True)
def cell_residual(A_, w_, c_, coordinates_):
    """Cell residual ∫ P : ∇φ dX."""
    d, nodes, points, params, weights, basis, geometry, displacement, coordinates, scratch = (
        _unpack(c_, w_, coordinates_)
    )
    gradients, jacobian, F, P = scratch
    model_id, extension_id, positive_only, _ = _ids(c_)
    A = numba.carray(A_, nodes * d)
    work = ws.new_workspace(ws.stack_buffer())
    for q in range(points):
        scale = _quadrature_point(
            q, weights, basis, geometry, coordinates, displacement, gradients, jacobian, F
        )
        point_stress(F, model_id, extension_id, positive_only, params, work, P)
        for a in range(nodes):
            for i in range(d):
                total = 0.0
                for j in range(d):
                    total += P[i, j] * gradients[a, j]
                A[a * d + i] += scale * total


@numba.njit(cache=True)
def cell_tangent(A_, w_, c_, coordinates_):
    """Cell tangent ∫ ∇φ_a : dP/dF : ∇φ_b dX (projected if the header says so)."""
    d, nodes, points, params, weights, basis, geometry, displacement, coordinates, scratch = (
        _unpack(c_, w_, coordinates_)
    )
    gradients, jacobian, F, P = scratch
    model_id, extension_id, positive_only, project = _ids(c_)
    size = nodes * d
    A = numba.carray(A_, (size, size))
    work = ws.new_workspace(ws.stack_buffer())
    C = np.empty((d * d, d * d))
    # CB[(i, j), b, k] = Σ_l C[(i, j), (k, l)] ∂φ_b/∂X_l
    CB = np.empty((d * d, nodes, d))
    for q in range(points):
        scale = _quadrature_point(
            q, weights, basis, geometry, coordinates, displacement, gradients, jacobian, F
        )
        point_tangent(F, model_id, extension_id, positive_only, params, project, work, P, C)
        for row in range(d * d):
            for b in range(nodes):
                for k in range(d):
                    total = 0.0
                    for l in range(d):
                        total += C[row, k * d + l] * gradients[b, l]
                    CB[row, b, k] = total * scale
        for a in range(nodes):
            for i in range(d):
                for b in range(nodes):
                    for k in range(d):
                        total = 0.0
                        for j in range(d):
                            total += gradients[a, j] * CB[i * d + j, b, k]
                        A[a * d + i, b * d + k] += total


# The C entry points DOLFINx calls. Two arities because ufcx's tabulate_tensor gained a
# ``custom_data`` pointer in DOLFINx 0.10; _compat says which one this DOLFINx wants. They are
# compiled on first use only (see kernel_address), so a scene that never asks for the energy,
# say, never compiles its kernel.
def _energy_entry(A_, w_, c_, coordinates_, entity_local_index, permutation):
    cell_energy(A_, w_, c_, coordinates_)


def _residual_entry(A_, w_, c_, coordinates_, entity_local_index, permutation):
    cell_residual(A_, w_, c_, coordinates_)


def _tangent_entry(A_, w_, c_, coordinates_, entity_local_index, permutation):
    cell_tangent(A_, w_, c_, coordinates_)


def _energy_entry_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
    cell_energy(A_, w_, c_, coordinates_)


def _residual_entry_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
    cell_residual(A_, w_, c_, coordinates_)


def _tangent_entry_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
    cell_tangent(A_, w_, c_, coordinates_)


_ENTRIES = {
    "energy": (_energy_entry, _energy_entry_with_data),
    "residual": (_residual_entry, _residual_entry_with_data),
    "tangent": (_tangent_entry, _tangent_entry_with_data),
}
_COMPILED: dict[str, object] = {}


def compile_kernel(entries: tuple) -> object:
    """A numba ``cfunc`` with the kernel signature of the running DOLFINx.

    ``entries`` holds the six-argument and the seven-argument (``custom_data``) Python function;
    the one matching :data:`dolfinx_invertible._compat.KERNEL_TAKES_CUSTOM_DATA` is compiled
    (or loaded from numba's disk cache).
    """
    from dolfinx_invertible import _compat

    entry = entries[1] if _compat.KERNEL_TAKES_CUSTOM_DATA else entries[0]
    return numba.cfunc(_compat.KERNEL_SIGNATURE, nopython=True, cache=True)(entry)


def kernel_address(kind: str) -> int:
    """Address of the compiled ``"energy"``, ``"residual"`` or ``"tangent"`` cell kernel."""
    if kind not in _COMPILED:
        _COMPILED[kind] = compile_kernel(_ENTRIES[kind])
    return _COMPILED[kind].address
