"""The SVD-free fast path: energy and stress from invariants where no extension can be active.

Where an extension provably cannot be active (C2 and IFE: J ≥ ε; C1: J > 0 and
Σ 1/σᵢ² ≤ 1/ε², which implies every σᵢ ≥ ε; no extension: always), a model written in the
invariants I₁ = tr C, I₂ = tr C² and J of C = FᵀF gives Ψ and

    P = 2 Ψ_{I₁} F + 4 Ψ_{I₂} F C + Ψ_J cof F

directly from F, and its derivative

    dP/dF = 2 Ψ_{I₁} 𝕀 + 4 Ψ_{I₂} ∂(F C)/∂F + Ψ_J ∂cof F/∂F + Σ_ab Ψ_ab vₐ ⊗ v_b,
    v = (2F, 4FC, cof F) = the derivatives of (I₁, I₂, J),

whose SPD projection is the identity whenever it is already positive definite (checked by an
LDLᵀ factorisation). Near rest it often is not, but only in its twist modes vec(R K) (R the polar
rotation, K skew): their stiffnesses (gᵢ + gⱼ)/(σᵢ + σⱼ) are negative under compressive stress
and zero at P = 0. Those modes span an invariant subspace found without an SVD (R by Newton's
polar iteration), so the fast path projects that 3×3 block (1×1 in 2D) and accepts the result if
the rest of the tangent is positive definite, a twist block within round-off of zero counting as
semidefinite; the outcome is the projected tangent (the tests compare it with the eigenvalue
clamp of the exact one). Only what still fails takes the SVD. Σ 1/σᵢ² = tr C⁻¹ is itself an
invariant: ½(I₁² − I₂)/J² in 3D, I₁/J² in 2D. (The paper prints the C1 test as "I₂/J² ≥ ε"; the
sound test is the one above.)
"""

from __future__ import annotations

import numba
import numpy as np

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.extensions.registry import C1_ID, C2_ID, IFE_ID
from dolfinx_invertible.constitutive.models.registry import (
    model_invariant_curvature,
    model_invariant_terms,
    model_uses_second_invariant,
)
from dolfinx_invertible.constitutive.tangent import project_symmetric_3

__all__ = [
    "extension_inactive",
    "invariant_energy",
    "invariant_stress",
    "invariant_tangent",
    "invariants",
]


@numba.njit(cache=True)
def invariants(F, model_id, extension_id):
    """(I₁, I₂, J) of C = FᵀF; I₂ only where the model or the extension's test needs it (else 0).

    The ids are compile-time literals, so the test folds away.
    """
    d = F.shape[0]
    I1 = 0.0
    I2 = 0.0
    for i in range(d):
        for j in range(d):
            I1 += F[i, j] * F[i, j]
    if model_uses_second_invariant(model_id) or extension_id == C1_ID:
        for i in range(d):
            for j in range(d):
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
def invariant_energy(F, I1, I2, J, model_id, extension_id, positive_only, params):
    """(done, Ψ, region): ``done`` is False when the SVD path is needed."""
    d = F.shape[0]
    if not extension_inactive(extension_id, positive_only, I1, I2, J, d, params):
        return False, 0.0, 0
    if positive_only and not J > 0.0:
        return True, np.inf, -1
    available, psi, _, _, _ = model_invariant_terms(model_id, I1, I2, J, d, params)
    return available, psi, 0


