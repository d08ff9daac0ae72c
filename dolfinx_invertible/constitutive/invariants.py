"""The SVD-free fast path: energy and stress from invariants where no extension can be active.

Where an extension provably cannot be active (C2 and IFE: J ≥ ε; C1: J > 0 and
Σ 1/σᵢ² ≤ 1/ε², which implies every σᵢ ≥ ε; no extension: always), a model written in the
invariants I₁ = tr C, I₂ = tr C² and J of C = FᵀF gives Ψ and

    P = 2 Ψ_{I₁} F + 4 Ψ_{I₂} F C + Ψ_J cof F

directly from F, and its derivative

    dP/dF = 2 Ψ_{I₁} 𝕀 + 4 Ψ_{I₂} ∂(F C)/∂F + Ψ_J ∂cof F/∂F + Σ_ab Ψ_ab vₐ ⊗ v_b,
    v = (2F, 4FC, cof F) = the derivatives of (I₁, I₂, J),

whose SPD projection is the identity whenever it is already positive definite (checked by a
Cholesky factorisation); only then does the projected tangent skip the SVD. Σ 1/σᵢ² = tr C⁻¹ is
itself an invariant: ½(I₁² − I₂)/J² in 3D, I₁/J² in 2D. (The paper prints the C1 test as "I₂/J²
≥ ε"; the sound test is the one above.)
"""

from __future__ import annotations

import numba
import numpy as np

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.extensions.registry import C1_ID, C2_ID, IFE_ID
from dolfinx_invertible.constitutive.models.registry import (
    model_invariant_curvature,
    model_invariant_terms,
)

__all__ = ["invariant_energy", "invariant_stress", "invariant_tangent", "extension_inactive"]


@numba.njit(cache=True)
def _invariants(F):
    """(I₁, I₂, J) of C = FᵀF."""
    d = F.shape[0]
    I1 = 0.0
    I2 = 0.0
    for i in range(d):
        for j in range(d):
            I1 += F[i, j] * F[i, j]
            C_ij = 0.0
            for k in range(d):
                C_ij += F[k, i] * F[k, j]
            I2 += C_ij * C_ij
    if d == 2:
        J = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    else:
        J = (
            F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
            - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
            + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0])
        )
    return I1, I2, J


@numba.njit(cache=True)
def extension_inactive(extension_id, positive_only, I1, I2, J, d, params):
    """Return True where the (extended) energy equals the model itself, decided without an SVD.

    For a plain model that needs J > 0 this is also True at J ≤ 0: the point is undefined, which
    the caller reports, and no SVD is needed to know it.
    """
    eps = params[2]
    if extension_id == C2_ID or extension_id == IFE_ID:
        return J >= eps
    if extension_id == C1_ID:
        if not J > 0.0:
            return False
        inverse_squares = I1 / (J * J) if d == 2 else 0.5 * (I1 * I1 - I2) / (J * J)
        return inverse_squares * eps * eps <= 1.0
    return True


@numba.njit(cache=True)
def invariant_energy(F, model_id, extension_id, positive_only, params):
    """(done, Ψ, region): ``done`` is False when the SVD path is needed."""
    d = F.shape[0]
    I1, I2, J = _invariants(F)
    if not extension_inactive(extension_id, positive_only, I1, I2, J, d, params):
        return False, 0.0, 0
    if positive_only and not J > 0.0:
        return True, np.inf, -1
    available, psi, _, _, _ = model_invariant_terms(model_id, I1, I2, J, d, params)
    return available, psi, 0


@numba.njit(cache=True)
def invariant_stress(F, model_id, extension_id, positive_only, params, P):
    """(done, Ψ, region) with P written when ``done``; False when the SVD path is needed."""
    d = F.shape[0]
    I1, I2, J = _invariants(F)
    if not extension_inactive(extension_id, positive_only, I1, I2, J, d, params):
        return False, 0.0, 0
    if positive_only and not J > 0.0:
        P[:, :] = 0.0
        return True, np.inf, -1
    available, psi, d1, d2, dJ = model_invariant_terms(model_id, I1, I2, J, d, params)
    if not available:
        return False, 0.0, 0
    for i in range(d):
        for j in range(d):
            # (F C)_ij = Σ_k F_ik C_kj and cof(F)_ij = ∂J/∂F_ij
            FC = 0.0
            if d2 != 0.0:
                for k in range(d):
                    C_kj = 0.0
                    for m in range(d):
                        C_kj += F[m, k] * F[m, j]
                    FC += F[i, k] * C_kj
            P[i, j] = 2.0 * d1 * F[i, j] + 4.0 * d2 * FC + dJ * _cofactor(F, i, j)
    return True, psi, 0


@numba.njit(cache=True)
def _cofactor(F, i, j):
    d = F.shape[0]
    if d == 2:
        sign = 1.0 if i == j else -1.0
        return sign * F[1 - i, 1 - j]
    i1 = (i + 1) % 3
    i2 = (i + 2) % 3
    j1 = (j + 1) % 3
    j2 = (j + 2) % 3
    return F[i1, j1] * F[i2, j2] - F[i1, j2] * F[i2, j1]


