"""Fixed corotated (paper §3.4): Ψ̂ = μ Σ(σᵢ − 1)² + λ/2 (J − 1)².

The volume term moves the primary contour to J = 1, away from the inverted region.
Separable form: f(x) = μ (x − 1)², k₂ = λ.
"""

from __future__ import annotations

from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.constitutive.models.base import Model


@compiled_only
def constants(mu, lam):
    """(c, k₁, k₂) of the separable form."""
    return 0.0, 0.0, lam


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
        for m in range(5):
            h[i, m] = 0.0


@compiled_only
def slopes(x, y, mu, lam):
    """Divided differences (f′(x) − f′(y))/(x − y) and (h′(x) − h′(y))/(x − y)."""
    return 2.0 * mu, 0.0


class FixedCorotated(Model):
    """Corotated model with the volume term λ/2 (J − 1)² (Stomakhin et al. 2012, §3.4)."""

    model_id = 2
    name = "fixed_corotated"