@numba.njit(cache=True)
def invariant_stress(F, I1, I2, J, model_id, extension_id, positive_only, params, P):
    """(done, Ψ, region) with P written when ``done``; False when the SVD path is needed."""
    d = F.shape[0]
    if not extension_inactive(extension_id, positive_only, I1, I2, J, d, params):
        return False, 0.0, 0
    if positive_only and not J > 0.0:
        P[:, :] = 0.0
        return True, np.inf, -1
    available, psi, d1, d2, dJ = model_invariant_terms(model_id, I1, I2, J, d, params)
    if not available:
        return False, 0.0, 0
    if d == 2:
        P[0, 0] = 2.0 * d1 * F[0, 0] + dJ * F[1, 1]
        P[0, 1] = 2.0 * d1 * F[0, 1] - dJ * F[1, 0]
        P[1, 0] = 2.0 * d1 * F[1, 0] - dJ * F[0, 1]
        P[1, 1] = 2.0 * d1 * F[1, 1] + dJ * F[0, 0]
    else:
        P[0, 0] = 2.0 * d1 * F[0, 0] + dJ * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
        P[0, 1] = 2.0 * d1 * F[0, 1] + dJ * (F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2])
        P[0, 2] = 2.0 * d1 * F[0, 2] + dJ * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0])
        P[1, 0] = 2.0 * d1 * F[1, 0] + dJ * (F[2, 1] * F[0, 2] - F[2, 2] * F[0, 1])
        P[1, 1] = 2.0 * d1 * F[1, 1] + dJ * (F[2, 2] * F[0, 0] - F[2, 0] * F[0, 2])
        P[1, 2] = 2.0 * d1 * F[1, 2] + dJ * (F[2, 0] * F[0, 1] - F[2, 1] * F[0, 0])
        P[2, 0] = 2.0 * d1 * F[2, 0] + dJ * (F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1])
        P[2, 1] = 2.0 * d1 * F[2, 1] + dJ * (F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2])
        P[2, 2] = 2.0 * d1 * F[2, 2] + dJ * (F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0])
    if model_uses_second_invariant(model_id) and d2 != 0.0:
        # + 4 Ψ₂ F C, (F C)_ij = Σ_k F_ik C_kj
        for i in range(d):
            for j in range(d):
                FC = 0.0
                for k in range(d):
                    C_kj = 0.0
                    for m in range(d):
                        C_kj += F[m, k] * F[m, j]
                    FC += F[i, k] * C_kj
                P[i, j] += 4.0 * d2 * FC
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


def _specialised_positive(n: int):
    """Test a symmetric n×n matrix (read, not written) for positive definiteness by LDLᵀ.

    Every pivot > 0; unpivoted, one division per pivot and no square roots.
    """

    @numba.njit(cache=True)
    def positive(C):
        factor = numba.carray(ws.stack_array(81), (9, 9))  # L below the diagonal
        pivots = numba.carray(ws.stack_array(9), 9)
        scaled = numba.carray(ws.stack_array(9), 9)  # row j of L times the pivots
        for j in range(n):
            for k in range(j):
                scaled[k] = factor[j, k] * pivots[k]
            pivot = C[j, j]
            for k in range(j):
                pivot -= factor[j, k] * scaled[k]
            if not pivot > 0.0:
                return False
            inverse = 1.0 / pivot
            pivots[j] = pivot
            for i in range(j + 1, n):
                value = C[i, j]
                for k in range(j):
                    value -= factor[i, k] * scaled[k]
                factor[i, j] = value * inverse
        return True

    return positive


_positive_2d = _specialised_positive(4)
_positive_3d = _specialised_positive(9)
_MAX_POLAR_ITERATIONS = 12
# A twist block whose smallest eigenvalue exceeds this (relative to the largest diagonal entry
# of the tangent) is positive definite beyond round-off.
_TWIST_MARGIN = 1e-10


@numba.njit(cache=True)
def _polar_rotation_3d(F, R):
    """R of the polar decomposition F = R S (det F > 0) by Newton's iteration R ← (R + R⁻ᵀ)/2.

    Quadratic convergence from R = F; near rest four iterations reach round-off. False if it
    has not converged within the iteration cap (a strongly distorted F: the caller takes the
    SVD instead).
    """
    for i in range(3):
        for j in range(3):
            R[i, j] = F[i, j]
    for _ in range(_MAX_POLAR_ITERATIONS):
        c00 = R[1, 1] * R[2, 2] - R[1, 2] * R[2, 1]
        c01 = R[1, 2] * R[2, 0] - R[1, 0] * R[2, 2]
        c02 = R[1, 0] * R[2, 1] - R[1, 1] * R[2, 0]
        c10 = R[2, 1] * R[0, 2] - R[2, 2] * R[0, 1]
        c11 = R[2, 2] * R[0, 0] - R[2, 0] * R[0, 2]
        c12 = R[2, 0] * R[0, 1] - R[2, 1] * R[0, 0]
        c20 = R[0, 1] * R[1, 2] - R[0, 2] * R[1, 1]
        c21 = R[0, 2] * R[1, 0] - R[0, 0] * R[1, 2]
        c22 = R[0, 0] * R[1, 1] - R[0, 1] * R[1, 0]
        determinant = R[0, 0] * c00 + R[0, 1] * c01 + R[0, 2] * c02
        if not determinant > 0.0:
            return False
        half_inverse = 0.5 / determinant
        new00 = 0.5 * R[0, 0] + half_inverse * c00
        new01 = 0.5 * R[0, 1] + half_inverse * c01
        new02 = 0.5 * R[0, 2] + half_inverse * c02
        new10 = 0.5 * R[1, 0] + half_inverse * c10
        new11 = 0.5 * R[1, 1] + half_inverse * c11
        new12 = 0.5 * R[1, 2] + half_inverse * c12
        new20 = 0.5 * R[2, 0] + half_inverse * c20
        new21 = 0.5 * R[2, 1] + half_inverse * c21
        new22 = 0.5 * R[2, 2] + half_inverse * c22
        change = max(
            abs(new00 - R[0, 0]), abs(new01 - R[0, 1]), abs(new02 - R[0, 2]),
            abs(new10 - R[1, 0]), abs(new11 - R[1, 1]), abs(new12 - R[1, 2]),
            abs(new20 - R[2, 0]), abs(new21 - R[2, 1]), abs(new22 - R[2, 2]),
        )  # fmt: skip
        R[0, 0], R[0, 1], R[0, 2] = new00, new01, new02
        R[1, 0], R[1, 1], R[1, 2] = new10, new11, new12
        R[2, 0], R[2, 1], R[2, 2] = new20, new21, new22
        # Quadratic convergence: the error left is about change²/2.
        if change <= 1e-9:
            return True
    return False


