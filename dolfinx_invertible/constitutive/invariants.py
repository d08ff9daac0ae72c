"""The SVD-free fast path: energy and stress from invariants where no extension can be active.

Where an extension provably cannot be active (C2 and IFE: J ≥ ε; C1: J > 0 and
Σ 1/σᵢ² ≤ 1/ε², which implies every σᵢ ≥ ε; no extension: always), a model written in the
invariants I₁ = tr C, I₂ = tr C² and J of C = FᵀF gives Ψ and

    P = 2 Ψ_{I₁} F + 4 Ψ_{I₂} F C + Ψ_J cof F

directly from F, and its derivative

    dP/dF = 2 Ψ_{I₁} 𝕀 + 4 Ψ_{I₂} ∂(F C)/∂F + Ψ_J ∂cof F/∂F + Σ_ab Ψ_ab vₐ ⊗ v_b,
    v = (2F, 4FC, cof F) = the derivatives of (I₁, I₂, J),

whose SPD projection needs no SVD either where its eigenvalues can be decided from σ alone. Those
are the σ-Hessian's and, for each pair, the stretch and twist stiffnesses 2Ψ₁ ∓ Ψ_J σₖ +
4Ψ₂(σᵢ² ± σᵢσⱼ + σⱼ²), with σ from the eigenvalues of C in closed form
(:func:`spectral_projection`). Near rest only the twist stiffnesses can be negative (compressive
stress; zero at P = 0), and their modes vec(R K) (R the polar rotation by Newton's iteration, K
skew) span an invariant subspace, so the projection subtracts the negative part of that 3×3 block
(1×1 in 2D); points whose stretch or Hessian eigenvalues are not clearly positive take the
SVD.

Σ 1/σᵢ² = tr C⁻¹ is itself an invariant: ½(I₁² − I₂)/J² in 3D, I₁/J² in 2D. (The paper prints
the C1 test as "I₂/J² ≥ ε"; the sound test is the one above.)
"""

from __future__ import annotations

import numba
import numpy as np

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.constitutive.extensions.registry import C1_ID, C2_ID, IFE_ID
from dolfinx_invertible.constitutive.literal import dispatch_on_dimension
from dolfinx_invertible.constitutive.models.registry import (
    model_invariant_curvature,
    model_invariant_terms,
    model_uses_second_invariant,
)
from dolfinx_invertible.constitutive.symmetric3 import eigenvalues, null_vector

__all__ = [
    "extension_inactive",
    "invariant_energy",
    "invariant_stress",
    "invariant_tangent",
    "invariants",
    "spectral_projection",
]


@compiled_only
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


@compiled_only
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


@compiled_only
def invariant_energy(F, I1, I2, J, model_id, extension_id, positive_only, params):
    """(done, Ψ, region): ``done`` is False when the SVD path is needed."""
    d = F.shape[0]
    if not extension_inactive(extension_id, positive_only, I1, I2, J, d, params):
        return False, 0.0, 0
    if positive_only and not J > 0.0:
        return True, np.inf, -1
    available, psi, _, _, _ = model_invariant_terms(model_id, I1, I2, J, d, params)
    return available, psi, 0


@compiled_only
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


@compiled_only
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


_MAX_POLAR_ITERATIONS = 12
# The stretch and diagonal-block stiffnesses computed from σ must exceed this, relative to the
# largest diagonal entry of the tangent, for the test to accept the point: their error is below
# 1e-11 of it wherever the test is used (see `_CONDITION_FLOOR`), so a point accepted has
# exactly those eigenvalues positive.
_DECISION_MARGIN = 1e-9
# σ comes from the eigenvalues of FᵀF, whose error is a few ulps of the largest one λ₁: the middle
# one must be at least this fraction of λ₁ for √λ₂ to be good to 1e-12 (the smallest singular
# value is J/(σ₁σ₂), as accurate as σ₁ and σ₂). More distorted points take the SVD.
_CONDITION_FLOOR = 1e-2
#: :func:`spectral_projection`'s code for a point it cannot decide: the SVD path is needed.
SPECTRAL_NEEDS_SVD = -1


@compiled_only
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


@compiled_only
def _positive_definite_3(a00, a11, a22, a01, a02, a12):
    """Leading minors of a symmetric 3×3 matrix (given by its six entries) all positive."""
    if not a00 > 0.0:
        return False
    minor = a00 * a11 - a01 * a01
    if not minor > 0.0:
        return False
    determinant = a00 * (a11 * a22 - a12 * a12) - a01 * (a01 * a22 - a12 * a02)
    determinant += a02 * (a01 * a12 - a11 * a02)
    return determinant > 0.0


