"""Numba cell kernels with DOLFINx's custom-kernel (ufcx ``tabulate_tensor``) signature.

Three kernels share one quadrature loop and the point functions of
:mod:`~dolfinx_invertible.pointwise`, which also serve the batch API:

* energy: ``A[0] = ∫_cell Ψ(F) dX``;
* residual: ``A[a·d + i] = ∫_cell P_ij ∂φ_a/∂X_j dX``;
* tangent: ``A[a·d + i, b·d + k] = ∫_cell ∂φ_a/∂X_j (dP/dF)_{ij,kl} ∂φ_b/∂X_l dX``,

with F = I + ∇u. Everything a kernel needs besides the cell's dofs and coordinates travels in
one DOLFINx Constant (:func:`pack_constants`): a header (dimension, element sizes, model and
extension ids, switches), the material parameters and the Basix reference tables. So one
compiled kernel per kind and dimension serves every element, quadrature rule and material, and
changing parameters or the projection switch never recompiles. Kernels are compiled on first
use (:func:`kernel_address`) into numba's disk cache; :func:`precompile` fills that cache ahead.
Each kernel counts, per form, the quadrature points it evaluated and how many needed the SVD.
The coefficient array ``w`` holds the cell's displacement dofs node by node with components
interleaved.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

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
    "precompile",
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
def _physical_gradients(coordinates, geometry, basis, gradients, jacobian, nodes, d):
    """Physical basis gradients at one point into ``gradients``; returns |det J| of the map.

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
def _deformation_gradient(displacement, gradients, F, nodes, d):
    for i in range(d):
        for j in range(d):
            F[i, j] = 1.0 if i == j else 0.0
    for a in range(nodes):
        for i in range(d):
            value = displacement[a * d + i]
            for j in range(d):
                F[i, j] += value * gradients[a, j]


# Layout of the constants array every kernel reads (one DOLFINx Constant): a header, the
# material parameters, then the reference tables. Passing the tables as data rather than baking
# them into the machine code lets one compiled (and disk-cached) kernel serve every element,
# quadrature rule and material; DOLFINx packs constants once per assembly, not per cell.
# header: dimension, nodes, points, geometry nodes, model, extension, positive_only, project,
# and the address (as float64 bits) of the row of PATH_COUNTERS the kernels count into.
HEADER = 9
PARAMETER_COUNT = 4  # Material.parameters: [μ, λ, ε, k]
PROJECT_SLOT = 7  # header entry of the projection switch
COUNTER_SLOT = 8

# Per-form counts of quadrature points evaluated and of those that needed an SVD:
# [energy points, energy SVDs, residual points, residual SVDs, tangent points, tangent SVDs].
# One module-level pool that is never freed, so a kernel can never write into released memory
# whatever the lifetime of the Python objects around a form; rows are handed out round-robin.
COUNTER_FIELDS = 6
PATH_COUNTERS = np.zeros((4096, COUNTER_FIELDS))
_next_counter_row = [0]


def counter_row() -> np.ndarray:
    """A zeroed row of :data:`PATH_COUNTERS` for one set of forms (round-robin reuse)."""
    row = PATH_COUNTERS[_next_counter_row[0] % PATH_COUNTERS.shape[0]]
    _next_counter_row[0] += 1
    row[:] = 0.0
    return row


