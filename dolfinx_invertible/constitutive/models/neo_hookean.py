"""Neo-Hookean: Ψ̂ = μ/2 (Σσᵢ² − d) − μ ln J + λ/2 (ln J)², defined for J > 0 only.

Separable form: f(x) = μ/2 (x² − 1) − μ ln x, h(x) = ln x, c = λ.
"""

from __future__ import annotations

import math

from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.constitutive.models.base import Model


@compiled_only
def constants(mu, lam):
    """(c, k₁, k₂) of the separable form."""
    return lam, 0.0, 0.0


@compiled_only
def tables(sigma, mu, lam, f, h):
    """F and h with their first four derivatives at each singular value."""
    for i in range(sigma.shape[0]):
        x = sigma[i]
        inverse = 1.0 / x
        inverse2 = inverse * inverse
        f[i, 0] = 0.5 * mu * (x * x - 1.0) - mu * math.log(x)
        f[i, 1] = mu * (x - inverse)
        f[i, 2] = mu * (1.0 + inverse2)
        f[i, 3] = -2.0 * mu * inverse2 * inverse
        f[i, 4] = 6.0 * mu * inverse2 * inverse2
        h[i, 0] = math.log(x)
        h[i, 1] = inverse
        h[i, 2] = -inverse2
        h[i, 3] = 2.0 * inverse2 * inverse
        h[i, 4] = -6.0 * inverse2 * inverse2


@compiled_only
def slopes(x, y, mu, lam):
    """Divided differences (f′(x) − f′(y))/(x − y) and (h′(x) − h′(y))/(x − y)."""
    inverse_product = 1.0 / (x * y)
    return mu * (1.0 + inverse_product), -inverse_product


@compiled_only
def invariant_terms(I1, I2, J, d, mu, lam):
    """Ψ and ∂Ψ/∂I₁, ∂Ψ/∂I₂, ∂Ψ/∂J for I₁ = tr C, I₂ = tr C² (J > 0): Ψ without an SVD."""
    log_J = math.log(J)
    psi = 0.5 * mu * (I1 - d) - mu * log_J + 0.5 * lam * log_J * log_J
    return psi, 0.5 * mu, 0.0, (lam * log_J - mu) / J


@compiled_only
def invariant_curvature(I1, I2, J, d, mu, lam):
    """Second derivatives (Ψ₁₁, Ψ₂₂, Ψ_JJ, Ψ₁₂, Ψ₁J, Ψ₂J) in (I₁, I₂, J) (J > 0)."""
    return 0.0, 0.0, (lam * (1.0 - math.log(J)) + mu) / (J * J), 0.0, 0.0, 0.0


class NeoHookean(Model):
    """Compressible Neo-Hookean energy (the paper's example model); needs J > 0 unextended."""

    model_id = 0
    name = "neo_hookean"
    requires_positive_volume = True
