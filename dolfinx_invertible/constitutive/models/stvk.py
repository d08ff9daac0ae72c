"""St. Venant–Kirchhoff: Ψ̂ = μ E:E + λ/2 (tr E)², E = (FᵀF − I)/2, i.e.

    Ψ̂ = μ/4 Σ(σᵢ² − 1)² + λ/8 (Σ(σᵢ² − 1))².

Separable form: f(x) = μ/4 (x² − 1)², h(x) = x² − 1, c = λ/4.
"""

from __future__ import annotations

from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.constitutive.models.base import Model

#: The invariant form reads I₂ = tr C² (the fast path computes it only for such models).
USES_SECOND_INVARIANT = True


@compiled_only
def constants(mu, lam):
    """(c, k₁, k₂) of the separable form."""
    return 0.25 * lam, 0.0, 0.0


@compiled_only
def tables(sigma, mu, lam, f, h):
    """F and h with their first four derivatives at each singular value."""
    for i in range(sigma.shape[0]):
        x = sigma[i]
        f[i, 0] = 0.25 * mu * (x * x - 1.0) ** 2
        f[i, 1] = mu * (x * x - 1.0) * x
        f[i, 2] = mu * (3.0 * x * x - 1.0)
        f[i, 3] = 6.0 * mu * x
        f[i, 4] = 6.0 * mu
        h[i, 0] = x * x - 1.0
        h[i, 1] = 2.0 * x
        h[i, 2] = 2.0
        h[i, 3] = 0.0
        h[i, 4] = 0.0


@compiled_only
def slopes(x, y, mu, lam):
    """Divided differences (f′(x) − f′(y))/(x − y) and (h′(x) − h′(y))/(x − y)."""
    return mu * (x * x + x * y + y * y - 1.0), 2.0


@compiled_only
def invariant_terms(I1, I2, J, d, mu, lam):
    """Ψ and ∂Ψ/∂I₁, ∂Ψ/∂I₂, ∂Ψ/∂J for I₁ = tr C, I₂ = tr C²: Ψ without an SVD."""
    psi = 0.25 * mu * (I2 - 2.0 * I1 + d) + 0.125 * lam * (I1 - d) ** 2
    return psi, -0.5 * mu + 0.25 * lam * (I1 - d), 0.25 * mu, 0.0


@compiled_only
def invariant_curvature(I1, I2, J, d, mu, lam):
    """Second derivatives (Ψ₁₁, Ψ₂₂, Ψ_JJ, Ψ₁₂, Ψ₁J, Ψ₂J) in (I₁, I₂, J)."""
    return 0.25 * lam, 0.0, 0.0, 0.0, 0.0, 0.0


class StVK(Model):
    """St. Venant–Kirchhoff energy (quadratic in Green strain; softens under compression)."""

    model_id = 5
    name = "stvk"