def _specialised_spectral_projection(d: int):
    """:func:`spectral_projection` for one dimension: constant loop bounds unroll."""
    n = d * d

    @compiled_only
    def projection(F, J, d1, d2, dJ, c11, c22, cJJ, c12, c1J, c2J, C):
        # σ from the eigenvalues of FᵀF; the smallest, signed, as J over the others.
        a00 = 0.0
        a11 = 0.0
        a22 = 0.0
        a01 = 0.0
        a02 = 0.0
        a12 = 0.0
        for k in range(d):
            a00 += F[k, 0] * F[k, 0]
            a11 += F[k, 1] * F[k, 1]
            a01 += F[k, 0] * F[k, 1]
            if d == 3:
                a22 += F[k, 2] * F[k, 2]
                a02 += F[k, 0] * F[k, 2]
                a12 += F[k, 1] * F[k, 2]
        if d == 3:
            l1, l2, _ = eigenvalues(a00, a11, a22, a01, a02, a12)
            if not (l1 > 0.0 and l2 >= _CONDITION_FLOOR * l1 and l1 < np.inf):
                return SPECTRAL_NEEDS_SVD
            s1 = np.sqrt(l1)
            s2 = np.sqrt(l2)
            s3 = J / (s1 * s2)
        else:
            half_difference = 0.5 * (a00 - a11)
            l1 = 0.5 * (a00 + a11) + np.sqrt(half_difference * half_difference + a01 * a01)
            if not (l1 > 0.0 and l1 < np.inf):
                return SPECTRAL_NEEDS_SVD
            s1 = np.sqrt(l1)
            s2 = J / s1
            s3 = 1.0
        sigma = numba.carray(ws.stack_array(3), 3)
        sigma[0] = s1
        sigma[1] = s2
        sigma[2] = s3
        shift = 0.0
        for alpha in range(n):
            shift = max(shift, C[alpha, alpha])
        margin = _DECISION_MARGIN * shift
        # With g = ∇σ Ψ(I₁, I₂, J), the pair (i, j) has the stretch stiffness (gᵢ − gⱼ)/(σᵢ − σⱼ)
        # = 2Ψ₁ − Ψ_J σₖ + 4Ψ₂(σᵢ² + σᵢσⱼ + σⱼ²) and the twist stiffness (gᵢ + gⱼ)/(σᵢ + σⱼ)
        # = 2Ψ₁ + Ψ_J σₖ + 4Ψ₂(σᵢ² − σᵢσⱼ + σⱼ²), k the third index (σₖ → 1 in 2D): no
        # quotient of differences, so no loss when σᵢ ≈ σⱼ.
        twist = numba.carray(ws.stack_array(3), 3)
        negative_twists = 0
        for k in range(1 if d == 2 else 3):
            i = 0 if d == 2 else (k + 1) % 3
            j = 1 if d == 2 else (k + 2) % 3
            other = 1.0 if d == 2 else sigma[k]
            squares = sigma[i] * sigma[i] + sigma[j] * sigma[j]
            product = sigma[i] * sigma[j]
            stretch = 2.0 * d1 - dJ * other + 4.0 * d2 * (squares + product)
            if not stretch > margin:
                return SPECTRAL_NEEDS_SVD
            twist[k] = 2.0 * d1 + dJ * other + 4.0 * d2 * (squares - product)
            if twist[k] < 0.0:
                negative_twists += 1
        # The diagonal block: the σ-Hessian of Ψ(I₁(σ), I₂(σ), J(σ)), with the invariants'
        # gradients (2σᵢ, 4σᵢ³, J/σᵢ) and ∂²J/∂σᵢ∂σⱼ = σₖ (1 in 2D).
        gradients = numba.carray(ws.stack_array(9), (3, 3))
        for i in range(d):
            gradients[0, i] = 2.0 * sigma[i]
            gradients[1, i] = 4.0 * sigma[i] * sigma[i] * sigma[i]
        if d == 3:
            gradients[2, 0] = s2 * s3
            gradients[2, 1] = s1 * s3
            gradients[2, 2] = s1 * s2
        else:
            gradients[2, 0] = s2
            gradients[2, 1] = s1
        h = numba.carray(ws.stack_array(9), (3, 3))
        for i in range(d):
            for j in range(i, d):
                x0 = gradients[0, j]
                x1 = gradients[1, j]
                x2 = gradients[2, j]
                value = gradients[0, i] * (c11 * x0 + c12 * x1 + c1J * x2)
                value += gradients[1, i] * (c12 * x0 + c22 * x1 + c2J * x2)
                value += gradients[2, i] * (c1J * x0 + c2J * x1 + cJJ * x2)
                if i == j:
                    value += 2.0 * d1 + 12.0 * d2 * sigma[i] * sigma[i] - margin
                else:
                    value += dJ * (1.0 if d == 2 else sigma[3 - i - j])
                h[i, j] = value
        if d == 3:
            positive = _positive_definite_3(h[0, 0], h[1, 1], h[2, 2], h[0, 1], h[0, 2], h[1, 2])
        else:
            positive = h[0, 0] > 0.0 and h[0, 0] * h[1, 1] - h[0, 1] * h[0, 1] > 0.0
        if not positive:
            return SPECTRAL_NEEDS_SVD
        if negative_twists == 0:
            return 0
        if not J > 0.0:
            return SPECTRAL_NEEDS_SVD
        # C −= T M₋ Tᵀ: T holds the orthonormal twist modes vec(R K)/√2 (R the polar rotation,
        # K skew), on which C acts as M = 2Ψ₁ I + Ψ_J S + 4Ψ₂(tr(S²) I − S² − adj S) in 3D
        # (S = RᵀF) and as the twist stiffness in 2D; M₋ is its negative part.
        modes = numba.carray(ws.stack_array(27), (3, 9))  # one mode per row
        negative = numba.carray(ws.stack_array(9), (3, 3))  # M₋
        root_half = np.sqrt(0.5)
        if d == 2:
            c = F[0, 0] + F[1, 1]
            s = F[1, 0] - F[0, 1]
            norm = np.sqrt(c * c + s * s)
            if not norm > 0.0:
                return SPECTRAL_NEEDS_SVD
            c *= root_half / norm
            s *= root_half / norm
            # R K with K = [[0, −1], [1, 0]]: [[−s, −c], [c, −s]] (F + cof F ∝ R).
            modes[0, 0] = -s
            modes[0, 1] = -c
            modes[0, 2] = c
            modes[0, 3] = -s
            negative[0, 0] = twist[0]
        else:
            R = numba.carray(ws.stack_array(9), (3, 3))
            if not _polar_rotation_3d(F, R):
                return SPECTRAL_NEEDS_SVD
            # K_k = [e_k]×: (R K_k)_ij = R_{i,k1} δ_{j,k2} − R_{i,k2} δ_{j,k1}, up to the sign
            # convention, which M₋ does not see.
            for k in range(3):
                k1 = (k + 1) % 3
                k2 = (k + 2) % 3
                for i in range(3):
                    modes[k, i * 3 + k] = 0.0
                    modes[k, i * 3 + k2] = -R[i, k1] * root_half
                    modes[k, i * 3 + k1] = R[i, k2] * root_half
            S = numba.carray(ws.stack_array(9), (3, 3))
            for i in range(3):
                for j in range(i, 3):
                    total = 0.0
                    for k in range(3):
                        total += 0.5 * (R[k, i] * F[k, j] + R[k, j] * F[k, i])
                    S[i, j] = total
                    S[j, i] = total
            M = numba.carray(ws.stack_array(9), (3, 3))
            squares = 0.0
            for i in range(3):
                for j in range(3):
                    squares += S[i, j] * S[i, j]
            for i in range(3):
                i1 = (i + 1) % 3
                i2 = (i + 2) % 3
                for j in range(3):
                    j1 = (j + 1) % 3
                    j2 = (j + 2) % 3
                    value = dJ * S[i, j]
                    if d2 != 0.0:
                        square = S[i, 0] * S[0, j] + S[i, 1] * S[1, j] + S[i, 2] * S[2, j]
                        adjugate = S[j1, i1] * S[j2, i2] - S[j1, i2] * S[j2, i1]
                        value -= 4.0 * d2 * (square + adjugate)
                    if i == j:
                        value += 2.0 * d1 + (4.0 * d2 * squares if d2 != 0.0 else 0.0)
                    M[i, j] = value
            m00, m11, m22, m01, m02, m12 = M[0, 0], M[1, 1], M[2, 2], M[0, 1], M[0, 2], M[1, 2]
            if negative_twists == 3:
                for i in range(3):
                    for j in range(3):
                        negative[i, j] = M[i, j]
            else:
                # The one stiffness alone on its side of zero is at least its own magnitude away
                # from the other two, so its eigenvector's error times it stays at round-off.
                if negative_twists == 1:
                    alone = min(twist[0], twist[1], twist[2])
                else:
                    alone = max(twist[0], twist[1], twist[2])
                v, length2 = null_vector(m00, m11, m22, m01, m02, m12, alone)
                # No null vector: the lone stiffness is a double one, hence round-off zero.
                weight = alone / length2 if length2 > 0.0 else 0.0
                for i in range(3):
                    for j in range(3):
                        lone = weight * v[i] * v[j]
                        negative[i, j] = lone if negative_twists == 1 else M[i, j] - lone
        m = 1 if d == 2 else 3
        weighted = numba.carray(ws.stack_array(27), (3, 9))
        for k in range(m):
            for beta in range(n):
                total = 0.0
                for l in range(m):
                    total += negative[k, l] * modes[l, beta]
                weighted[k, beta] = total
        for alpha in range(n):
            for beta in range(n):
                total = 0.0
                for k in range(m):
                    total += modes[k, alpha] * weighted[k, beta]
                C[alpha, beta] -= total
        return negative_twists

    return projection


