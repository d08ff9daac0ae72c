"""The SVD-free fast path: energy and stress from invariants where no extension can be active.

Where an extension provably cannot be active (C2 and IFE: J ≥ ε; C1: J > 0 and
Σ 1/σᵢ² ≤ 1/ε², which implies every σᵢ ≥ ε; no extension: always), a model written in the
invariants I₁ = tr C, I₂ = tr C² and J of C = FᵀF gives Ψ and

    P = 2 Ψ_{I₁} F + 4 Ψ_{I₂} F C + Ψ_J cof F

directly from F. Σ 1/σᵢ² = tr C⁻¹ is itself an invariant: ½(I₁² − I₂)/J² in 3D, I₁/J² in 2D.
(The paper prints the C1 test as "I₂/J² ≥ ε"; the sound test is the one above.)
"""

from __future__ import annotations

import numba
import numpy as np

from dolfinx_invertible.extensions.base import C1_ID, C2_ID, IFE_ID
from dolfinx_invertible.models.registry import model_invariant_terms

__all__ = ["invariant_energy", "invariant_stress", "extension_inactive"]


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
    """True where the (extended) energy equals the model itself, decided without an SVD.

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