def _specialised_twist_projection(d: int):
    """Project the twist block of an exact invariant-form tangent, without an SVD.

    For an isotropic energy the twist modes vec(R K) (R the polar rotation of F, K skew) span an
    invariant subspace of dP/dF, on which the tangent acts as the symmetric m×m matrix
    M = Tᵀ C T (m = 1 in 2D, 3 in 3D; T holds the orthonormal modes); its eigenvalues are the
    rotational stiffnesses (gᵢ + gⱼ)/(σᵢ + σⱼ), negative under compression. Clamping them (C += T
    (M₊ − M) Tᵀ) is the SPD projection restricted to that subspace; if the rest of C is positive
    semidefinite (the caller checks), the result is the projected tangent itself.

    Returns False when the polar iteration fails, or when M is already positive definite (then
    the twist modes are not what made C fail the test, and the SVD is needed).
    """
    n = d * d
    m = 1 if d == 2 else 3

    @numba.njit(cache=True)
    def projection(F, C, shifted):
        R = numba.carray(ws.stack_array(9), (3, 3))
        modes = numba.carray(ws.stack_array(27), (3, 9))  # the twist modes, one per row
        image = numba.carray(ws.stack_array(27), (3, 9))  # C applied to each
        M = numba.carray(ws.stack_array(9), (3, 3))
        change = numba.carray(ws.stack_array(9), (3, 3))
        weighted = numba.carray(ws.stack_array(27), (3, 9))
        if d == 2:
            # F + cof F is a positive multiple of the polar rotation (det F > 0).
            c = F[0, 0] + F[1, 1]
            s = F[1, 0] - F[0, 1]
            norm = np.sqrt(c * c + s * s)
            if not norm > 0.0:
                return False
            c /= norm
            s /= norm
            # vec(R K)/√2 with K = [[0, −1], [1, 0]]: R K = [[−s, −c], [c, −s]].
            root_half = np.sqrt(0.5)
            modes[0, 0] = -s * root_half
            modes[0, 1] = -c * root_half
            modes[0, 2] = c * root_half
            modes[0, 3] = -s * root_half
        else:
            if not _polar_rotation_3d(F, R):
                return False
            root_half = np.sqrt(0.5)
            # K_k = the skew matrix of axis k: (R K_k)_ij = Σ_l R_il (K_k)_lj.
            for k in range(3):
                k1 = (k + 1) % 3
                k2 = (k + 2) % 3
                for i in range(3):
                    for j in range(3):
                        modes[k, i * 3 + j] = 0.0
                    # (K_k)_{k1,k2} = −1, (K_k)_{k2,k1} = +1
                    modes[k, i * 3 + k2] -= R[i, k1] * root_half
                    modes[k, i * 3 + k1] += R[i, k2] * root_half
        for k in range(m):
            for alpha in range(n):
                total = 0.0
                for beta in range(n):
                    total += C[alpha, beta] * modes[k, beta]
                image[k, alpha] = total
        for k in range(m):
            for l in range(m):
                total = 0.0
                for alpha in range(n):
                    total += modes[k, alpha] * image[l, alpha]
                M[k, l] = total
        shift = 0.0
        for alpha in range(n):
            shift = max(shift, C[alpha, alpha])
        # Clearly positive definite twist block (beyond round-off): the twist modes are not what
        # made C fail, so projecting them cannot help.
        margin = _TWIST_MARGIN * shift
        if m == 1:
            if M[0, 0] > margin:
                return False
            change[0, 0] = max(M[0, 0], 0.0) - M[0, 0]
        else:
            for k in range(3):
                for l in range(k + 1, 3):
                    average = 0.5 * (M[k, l] + M[l, k])
                    M[k, l] = average
                    M[l, k] = average
            for k in range(3):
                M[k, k] -= margin
            clearly_positive = _positive_definite_3(M)
            for k in range(3):
                M[k, k] += margin
            if clearly_positive:
                return False
            for k in range(3):
                for l in range(3):
                    change[k, l] = -M[k, l]
            project_symmetric_3(M)
            for k in range(3):
                for l in range(3):
                    change[k, l] += M[k, l]
        for k in range(m):
            for beta in range(n):
                total = 0.0
                for l in range(m):
                    total += change[k, l] * modes[l, beta]
                weighted[k, beta] = total
        # C += T (M₊ − M) Tᵀ; ``shifted`` = that + s T Tᵀ (s the largest diagonal entry of C), which
        # is positive definite exactly when the rest of C is: a plain LDLᵀ test decides.
        for alpha in range(n):
            for beta in range(n):
                total = 0.0
                projector = 0.0
                for k in range(m):
                    total += modes[k, alpha] * weighted[k, beta]
                    projector += modes[k, alpha] * modes[k, beta]
                C[alpha, beta] += total
                shifted[alpha, beta] = C[alpha, beta] + shift * projector
        return True

    return projection


