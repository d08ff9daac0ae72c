"""The three cell functions behind DOLFINx's custom-kernel (ufcx ``tabulate_tensor``) entries.

They share one quadrature loop and the point functions of
:mod:`~dolfinx_invertible.constitutive.pointwise`, which also serve the batch API:

* energy: ``A[0] = ∫_cell Ψ(F) dX``;
* residual: ``A[a·d + i] = ∫_cell P_ij ∂φ_a/∂X_j dX``;
* tangent: ``A[a·d + i, b·d + k] = ∫_cell ∂φ_a/∂X_j (dP/dF)_{ij,kl} ∂φ_b/∂X_l dX``,

with F = I + ∇u. A point whose energy overflows (a finite but enormous F) adds +inf to the
energy, so a line search backtracks from such a state; where its stress or tangent would
overflow, the point adds nothing to the residual and the tangent (never NaN or inf) and +inf to
the energy (:data:`~dolfinx_invertible.constitutive.principal.OVERFLOW_REGION`).

The coefficient array ``w`` holds the cell's displacement dofs node by node
with components interleaved; the constants ``c`` follow
:mod:`~dolfinx_invertible.fem.kernels.constants`.

The cell functions are compiled per dimension, model and extension, all three literal constants
(``numba.literally``): the loops over components have constant trip counts and are unrolled and
vectorised (with a run-time dimension the same loops were several times slower), and only the
chain of the material in use is compiled (:mod:`~dolfinx_invertible.constitutive.literal`).

The per-cell helpers (layout, material, geometry, counters) are ``forceinline``: LLVM inlines
them, where called out of line every array argument cost a reference-count call and the node
loops could not be specialised. The residual also has quadrature loops for constant node counts
(P1 and P2 simplices), which measured 25 % faster per cell than the run-time count; numba's own
``inline="always"`` would do the same but multiplied the compile time twentyfold.
"""

from __future__ import annotations

import numba

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.constitutive.literal import run_time_integers
from dolfinx_invertible.constitutive.pointwise import point_energy, point_stress, point_tangent
from dolfinx_invertible.fem.kernels.constants import (
    DERIVED_STIFFNESS,
    GEOMETRY_NODES_SLOT,
    HEADER_SIZE,
    MAX_NODES,
    NODES_SLOT,
    PARAMETER_COUNT,
    PARAMETER_SOURCES_SLOT,
    PARAMETERS_START,
    POSITIVE_ONLY_SLOT,
    PROJECT_SLOT,
    SVD_PATH_SLOT,
    WEIGHTS_START,
)
from dolfinx_invertible.fem.kernels.counters import (
    ENERGY_COUNTS,
    RESIDUAL_COUNTS,
    TANGENT_COUNTS,
    count_points,
    integer_from_bits,
)
from dolfinx_invertible.fem.kernels.geometry import (
    cell_layout,
    deformation_gradient,
    gradients_from_reference,
    inverse_jacobian,
    point_geometry,
    reference_deformation,
)

__all__ = ["cell_energy", "cell_residual", "cell_tangent"]

# The counter fields, not literals: count_points compiles once, not once per kernel.
_ENERGY_FIELD, _RESIDUAL_FIELD, _TANGENT_FIELD = run_time_integers(
    ENERGY_COUNTS, RESIDUAL_COUNTS, TANGENT_COUNTS
)

# Kernel scratch on the stack (never zeroed: every entry is written before it is read):
# basis gradients (nodes × d), geometry Jacobian, F, P, dP/dF (d² × d²) and dP/dF contracted
# with the gradients (d² × nodes × d), sized for the largest supported element.
_GRADIENTS = 0
_JACOBIAN = _GRADIENTS + 3 * MAX_NODES
_DEFORMATION = _JACOBIAN + 9
_STRESS = _DEFORMATION + 9
_TANGENT = _STRESS + 9
_CONTRACTED = _TANGENT + 81
KERNEL_SCRATCH = _CONTRACTED + 9 * 3 * MAX_NODES


@compiled_only(forceinline=True)
def _material(c_, c, params):
    """Fill ``params`` ([μ, λ, ε, k]) from the constants; return (positive_only, project, path).

    ``path`` is the address of the material's SVD path
    (:mod:`~dolfinx_invertible.constitutive.svd_path`).

    A parameter given as a DOLFINx Constant is read from that Constant, which DOLFINx packs
    after the kernel's own constants (see :mod:`.constants`), so a new ``value`` is seen at the
    next assembly; a C1 stiffness left to its default follows μ and λ (20 E).
    """
    total = c.shape[0]
    for p in range(PARAMETER_COUNT):
        source = c[PARAMETER_SOURCES_SLOT + p]
        if source >= 0.0:
            params[p] = c_[total + int(source)]
        else:
            params[p] = c[PARAMETERS_START + p]
    if c[PARAMETER_SOURCES_SLOT + PARAMETER_COUNT - 1] == DERIVED_STIFFNESS:
        mu = params[0]
        lam = params[1]
        params[3] = 20.0 * mu * (3.0 * lam + 2.0 * mu) / (lam + mu)
    return c[POSITIVE_ONLY_SLOT] != 0.0, c[PROJECT_SLOT] != 0.0, integer_from_bits(c[SVD_PATH_SLOT])


