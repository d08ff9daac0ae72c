"""As-rigid-as-possible: Ψ̂ = μ Σ(σᵢ − 1)².

No volume term: λ is 0 by definition. Separable form: f(x) = μ (x − 1)².
"""

from __future__ import annotations

import numba

from dolfinx_invertible.models.base import Model

MODEL_ID = 4


@numba.njit(cache=True)
def constants(mu, lam):
    """(c, k₁, k₂) of the separable form."""
    return 0.0, 0.0, 0.0


@numba.njit(cache=True)
def tables(sigma, mu, lam, f, h):
    """f and h with their first four derivatives at each singular value."""
    for i in range(sigma.shape[0]):
        x = sigma[i]
        f[i, 0] = mu * (x - 1.0) ** 2
        f[i, 1] = 2.0 * mu * (x - 1.0)
        f[i, 2] = 2.0 * mu
        f[i, 3] = 0.0
        f[i, 4] = 0.0
        for m in range(5):
            h[i, m] = 0.0


@numba.njit(cache=True)
def slopes(x, y, mu, lam):
    """Divided differences (f′(x) − f′(y))/(x − y) and (h′(x) − h′(y))/(x − y)."""
    return 2.0 * mu, 0.0


class ARAP(Model):
    """As-rigid-as-possible energy; only a shear modulus μ (λ = 0)."""

    model_id = MODEL_ID
    name = "arap"

    def __init__(self, mu: float):
        super().__init__(mu, 0.0)

    def __repr__(self) -> str:
        return f"ARAP(mu={self.mu!r})"
