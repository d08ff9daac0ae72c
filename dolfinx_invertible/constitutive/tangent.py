"""First Piola–Kirchhoff stress and its derivative in F-space from principal quantities.

With F = U Σ Vᵀ, g = ∇Ψ̂ext(σ) and H = ∇²Ψ̂ext(σ):

* P = U diag(g) Vᵀ;
* dP/dF = Σₘₙ Aₘₙ Dₘ Dₙᵀ + Σ_{i<j} [aᵢⱼ sᵢⱼ sᵢⱼᵀ + bᵢⱼ tᵢⱼ tᵢⱼᵀ], with A = H, Dₘ = vec(uₘ vₘᵀ),
  sᵢⱼ / tᵢⱼ = vec(uᵢ vⱼᵀ ± uⱼ vᵢᵀ)/√2 the symmetric ("stretch") and antisymmetric ("twist")
  modes, aᵢⱼ = (gᵢ − gⱼ)/(σᵢ − σⱼ), bᵢⱼ = (gᵢ + gⱼ)/(σᵢ + σⱼ).

The SPD projection clamps the eigenvalues of A and the scalars aᵢⱼ, bᵢⱼ at zero, which is the
closest positive semidefinite tangent in the Frobenius norm with the same eigenvectors. The
vectorisation is row-major: entry (i, j) of a d×d matrix sits at i·d + j.
"""

from __future__ import annotations

import numba
import numpy as np

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.constitutive.literal import dispatch_on_dimension, run_time_integers
from dolfinx_invertible.constitutive.principal import (
    gradient_slope,
    quotient_slope,
    rotation_slope,
    sum_slope,
)

__all__ = [
    "clamp_symmetric",
    "project_symmetric_3",
    "stress_derivative",
    "workspace_first_piola",
]

_MAX_EIGEN_SWEEPS = 30


def _specialised_workspace_first_piola(d: int):
    """:func:`workspace_first_piola` for one dimension: constant loop bounds unroll."""

    @compiled_only
    def product(work, P):
        for i in range(d):
            for j in range(d):
                total = 0.0
                for m in range(d):
                    total += work[ws.U + d * i + m] * work[ws.G + m] * work[ws.V + d * j + m]
                P[i, j] = total

    return product


def workspace_first_piola(work, P, d):
    """P = U diag(g) Vᵀ from the U, G and V workspace slots, read by offset.

    Read by offset rather than through three views, whose reference counting costs about as
    much as the product. ``P`` is ``d×d``, ``d`` a compile-time literal.
    """
    _WORKSPACE_FIRST_PIOLA[d](work, P)


_WORKSPACE_FIRST_PIOLA = {d: _specialised_workspace_first_piola(d) for d in (2, 3)}
dispatch_on_dimension(workspace_first_piola, _WORKSPACE_FIRST_PIOLA)


@compiled_only
def _is_positive_definite(A):
    """Cholesky pivots all positive: no projection work needed (the common case)."""
    d = A.shape[0]
    a00 = A[0, 0]
    if not a00 > 0.0:
        return False
    if d == 2:
        return a00 * A[1, 1] - A[0, 1] * A[1, 0] > 0.0
    minor = a00 * A[1, 1] - A[0, 1] * A[1, 0]
    if not minor > 0.0:
        return False
    determinant = (
        A[0, 0] * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1])
        - A[0, 1] * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
        + A[0, 2] * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0])
    )
    return determinant > 0.0


@compiled_only
def _rotation(a_pp, a_qq, a_pq):
    """(c, s, t) of the Jacobi rotation that zeroes a_pq of a symmetric matrix (a_pq ≠ 0).

    t = tan θ is the smaller root of t² + 2ζt − 1 = 0, ζ = (a_qq − a_pp)/(2 a_pq), written with
    one square root and one division; then c = 1/√(1 + t²), s = t c.
    """
    h = a_qq - a_pp
    t = 2.0 * a_pq / (abs(h) + np.sqrt(h * h + 4.0 * a_pq * a_pq))
    if h < 0.0:
        t = -t
    c = 1.0 / np.sqrt(1.0 + t * t)
    return c, t * c, t