def _specialised_cholesky_positive(n: int):
    """Cholesky of a symmetric n×n matrix (read, not written) succeeds with positive pivots."""

    @numba.njit(cache=True)
    def positive(C):
        factor = numba.carray(ws.stack_array(81), (9, 9))
        for j in range(n):
            pivot = C[j, j]
            for k in range(j):
                pivot -= factor[j, k] * factor[j, k]
            if not pivot > 0.0:
                return False
            root = np.sqrt(pivot)
            factor[j, j] = root
            for i in range(j + 1, n):
                value = C[i, j]
                for k in range(j):
                    value -= factor[i, k] * factor[j, k]
                factor[i, j] = value / root
        return True

    return positive


_cholesky_positive_2d = _specialised_cholesky_positive(4)
_cholesky_positive_3d = _specialised_cholesky_positive(9)


@numba.njit(cache=True)
def invariant_tangent(F, model_id, extension_id, positive_only, params, project, P, C):
    """(done, Ψ, region) with P and dP/dF written when ``done``.

    False when the SVD path is needed: the extension may be active, the model is not written in
    invariants, or the projection was asked for and the tangent is not positive definite.
    """
    if F.shape[0] == 3:
        return _invariant_tangent_3d(
            F, model_id, extension_id, positive_only, params, project, P, C
        )
    return _invariant_tangent_2d(F, model_id, extension_id, positive_only, params, project, P, C)


def _specialised_invariant_tangent(d: int):
    """:func:`invariant_tangent` compiled for one dimension: constant loop bounds unroll."""

    @numba.njit(cache=True)
    def tangent(F, model_id, extension_id, positive_only, params, project, P, C):
        I1, I2, J = _invariants(F)
        if not extension_inactive(extension_id, positive_only, I1, I2, J, d, params):
            return False, 0.0, 0
        n = d * d
        if positive_only and not J > 0.0:
            P[:, :] = 0.0
            C[:, :] = 0.0
            return True, np.inf, -1
        available, psi, d1, d2, dJ = model_invariant_terms(model_id, I1, I2, J, d, params)
        if not available:
            return False, 0.0, 0
        c11, c22, cJJ, c12, c1J, c2J = model_invariant_curvature(model_id, I1, I2, J, d, params)
        vectors = numba.carray(ws.stack_array(27), (3, 9))
        right = numba.carray(ws.stack_array(9), (3, 3))  # C = FᵀF
        left = numba.carray(ws.stack_array(9), (3, 3))  # B = FFᵀ
        for i in range(d):
            for j in range(d):
                total_right = 0.0
                total_left = 0.0
                for k in range(d):
                    total_right += F[k, i] * F[k, j]
                    total_left += F[i, k] * F[j, k]
                right[i, j] = total_right
                left[i, j] = total_left
        for i in range(d):
            for j in range(d):
                FC = 0.0
                for k in range(d):
                    FC += F[i, k] * right[k, j]
                vectors[0, i * d + j] = 2.0 * F[i, j]
                vectors[1, i * d + j] = 4.0 * FC
                vectors[2, i * d + j] = _cofactor(F, i, j)
                P[i, j] = (
                    d1 * vectors[0, i * d + j]
                    + d2 * vectors[1, i * d + j]
                    + dJ * vectors[2, i * d + j]
                )
        for alpha in range(n):
            a0 = vectors[0, alpha]
            a1 = vectors[1, alpha]
            a2 = vectors[2, alpha]
            w0 = c11 * a0 + c12 * a1 + c1J * a2
            w1 = c12 * a0 + c22 * a1 + c2J * a2
            w2 = c1J * a0 + c2J * a1 + cJJ * a2
            for beta in range(n):
                C[alpha, beta] = (
                    w0 * vectors[0, beta] + w1 * vectors[1, beta] + w2 * vectors[2, beta]
                )
            C[alpha, alpha] += 2.0 * d1
        if d2 != 0.0:
            # 4 Ψ₂ ∂(FC)_ij/∂F_kl = 4 Ψ₂ (δ_ik C_lj + F_il F_kj + B_ik δ_jl)
            for i in range(d):
                for j in range(d):
                    for k in range(d):
                        for l in range(d):
                            value = F[i, l] * F[k, j]
                            if i == k:
                                value += right[l, j]
                            if j == l:
                                value += left[i, k]
                            C[i * d + j, k * d + l] += 4.0 * d2 * value
        if dJ != 0.0:
            if d == 2:
                for i in range(2):
                    for j in range(2):
                        C[i * 2 + j, (1 - i) * 2 + (1 - j)] += dJ if i == j else -dJ
            else:
                for i in range(3):
                    i1 = (i + 1) % 3
                    i2 = (i + 2) % 3
                    for j in range(3):
                        j1 = (j + 1) % 3
                        j2 = (j + 2) % 3
                        row = i * 3 + j
                        C[row, i1 * 3 + j1] += dJ * F[i2, j2]
                        C[row, i2 * 3 + j2] += dJ * F[i1, j1]
                        C[row, i1 * 3 + j2] -= dJ * F[i2, j1]
                        C[row, i2 * 3 + j1] -= dJ * F[i1, j2]
        if project:
            positive = _cholesky_positive_3d(C) if d == 3 else _cholesky_positive_2d(C)
            if not positive:
                return False, 0.0, 0
        return True, psi, 0

    return tangent


_invariant_tangent_2d = _specialised_invariant_tangent(2)
_invariant_tangent_3d = _specialised_invariant_tangent(3)