_spectral_projection_2d = _specialised_spectral_projection(2)
_spectral_projection_3d = _specialised_spectral_projection(3)


def spectral_projection(F, d, J, d1, d2, dJ, c11, c22, cJJ, c12, c1J, c2J, C):
    """Project the exact invariant-form tangent ``C`` onto the PSD cone in place, without an SVD.

    The eigenvalues of the tangent of an isotropic energy are the σ-Hessian's, the pairs'
    stretch and their twist stiffnesses, all written here in the invariant derivatives
    (Ψ₁, Ψ₂, Ψ_J and the curvature) and σ, which comes from the eigenvalues of FᵀF in closed
    form. Where the stretch and Hessian eigenvalues are clearly positive (above
    ``_DECISION_MARGIN`` of the largest diagonal entry, beyond their estimation error), only the
    twist stiffnesses can be negative, and the projection is C minus its negative part on the
    twist modes vec(R K) (an invariant subspace; R by the polar iteration). Returns the number of
    negative twist stiffnesses clamped (0: ``C`` is already positive semidefinite and left
    alone), or :data:`SPECTRAL_NEEDS_SVD` (``C`` untouched) for a point it does not decide: a
    stretch or Hessian eigenvalue not clearly positive, σ too spread to be estimated this way, a
    twist clamp at J ≤ 0, or a polar iteration that does not converge. ``F`` is ``d×d``, ``d`` a
    compile-time literal in compiled code.
    """
    return _SPECTRAL_PROJECTION[d](F, J, d1, d2, dJ, c11, c22, cJJ, c12, c1J, c2J, C)