def pack_constants(
    tables: ReferenceTables,
    dimension: int,
    material,
    project: bool,
    counters: np.ndarray | None = None,
) -> np.ndarray:
    """The constants array the cell kernels (:func:`kernel_address`) read."""
    points, nodes, _ = tables.basis_derivatives.shape
    if nodes > _MAX_NODES or tables.geometry_derivatives.shape[1] > _MAX_NODES:
        raise ValueError(f"the kernels support at most {_MAX_NODES} nodes per cell, got {nodes}")
    address = 0.0
    if counters is not None:
        address = np.array([counters.ctypes.data], dtype=np.int64).view(np.float64)[0]
    header = [
        dimension,
        nodes,
        points,
        tables.geometry_derivatives.shape[1],
        material.model.model_id,
        material.extension_id,
        float(material.positive_only),
        float(project),
        address,
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


@intrinsic
def _pointer_from_bits(typingctx, bits):
    """The float64 ``bits`` reinterpreted as a pointer to float64 (0.0 gives null)."""

    def codegen(context, builder, signature, args):
        integer = builder.bitcast(args[0], ir.IntType(64))
        return builder.inttoptr(integer, context.get_value_type(signature.return_type))

    return types.CPointer(types.float64)(types.float64), codegen


@intrinsic
def _is_null(typingctx, pointer):
    def codegen(context, builder, signature, args):
        return cgutils.is_null(builder, args[0])

    return types.boolean(pointer), codegen


@numba.njit(cache=True)
def _count(c, field, points, svd_points):
    pointer = _pointer_from_bits(c[COUNTER_SLOT])
    if not _is_null(pointer):
        counters = numba.carray(pointer, COUNTER_FIELDS)
        counters[field] += points
        counters[field + 1] += svd_points


# Kernel scratch on the stack (never zeroed: every entry is written before it is read):
# basis gradients (nodes × d), geometry Jacobian, F, P, dP/dF (d² × d²) and dP/dF contracted
# with the gradients (d² × nodes × d). Sized for the largest supported element (10 nodes).
_MAX_NODES = 10
_GRADIENTS = 0
_JACOBIAN = _GRADIENTS + 3 * _MAX_NODES
_DEFORMATION = _JACOBIAN + 9
_STRESS = _DEFORMATION + 9
_TANGENT = _STRESS + 9
_CONTRACTED = _TANGENT + 81
KERNEL_SCRATCH = _CONTRACTED + 9 * 3 * _MAX_NODES


@numba.njit(cache=True)
def _cell_layout(c_, w_, coordinates_, d):
    """Views of the kernel inputs for dimension ``d``, and the element sizes."""
    header = numba.carray(c_, HEADER)
    nodes = int(header[1])
    points = int(header[2])
    geometry_nodes = int(header[3])
    total = HEADER + PARAMETER_COUNT + points * (1 + (nodes + geometry_nodes) * d)
    c = numba.carray(c_, total)
    start = HEADER + PARAMETER_COUNT + points
    geometry_start = start + points * nodes * d
    displacement = numba.carray(w_, nodes * d)
    coordinates = numba.carray(coordinates_, (geometry_nodes, 3))
    return c, nodes, points, start, geometry_start, displacement, coordinates


@numba.njit(cache=True)
def _point_geometry(c, q, start, geometry_start, coordinates, displacement, scratch, d, nodes):
    """Physical basis gradients and F at point ``q``; returns the weight times |det J|."""
    geometry_nodes = coordinates.shape[0]
    gradients = numba.carray(ws.address(scratch, _GRADIENTS), (nodes, d))
    jacobian = numba.carray(ws.address(scratch, _JACOBIAN), (d, d))
    F = numba.carray(ws.address(scratch, _DEFORMATION), (d, d))
    basis = numba.carray(ws.address(c, start + q * nodes * d), nodes * d)
    geometry = numba.carray(
        ws.address(c, geometry_start + q * geometry_nodes * d), geometry_nodes * d
    )
    scale = c[HEADER + PARAMETER_COUNT + q] * _physical_gradients(
        coordinates, geometry, basis, gradients, jacobian, nodes, d
    )
    _deformation_gradient(displacement, gradients, F, nodes, d)
    return scale, gradients, F


@numba.njit(cache=True)
def _material(c):
    """(parameters, model id, extension id, positive_only, project) from the constants."""
    params = c[HEADER : HEADER + PARAMETER_COUNT]
    return params, int(c[4]), int(c[5]), c[6] != 0.0, c[PROJECT_SLOT] != 0.0


# The cell functions are compiled per dimension, a literal constant (numba.literally), so the
# loops over components have constant trip counts and are unrolled and vectorised: with a
# run-time dimension the same loops were several times slower (a constant node count as well
# measured no faster). Only the dimension a scene uses is ever compiled (see kernel_address).
@numba.njit(cache=True)
def cell_energy(A_, w_, c_, coordinates_, d):
    """Cell energy ∫Ψ(F) dX."""
    numba.literally(d)
    c, nodes, points, start, geometry_start, displacement, coordinates = _cell_layout(
        c_, w_, coordinates_, d
    )
    params, model_id, extension_id, positive_only, _ = _material(c)
    scratch = numba.carray(ws.stack_array(KERNEL_SCRATCH), KERNEL_SCRATCH)
    work = ws.new_workspace(ws.stack_buffer())
    total = 0.0
    svd_points = 0
    for q in range(points):
        scale, _, F = _point_geometry(
            c, q, start, geometry_start, coordinates, displacement, scratch, d, nodes
        )
        psi, _, through_svd = point_energy(F, model_id, extension_id, positive_only, params, work)
        svd_points += through_svd
        total += scale * psi
    A_[0] += total
    _count(c, 0, points, svd_points)


@numba.njit(cache=True)
def cell_residual(A_, w_, c_, coordinates_, d):
    """Cell residual ∫ P : ∇φ dX."""
    numba.literally(d)
    c, nodes, points, start, geometry_start, displacement, coordinates = _cell_layout(
        c_, w_, coordinates_, d
    )
    params, model_id, extension_id, positive_only, _ = _material(c)
    scratch = numba.carray(ws.stack_array(KERNEL_SCRATCH), KERNEL_SCRATCH)
    work = ws.new_workspace(ws.stack_buffer())
    P = numba.carray(ws.address(scratch, _STRESS), (d, d))
    A = numba.carray(A_, nodes * d)
    svd_points = 0
    for q in range(points):
        scale, gradients, F = _point_geometry(
            c, q, start, geometry_start, coordinates, displacement, scratch, d, nodes
        )
        _, _, through_svd = point_stress(F, model_id, extension_id, positive_only, params, work, P)
        svd_points += through_svd
        for a in range(nodes):
            for i in range(d):
                total = 0.0
                for j in range(d):
                    total += P[i, j] * gradients[a, j]
                A[a * d + i] += scale * total
    _count(c, 2, points, svd_points)


@numba.njit(cache=True)
def cell_tangent(A_, w_, c_, coordinates_, d):
    """Cell tangent ∫ ∇φ_a : dP/dF : ∇φ_b dX (projected if the header says so)."""
    numba.literally(d)
    c, nodes, points, start, geometry_start, displacement, coordinates = _cell_layout(
        c_, w_, coordinates_, d
    )
    params, model_id, extension_id, positive_only, project = _material(c)
    scratch = numba.carray(ws.stack_array(KERNEL_SCRATCH), KERNEL_SCRATCH)
    work = ws.new_workspace(ws.stack_buffer())
    n = d * d
    P = numba.carray(ws.address(scratch, _STRESS), (d, d))
    C = numba.carray(ws.address(scratch, _TANGENT), (n, n))
    # CB[(i, j), b, k] = Σ_l C[(i, j), (k, l)] ∂φ_b/∂X_l, times the point's weight
    CB = numba.carray(ws.address(scratch, _CONTRACTED), (n, nodes, d))
    size = nodes * d
    A = numba.carray(A_, (size, size))
    svd_points = 0
    for q in range(points):
        scale, gradients, F = _point_geometry(
            c, q, start, geometry_start, coordinates, displacement, scratch, d, nodes
        )
        _, _, through_svd = point_tangent(
            F, model_id, extension_id, positive_only, params, project, work, P, C
        )
        svd_points += through_svd
        for row in range(n):
            for b in range(nodes):
                for k in range(d):
                    total = 0.0
                    for l in range(d):
                        total += C[row, k * d + l] * gradients[b, l]
                    CB[row, b, k] = total * scale
        # The tangent is symmetric: fill the upper block triangle (b ≥ a), mirror at the end.
        for a in range(nodes):
            for i in range(d):
                for b in range(a, nodes):
                    for k in range(d):
                        total = 0.0
                        for j in range(d):
                            total += gradients[a, j] * CB[i * d + j, b, k]
                        A[a * d + i, b * d + k] += total
    for a in range(nodes):
        for b in range(a + 1, nodes):
            for i in range(d):
                for k in range(d):
                    A[b * d + k, a * d + i] = A[a * d + i, b * d + k]
    _count(c, 4, points, svd_points)


# The C entry points DOLFINx calls, one per (kind, dimension). Two arities because
# ufcx's tabulate_tensor gained a ``custom_data`` pointer in DOLFINx 0.10; _compat says which
# one this DOLFINx wants. They are compiled on first use only (see kernel_address), so a scene
# that never asks for the energy, say, never compiles its kernel.
def _entries(kind: str, d: int) -> tuple:
    if kind == "energy":

        def entry(A_, w_, c_, coordinates_, entity_local_index, permutation):
            cell_energy(A_, w_, c_, coordinates_, d)

        def entry_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
            cell_energy(A_, w_, c_, coordinates_, d)

    elif kind == "residual":

        def entry(A_, w_, c_, coordinates_, entity_local_index, permutation):
            cell_residual(A_, w_, c_, coordinates_, d)

        def entry_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
            cell_residual(A_, w_, c_, coordinates_, d)

    else:

        def entry(A_, w_, c_, coordinates_, entity_local_index, permutation):
            cell_tangent(A_, w_, c_, coordinates_, d)

        def entry_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
            cell_tangent(A_, w_, c_, coordinates_, d)

    return entry, entry_with_data


KERNEL_KINDS = ("energy", "residual", "tangent")
_COMPILED: dict[tuple, object] = {}


def compile_kernel(entries: tuple) -> object:
    """A numba ``cfunc`` with the kernel signature of the running DOLFINx.

    ``entries`` holds the six-argument and the seven-argument (``custom_data``) Python function;
    the one matching :data:`dolfinx_invertible._compat.KERNEL_TAKES_CUSTOM_DATA` is compiled
    (or loaded from numba's disk cache).
    """
    from dolfinx_invertible import _compat

    entry = entries[1] if _compat.KERNEL_TAKES_CUSTOM_DATA else entries[0]
    return numba.cfunc(_compat.KERNEL_SIGNATURE, nopython=True, cache=True)(entry)


def kernel_address(kind: str, dimension: int) -> int:
    """Address of the compiled ``"energy"``, ``"residual"`` or ``"tangent"`` cell kernel for
    ``dimension`` 2 or 3 (any supported element: up to 10 nodes per cell)."""
    if kind not in KERNEL_KINDS:
        raise ValueError(f"kind must be one of {KERNEL_KINDS}, got {kind!r}")
    if dimension not in (2, 3):
        raise ValueError(f"no kernel for dimension {dimension}; 2 and 3 are supported")
    key = (kind, int(dimension))
    if key not in _COMPILED:
        _COMPILED[key] = compile_kernel(_entries(*key))
    return _COMPILED[key].address


def precompile(dimensions: tuple[int, ...] = (3, 2)) -> dict[tuple[str, int], float]:
    """Compile every cell kernel for ``dimensions`` into numba's disk cache; seconds per kernel.

    ``make setup`` runs this (``python -m dolfinx_invertible compile``) so that the first
    assembly in a user's script loads the kernels instead of compiling them; with a warm cache
    it takes about a second.
    """
    import time

    seconds = {}
    for dimension in dimensions:
        for kind in KERNEL_KINDS:
            start = time.perf_counter()
            kernel_address(kind, dimension)
            seconds[(kind, dimension)] = time.perf_counter() - start
    return seconds