@compiled_only
def project_symmetric_3(A):
    """Replace the symmetric 3×3 ``A`` in place by its projection onto the PSD cone.

    Cyclic Jacobi on scalars (no array traffic inside the sweeps) until the off-diagonal part
    is below 1e-12 of the diagonal (dropping it then changes the result by as much: the
    projection is Lipschitz), then the eigenvalues clamped at zero.
    """
    a00, a11, a22 = A[0, 0], A[1, 1], A[2, 2]
    a01, a02, a12 = 0.5 * (A[0, 1] + A[1, 0]), 0.5 * (A[0, 2] + A[2, 0]), 0.5 * (A[1, 2] + A[2, 1])
    v00, v01, v02 = 1.0, 0.0, 0.0
    v10, v11, v12 = 0.0, 1.0, 0.0
    v20, v21, v22 = 0.0, 0.0, 1.0
    for _ in range(_MAX_EIGEN_SWEEPS):
        off = a01 * a01 + a02 * a02 + a12 * a12
        if off <= 1e-24 * (a00 * a00 + a11 * a11 + a22 * a22) or off == 0.0:
            break
        if a01 != 0.0:  # (p, q, r) = (0, 1, 2)
            c, s, t = _rotation(a00, a11, a01)
            a00, a11, a01 = a00 - t * a01, a11 + t * a01, 0.0
            a02, a12 = c * a02 - s * a12, s * a02 + c * a12
            v00, v01 = c * v00 - s * v01, s * v00 + c * v01
            v10, v11 = c * v10 - s * v11, s * v10 + c * v11
            v20, v21 = c * v20 - s * v21, s * v20 + c * v21
        if a02 != 0.0:  # (0, 2, 1)
            c, s, t = _rotation(a00, a22, a02)
            a00, a22, a02 = a00 - t * a02, a22 + t * a02, 0.0
            a01, a12 = c * a01 - s * a12, s * a01 + c * a12
            v00, v02 = c * v00 - s * v02, s * v00 + c * v02
            v10, v12 = c * v10 - s * v12, s * v10 + c * v12
            v20, v22 = c * v20 - s * v22, s * v20 + c * v22
        if a12 != 0.0:  # (1, 2, 0)
            c, s, t = _rotation(a11, a22, a12)
            a11, a22, a12 = a11 - t * a12, a22 + t * a12, 0.0
            a01, a02 = c * a01 - s * a02, s * a01 + c * a02
            v01, v02 = c * v01 - s * v02, s * v01 + c * v02
            v11, v12 = c * v11 - s * v12, s * v11 + c * v12
            v21, v22 = c * v21 - s * v22, s * v21 + c * v22
    e0, e1, e2 = max(a00, 0.0), max(a11, 0.0), max(a22, 0.0)
    A[0, 0] = v00 * e0 * v00 + v01 * e1 * v01 + v02 * e2 * v02
    A[1, 1] = v10 * e0 * v10 + v11 * e1 * v11 + v12 * e2 * v12
    A[2, 2] = v20 * e0 * v20 + v21 * e1 * v21 + v22 * e2 * v22
    A[0, 1] = A[1, 0] = v00 * e0 * v10 + v01 * e1 * v11 + v02 * e2 * v12
    A[0, 2] = A[2, 0] = v00 * e0 * v20 + v01 * e1 * v21 + v02 * e2 * v22
    A[1, 2] = A[2, 1] = v10 * e0 * v20 + v11 * e1 * v21 + v12 * e2 * v22


def _specialised_clamp_symmetric(d: int):
    """:func:`clamp_symmetric` for one dimension: constant loop bounds unroll."""

    @compiled_only
    def clamp(A, eigenvalues, eigenvectors):
        if _is_positive_definite(A):
            return
        if d == 3:
            project_symmetric_3(A)
            return
        for i in range(d):
            for j in range(d):
                eigenvectors[i, j] = 1.0 if i == j else 0.0
        for _ in range(_MAX_EIGEN_SWEEPS):
            off = 0.0
            diagonal = 0.0
            for p in range(d):
                diagonal += A[p, p] * A[p, p]
                for q in range(p + 1, d):
                    off += A[p, q] * A[p, q]
            if off <= 1e-32 * diagonal or off == 0.0:
                break
            for p in range(d - 1):
                for q in range(p + 1, d):
                    if A[p, q] == 0.0:
                        continue
                    theta = (A[q, q] - A[p, p]) / (2.0 * A[p, q])
                    t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
                    if theta < 0.0:
                        t = -t
                    c = 1.0 / np.sqrt(t * t + 1.0)
                    s = t * c
                    for k in range(d):
                        akp = A[k, p]
                        akq = A[k, q]
                        A[k, p] = c * akp - s * akq
                        A[k, q] = s * akp + c * akq
                    for k in range(d):
                        apk = A[p, k]
                        aqk = A[q, k]
                        A[p, k] = c * apk - s * aqk
                        A[q, k] = s * apk + c * aqk
                    for k in range(d):
                        vkp = eigenvectors[k, p]
                        vkq = eigenvectors[k, q]
                        eigenvectors[k, p] = c * vkp - s * vkq
                        eigenvectors[k, q] = s * vkp + c * vkq
        for m in range(d):
            eigenvalues[m] = max(A[m, m], 0.0)
        for i in range(d):
            for j in range(d):
                total = 0.0
                for m in range(d):
                    total += eigenvectors[i, m] * eigenvalues[m] * eigenvectors[j, m]
                A[i, j] = total

    return clamp