_SPECTRAL_PROJECTION = {2: _spectral_projection_2d, 3: _spectral_projection_3d}
dispatch_on_dimension(spectral_projection, _SPECTRAL_PROJECTION)


def _specialised_invariant_tangent(d: int):
    """:func:`invariant_tangent` compiled for one dimension: constant loop bounds unroll."""
    # This dimension's projection itself: the closure's d is a constant, so no dispatch.
    projection = _spectral_projection_3d if d == 3 else _spectral_projection_2d

    @compiled_only
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
        if project and (
            projection(F, J, d1, d2, dJ, c11, c22, cJJ, c12, c1J, c2J, C) == SPECTRAL_NEEDS_SVD
        ):
            return False, 0.0, 0
        return True, psi, 0

    return tangent


def invariant_tangent(
    F, d, I1, I2, J, model_id, extension_id, positive_only, params, project, P, C
):
    """(done, Ψ, region) with P and dP/dF written when ``done``.

    False when the SVD path is needed: the extension may be active, the model is not written in
    invariants, or the projection was asked for and :func:`spectral_projection` cannot decide
    the point. ``F`` is ``d×d``, ``d`` a compile-time literal in compiled code.
    """
    return _INVARIANT_TANGENT[d](
        F, I1, I2, J, model_id, extension_id, positive_only, params, project, P, C
    )


_INVARIANT_TANGENT = {d: _specialised_invariant_tangent(d) for d in (2, 3)}
dispatch_on_dimension(invariant_tangent, _INVARIANT_TANGENT)