@numba.njit(cache=True)
def _positive_definite_3(A):
    """Leading minors of a symmetric 3×3 matrix all positive."""
    if not A[0, 0] > 0.0:
        return False
    minor = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    if not minor > 0.0:
        return False
    determinant = (
        A[0, 0] * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1])
        - A[0, 1] * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
        + A[0, 2] * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0])
    )
    return determinant > 0.0


_twist_projection_2d = _specialised_twist_projection(2)
_twist_projection_3d = _specialised_twist_projection(3)


@numba.njit(cache=True)
def invariant_tangent(F, I1, I2, J, model_id, extension_id, positive_only, params, project, P, C):
    """(done, Ψ, region) with P and dP/dF written when ``done``.

    False when the SVD path is needed: the extension may be active, the model is not written in
    invariants, or the projection was asked for and the tangent is neither positive definite
    nor made positive semidefinite by projecting its twist block.
    """
    if F.shape[0] == 3:
        return _invariant_tangent_3d(
            F, I1, I2, J, model_id, extension_id, positive_only, params, project, P, C
        )
    return _invariant_tangent_2d(
        F, I1, I2, J, model_id, extension_id, positive_only, params, project, P, C
    )


def _specialised_invariant_tangent(d: int):
    """:func:`invariant_tangent` compiled for one dimension: constant loop bounds unroll."""

    @numba.njit(cache=True)
    def tangent(F, I1, I2, J, model_id, extension_id, positive_only, params, project, P, C):
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
        if model_uses_second_invariant(model_id) and d2 != 0.0:
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
            positive = _positive_3d if d == 3 else _positive_2d
            if not positive(C):
                # Near rest the only negative stiffness is rotational (compressive stress):
                # clamp the twist block, then accept what is semidefinite within round-off.
                # Tolerance-aware acceptance: a twist block within round-off of zero counts as
                # semidefinite (its clamp changes nothing), and the shifted matrix is positive
                # definite iff the rest of C is; then C, with its twist block projected, is the
                # projected tangent (no SVD).
                shifted = numba.carray(ws.stack_array(81), (n, n))
                twist_projection = _twist_projection_3d if d == 3 else _twist_projection_2d
                if not twist_projection(F, C, shifted):
                    return False, 0.0, 0
                if not positive(shifted):
                    return False, 0.0, 0
        return True, psi, 0

    return tangent


_invariant_tangent_2d = _specialised_invariant_tangent(2)
_invariant_tangent_3d = _specialised_invariant_tangent(3)
