"""As-rigid-as-possible: Ψ̂ = μ Σ(σᵢ − 1)².

No volume term: λ is 0 by definition. Separable form: f(x) = μ (x − 1)².
"""

from __future__ import annotations

from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.constitutive.models.base import Model

# f = μ (x − 1)² and h = 0, as in fixed corotated: the same tables and divided differences.
from dolfinx_invertible.constitutive.models.fixed_corotated import slopes, tables  # noqa: F401


@compiled_only
def constants(mu, lam):
    """(c, k₁, k₂) of the separable form."""
    return 0.0, 0.0, 0.0


class ARAP(Model):
    """As-rigid-as-possible energy; only a shear modulus μ (λ = 0)."""

    model_id = 4
    name = "arap"

    def __init__(self, mu: float):
        super().__init__(mu, 0.0)

    def __repr__(self) -> str:
        return f"ARAP(mu={self._mu!r})"