@compiled_only
def _point_views(scratch, nodes, d):
    """Return views of the per-point scratch: basis gradients, geometry Jacobian, F."""
    gradients = numba.carray(ws.address(scratch, _GRADIENTS), (nodes, d))
    jacobian = numba.carray(ws.address(scratch, _JACOBIAN), (d, d))
    F = numba.carray(ws.address(scratch, _DEFORMATION), (d, d))
    return gradients, jacobian, F


@compiled_only
def cell_energy(A_, w_, c_, coordinates_, d, model_id, extension_id):
    """Add the cell energy ∫Ψ(F) dX to ``A_[0]``."""
    numba.literally(d)
    numba.literally(model_id)
    numba.literally(extension_id)
    c, nodes, points, start, geometry_start, displacement, coordinates = cell_layout(
        c_, w_, coordinates_, d
    )
    params = numba.carray(ws.stack_array(PARAMETER_COUNT), PARAMETER_COUNT)
    positive_only, _, svd_path = _material(c_, c, params)
    scratch = numba.carray(ws.stack_array(KERNEL_SCRATCH), KERNEL_SCRATCH)
    work = ws.new_workspace(ws.stack_buffer())
    gradients, jacobian, F = _point_views(scratch, nodes, d)
    total = 0.0
    svd_points = 0
    for q in range(points):
        scale = point_geometry(
            c, q, start, geometry_start, coordinates, displacement, gradients, jacobian, F, d, nodes
        )
        psi, _, through_svd = point_energy(
            F, d, model_id, extension_id, positive_only, params, svd_path, work
        )
        svd_points += through_svd
        total += scale * psi
    A_[0] += total
    count_points(c, _ENERGY_FIELD, points, svd_points)


@compiled_only(forceinline=True)
def _residual_points(A_, c_, w_, coordinates_, d, model_id, extension_id, nodes, geometry_nodes):
    """Run the quadrature loop of :func:`cell_residual`; return (points, points through the SVD).

    Inlined by LLVM (``forceinline``): where the caller passes constant node counts, the node
    loops are unrolled for that element.
    """
    c, _, points, start, geometry_start, displacement, _ = cell_layout(c_, w_, coordinates_, d)
    coordinates = numba.carray(coordinates_, (geometry_nodes, 3))
    params = numba.carray(ws.stack_array(PARAMETER_COUNT), PARAMETER_COUNT)
    positive_only, _, svd_path = _material(c_, c, params)
    work = ws.new_workspace(ws.stack_buffer())
    jacobian = numba.carray(ws.stack_array(9), (d, d))
    inverse = numba.carray(ws.stack_array(9), (d, d))
    F = numba.carray(ws.stack_array(9), (d, d))
    P = numba.carray(ws.stack_array(9), (d, d))
    # P Kᵀ times the point's weight: the residual is Σ_r (P Kᵀ)_ir ∂φ_a/∂ξ_r.
    weighted = numba.carray(ws.stack_array(9), (d, d))
    A = numba.carray(A_, nodes * d)
    # A P1 simplex geometry (d + 1 nodes) is affine: J, J⁻¹ and |det J| are the same at every
    # point, and its reference derivatives the same at every point too, so the values computed
    # at the first point are those of any other.
    affine = geometry_nodes == d + 1
    determinant = 0.0
    svd_points = 0
    for q in range(points):
        if q == 0 or not affine:
            geometry = numba.carray(
                ws.address(c, geometry_start + q * geometry_nodes * d), geometry_nodes * d
            )
            determinant = inverse_jacobian(
                coordinates, geometry, jacobian, inverse, geometry_nodes, d
            )
        scale = c[WEIGHTS_START + q] * determinant
        basis = numba.carray(ws.address(c, start + q * nodes * d), nodes * d)
        reference_deformation(displacement, basis, inverse, F, nodes, d)
        _, _, through_svd = point_stress(
            F, d, model_id, extension_id, positive_only, params, svd_path, work, P
        )
        svd_points += through_svd
        for i in range(d):
            for r in range(d):
                total = 0.0
                for j in range(d):
                    total += P[i, j] * inverse[r, j]
                weighted[i, r] = scale * total
        for a in range(nodes):
            for i in range(d):
                total = 0.0
                for r in range(d):
                    total += weighted[i, r] * basis[a * d + r]
                A[a * d + i] += total
    return points, svd_points