_clamp_symmetric_2d = _specialised_clamp_symmetric(2)
_clamp_symmetric_3d = _specialised_clamp_symmetric(3)


def clamp_symmetric(A, d, eigenvalues, eigenvectors):
    """Replace symmetric ``A`` in place by its projection onto the PSD cone (cyclic Jacobi).

    ``A`` is ``d×d``, ``d`` a compile-time literal in compiled code.
    """
    _CLAMP_SYMMETRIC[d](A, eigenvalues, eigenvectors)


_CLAMP_SYMMETRIC = {2: _clamp_symmetric_2d, 3: _clamp_symmetric_3d}
dispatch_on_dimension(clamp_symmetric, _CLAMP_SYMMETRIC)


def _specialised_stress_derivative(d: int):
    """:func:`stress_derivative` compiled for one dimension: constant loop bounds unroll."""
    clamp = _CLAMP_SYMMETRIC[d]

    @compiled_only
    def derivative(model_id, region, sigma, params, work, project, C):
        n = d * d
        U = ws.matrix(work, ws.U, d)
        V = ws.matrix(work, ws.V, d)
        A = ws.matrix(work, ws.A_BLOCK, d)
        hessian = ws.matrix(work, ws.H, d)
        gradient = ws.vector(work, ws.G, d)
        modes = ws.modes(work, ws.MODES, d)
        weighted = ws.modes(work, ws.WEIGHTED, d)
        for m in range(d):
            for i in range(d):
                for j in range(d):
                    modes[m, i * d + j] = U[i, m] * V[j, m]
        for i in range(d):
            for j in range(d):
                A[i, j] = hessian[i, j]
        if project:
            clamp(A, ws.vector(work, ws.EIGENVALUES, d), ws.matrix(work, ws.EIGENVECTORS, d))
        for m in range(d):
            for alpha in range(n):
                total = 0.0
                for k in range(d):
                    total += A[k, m] * modes[k, alpha]
                weighted[m, alpha] = total
        for alpha in range(n):
            for beta in range(alpha, n):
                total = 0.0
                for m in range(d):
                    total += weighted[m, alpha] * modes[m, beta]
                C[alpha, beta] = total
        stretch_mode = ws.vector(work, ws.STRETCH_MODE, n)
        twist_mode = ws.vector(work, ws.TWIST_MODE, n)
        for i in range(d - 1):
            for j in range(i + 1, d):
                stretch = gradient_slope(model_id, region, sigma, params, work, i, j)
                twist = rotation_slope(sigma, gradient, i, j)
                if project:
                    stretch = max(stretch, 0.0)
                    twist = max(twist, 0.0)
                # a s sᵀ + b t tᵀ with s, t = vec(uᵢ vⱼᵀ ± uⱼ vᵢᵀ)/√2; the 1/2 goes into a and b.
                for p in range(d):
                    for r in range(d):
                        x = U[p, i] * V[r, j]
                        y = U[p, j] * V[r, i]
                        stretch_mode[p * d + r] = x + y
                        twist_mode[p * d + r] = x - y
                stretch *= 0.5
                twist *= 0.5
                for alpha in range(n):
                    s_alpha = stretch * stretch_mode[alpha]
                    t_alpha = twist * twist_mode[alpha]
                    for beta in range(alpha, n):
                        C[alpha, beta] += s_alpha * stretch_mode[beta] + t_alpha * twist_mode[beta]
        for alpha in range(n):
            for beta in range(alpha):
                C[alpha, beta] = C[beta, alpha]

    return derivative


_stress_derivative_2d = _specialised_stress_derivative(2)


def stress_derivative(model_id, region, sigma, d, params, work, project, C):
    """dP/dF as a (d², d²) matrix into ``C`` from the U, V, G and H workspace slots.

    ``d`` is the length of ``sigma``, a compile-time literal in compiled code.
    """
    _STRESS_DERIVATIVE[d](model_id, region, sigma, params, work, project, C)


