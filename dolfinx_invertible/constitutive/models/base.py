"""Common behaviour of the isotropic energy models: parameters, validation, identity."""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.constitutive.validation import check_positive

__all__ = ["Model"]


class Model:
    """An isotropic hyperelastic energy Ψ̂(σ) with Lamé parameters μ and λ.

    Subclasses set ``name`` and ``requires_positive_volume`` (the energy is only defined for
    J > 0); :mod:`~dolfinx_invertible.constitutive.models.registry` gives each its ``model_id``,
    the branch the compiled kernels take.
    """

    model_id: int = -1
    name: str = "model"
    requires_positive_volume: bool = False

    def __init__(self, mu: float, lam: float):
        self.mu = check_positive("mu", mu)
        lam = float(lam)
        # λ > −2μ/3 keeps the bulk modulus positive (ν > −1); λ may be 0 or negative above it.
        if not (np.isfinite(lam) and 3.0 * lam + 2.0 * self.mu > 0.0):
            raise ValueError(
                f"lam must be finite with 3 lam + 2 mu > 0 (Poisson ratio > -1), got lam={lam!r}"
            )
        self.lam = lam

    @property
    def youngs_modulus(self) -> float:
        """E = μ(3λ + 2μ)/(λ + μ), the Young's modulus of the linearised model."""
        return self.mu * (3.0 * self.lam + 2.0 * self.mu) / (self.lam + self.mu)

    @property
    def parameters(self) -> np.ndarray:
        """Parameters in the order the kernels read them: [μ, λ]."""
        return np.array([self.mu, self.lam])

    def __repr__(self) -> str:
        return f"{type(self).__name__}(mu={self.mu!r}, lam={self.lam!r})"

    def __eq__(self, other) -> bool:
        return type(other) is type(self) and np.array_equal(other.parameters, self.parameters)

    def __hash__(self) -> int:
        return hash((type(self).__name__, self.mu, self.lam))