@compiled_only
def cell_residual(A_, w_, c_, coordinates_, d, model_id, extension_id):
    """Add the cell residual ∫ P : ∇φ dX to ``A_``.

    The P1 and P2 simplices of dimension ``d`` (on their affine geometry) get quadrature loops
    with constant node counts; any other element takes the loop with run-time counts.
    """
    numba.literally(d)
    numba.literally(model_id)
    numba.literally(extension_id)
    header = numba.carray(c_, HEADER_SIZE)
    nodes = int(header[NODES_SLOT])
    geometry_nodes = int(header[GEOMETRY_NODES_SLOT])
    vertices = d + 1
    if geometry_nodes == vertices and nodes == vertices:
        points, svd_points = _residual_points(
            A_, c_, w_, coordinates_, d, model_id, extension_id, d + 1, d + 1
        )
    elif geometry_nodes == vertices and nodes == (d + 1) * (d + 2) // 2:
        points, svd_points = _residual_points(
            A_, c_, w_, coordinates_, d, model_id, extension_id, (d + 1) * (d + 2) // 2, d + 1
        )
    else:
        points, svd_points = _residual_points(
            A_, c_, w_, coordinates_, d, model_id, extension_id, nodes, geometry_nodes
        )
    count_points(header, _RESIDUAL_FIELD, points, svd_points)


@compiled_only(forceinline=True)
def _tangent_points(A_, c_, w_, coordinates_, d, model_id, extension_id, nodes, geometry_nodes):
    """Run the quadrature loop of :func:`cell_tangent`; return (points, points through the SVD).

    Inlined by LLVM (``forceinline``), as :func:`_residual_points`: with constant node counts the
    contraction with the basis gradients unrolls for the element at hand.
    """
    c, _, points, start, geometry_start, displacement, _ = cell_layout(c_, w_, coordinates_, d)
    coordinates = numba.carray(coordinates_, (geometry_nodes, 3))
    params = numba.carray(ws.stack_array(PARAMETER_COUNT), PARAMETER_COUNT)
    positive_only, project, svd_path = _material(c_, c, params)
    scratch = numba.carray(ws.stack_array(KERNEL_SCRATCH), KERNEL_SCRATCH)
    work = ws.new_workspace(ws.stack_buffer())
    gradients, jacobian, F = _point_views(scratch, nodes, d)
    inverse = numba.carray(ws.stack_array(9), (d, d))
    n = d * d
    P = numba.carray(ws.address(scratch, _STRESS), (d, d))
    C = numba.carray(ws.address(scratch, _TANGENT), (n, n))
    # CB[(i, j), b, k] = Σ_l C[(i, j), (k, l)] ∂φ_b/∂X_l, times the point's weight
    CB = numba.carray(ws.address(scratch, _CONTRACTED), (n, nodes, d))
    size = nodes * d
    A = numba.carray(A_, (size, size))
    # An affine geometry (d + 1 nodes): J⁻¹ and |det J| are those of the first point.
    affine = geometry_nodes == d + 1
    determinant = 0.0
    svd_points = 0
    for q in range(points):
        if q == 0 or not affine:
            geometry = numba.carray(
                ws.address(c, geometry_start + q * geometry_nodes * d), geometry_nodes * d
            )
            determinant = inverse_jacobian(
                coordinates, geometry, jacobian, inverse, geometry_nodes, d
            )
        scale = c[WEIGHTS_START + q] * determinant
        basis = numba.carray(ws.address(c, start + q * nodes * d), nodes * d)
        gradients_from_reference(basis, inverse, gradients, nodes, d)
        deformation_gradient(displacement, gradients, F, nodes, d)
        _, _, through_svd = point_tangent(
            F, d, model_id, extension_id, positive_only, params, project, svd_path, work, P, C
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
    return points, svd_points


@compiled_only
def cell_tangent(A_, w_, c_, coordinates_, d, model_id, extension_id):
    """Add the cell tangent ∫ ∇φ_a : dP/dF : ∇φ_b dX (projected if the header says so).

    Constant node counts for the P1 and P2 simplices, as in :func:`cell_residual`.
    """
    numba.literally(d)
    numba.literally(model_id)
    numba.literally(extension_id)
    header = numba.carray(c_, HEADER_SIZE)
    nodes = int(header[NODES_SLOT])
    geometry_nodes = int(header[GEOMETRY_NODES_SLOT])
    vertices = d + 1
    if geometry_nodes == vertices and nodes == vertices:
        points, svd_points = _tangent_points(
            A_, c_, w_, coordinates_, d, model_id, extension_id, d + 1, d + 1
        )
    elif geometry_nodes == vertices and nodes == (d + 1) * (d + 2) // 2:
        points, svd_points = _tangent_points(
            A_, c_, w_, coordinates_, d, model_id, extension_id, (d + 1) * (d + 2) // 2, d + 1
        )
    else:
        points, svd_points = _tangent_points(
            A_, c_, w_, coordinates_, d, model_id, extension_id, nodes, geometry_nodes
        )
    count_points(header, _TANGENT_FIELD, points, svd_points)