# The pair indices, not literals: the slope chain (down to the model's volume derivatives)
# compiles once, not once per pair.
_FIRST, _SECOND, _THIRD = run_time_integers(0, 1, 2)


@compiled_only
def _stress_derivative_3d(model_id, region, sigma, params, work, project, C):
    """Write the 3D tangent as C = Σₖ wₖ eₖᵀ over nine modes eₖ of the SVD frame.

    The modes are the three diagonal ones Dₘ and each pair's stretch and twist (without their
    1/√2); wₖ is Σₙ Aₙₘ Dₙ for a diagonal mode and ½a s or ½b t for a pair's. The workspace is
    read by offset rather than through views, and off the model the slopes come from their
    scalar cores: every array view or array argument costs two out-of-line reference-count
    calls, which made up most of the time of the assembly here. Modes and weights live in one
    stack array, which cannot alias ``C``, so each entry of ``C`` is written once.
    """
    U = ws.U
    V = ws.V
    A = ws.A_BLOCK
    for i in range(9):
        work[A + i] = work[ws.H + i]
    if project:
        _clamp_symmetric_3d(
            ws.matrix(work, A, 3),
            ws.vector(work, ws.EIGENVALUES, 3),
            ws.matrix(work, ws.EIGENVECTORS, 3),
        )
    # The slopes first: on the model they call into the model with array arguments.
    stretch01, twist01 = _pair_slopes(
        model_id, region, sigma, params, work, project, _FIRST, _SECOND
    )
    stretch02, twist02 = _pair_slopes(
        model_id, region, sigma, params, work, project, _FIRST, _THIRD
    )
    stretch12, twist12 = _pair_slopes(
        model_id, region, sigma, params, work, project, _SECOND, _THIRD
    )
    # Rows 0–8 the modes, rows 9–17 their weights.
    table = numba.carray(ws.stack_array(162), (18, 9))
    for m in range(3):
        for i in range(3):
            for j in range(3):
                table[m, 3 * i + j] = work[U + 3 * i + m] * work[V + 3 * j + m]
    for m in range(3):
        for alpha in range(9):
            table[9 + m, alpha] = (
                work[A + m] * table[0, alpha]
                + work[A + 3 + m] * table[1, alpha]
                + work[A + 6 + m] * table[2, alpha]
            )
    row = 3
    for i in range(2):
        for j in range(i + 1, 3):
            if i == 0:
                stretch, twist = (stretch01, twist01) if j == 1 else (stretch02, twist02)
            else:
                stretch, twist = stretch12, twist12
            for p in range(3):
                for r in range(3):
                    x = work[U + 3 * p + i] * work[V + 3 * r + j]
                    y = work[U + 3 * p + j] * work[V + 3 * r + i]
                    table[row, 3 * p + r] = x + y
                    table[row + 1, 3 * p + r] = x - y
                    table[9 + row, 3 * p + r] = stretch * (x + y)
                    table[10 + row, 3 * p + r] = twist * (x - y)
            row += 2
    for alpha in range(9):
        for beta in range(alpha, 9):
            total = 0.0
            for k in range(9):
                total += table[9 + k, alpha] * table[k, beta]
            C[alpha, beta] = total
            C[beta, alpha] = total


@compiled_only
def _pair_slopes(model_id, region, sigma, params, work, project, i, j):
    """½aᵢⱼ and ½bᵢⱼ (clamped at 0 if ``project``): the weights of the pair's two modes."""
    sigma_i = sigma[i]
    sigma_j = sigma[j]
    g_i = work[ws.G + i]
    g_j = work[ws.G + j]
    if region == 0:
        stretch = gradient_slope(model_id, region, sigma, params, work, i, j)
    else:
        stretch = quotient_slope(
            sigma_i,
            sigma_j,
            g_i,
            g_j,
            work[ws.H + 4 * i],
            work[ws.H + 4 * j],
            work[ws.H + 3 * i + j],
        )
    twist = sum_slope(sigma_i, sigma_j, g_i, g_j)
    if project:
        stretch = max(stretch, 0.0)
        twist = max(twist, 0.0)
    return 0.5 * stretch, 0.5 * twist


_STRESS_DERIVATIVE = {2: _stress_derivative_2d, 3: _stress_derivative_3d}
dispatch_on_dimension(stress_derivative, _STRESS_DERIVATIVE)
