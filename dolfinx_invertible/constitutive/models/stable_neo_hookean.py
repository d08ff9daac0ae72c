"""Stable Neo-Hookean (Smith et al. 2018, without the log barrier).

    Ψ̂ = μ/2 (Σσᵢ² − d) − μ (J − 1) + (λ + μ)/2 (J − 1)².

Defined everywhere, stress free at σ = 1. Smith et al. remap the Lamé parameters so that the
model linearises to standard linear elasticity; here that remapping is built in (the volume
stiffness is λ + μ), so the same (μ, λ) as for the other models give the same small-strain
response: the Hessian at σ = 1 is 2μ I + λ 11ᵀ.
Separable form: f(x) = μ/2 (x² − 1), k₁ = −μ, k₂ = λ + μ.
"""

from __future__ import annotations

from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.constitutive.models.base import Model


@compiled_only
def constants(mu, lam):
    """(c, k₁, k₂) of the separable form."""
    return 0.0, -mu, lam + mu


@compiled_only
def tables(sigma, mu, lam, f, h):
    """F and h with their first four derivatives at each singular value."""
    for i in range(sigma.shape[0]):
        x = sigma[i]
        f[i, 0] = 0.5 * mu * (x * x - 1.0)
        f[i, 1] = mu * x
        f[i, 2] = mu
        f[i, 3] = 0.0
        f[i, 4] = 0.0
        for m in range(5):
            h[i, m] = 0.0


@compiled_only
def slopes(x, y, mu, lam):
    """Divided differences (f′(x) − f′(y))/(x − y) and (h′(x) − h′(y))/(x − y)."""
    return mu, 0.0


@compiled_only
def invariant_terms(I1, I2, J, d, mu, lam):
    """Ψ and ∂Ψ/∂I₁, ∂Ψ/∂I₂, ∂Ψ/∂J for I₁ = tr C, I₂ = tr C²: Ψ without an SVD."""
    psi = 0.5 * mu * (I1 - d) - mu * (J - 1.0) + 0.5 * (lam + mu) * (J - 1.0) ** 2
    return psi, 0.5 * mu, 0.0, (lam + mu) * (J - 1.0) - mu


@compiled_only
def invariant_curvature(I1, I2, J, d, mu, lam):
    """Second derivatives (Ψ₁₁, Ψ₂₂, Ψ_JJ, Ψ₁₂, Ψ₁J, Ψ₂J) in (I₁, I₂, J)."""
    return 0.0, 0.0, lam + mu, 0.0, 0.0, 0.0


class StableNeoHookean(Model):
    """Stable Neo-Hookean flesh model (Smith, de Goes, Kim 2018), inversion-safe by design."""

    model_id = 3
    name = "stable_neo_hookean"
