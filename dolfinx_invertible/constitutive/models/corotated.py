"""Corotated: Ψ̂ = μ Σ(σᵢ − 1)² + λ/2 (Σ(σᵢ − 1))².

Its primary contour Σ(σᵢ − 1) = 0 crosses into the inverted region (paper §3.3).
Separable form: f(x) = μ (x − 1)², h(x) = x − 1, c = λ.
"""

from __future__ import annotations

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
        f[i, 0] = mu * (x - 1.0) ** 2
        f[i, 1] = 2.0 * mu * (x - 1.0)
        f[i, 2] = 2.0 * mu
        f[i, 3] = 0.0
        f[i, 4] = 0.0
        h[i, 0] = x - 1.0
        h[i, 1] = 1.0
        h[i, 2] = 0.0
        h[i, 3] = 0.0
        h[i, 4] = 0.0


@compiled_only
def slopes(x, y, mu, lam):
    """Divided differences (f′(x) − f′(y))/(x − y) and (h′(x) − h′(y))/(x − y)."""
    return 2.0 * mu, 0.0


class Corotated(Model):
    """Corotated linear elasticity made hyperelastic (Chao et al. 2010, McAdams et al. 2011)."""

    model_id = 1
    name = "corotated"
