"""Common behaviour of the isotropic energy models: parameters, validation, identity."""

from __future__ import annotations

import math

import numpy as np

from dolfinx_invertible.constitutive.validation import Parameter, check_positive

__all__ = ["Model"]


def _check_lam(name: str, lam: float) -> float:
    # λ > −2μ/3 keeps the bulk modulus positive (ν > −1); λ may be 0 or negative above it. The
    # bound on μ is checked with both values by Model.parameters.
    if not math.isfinite(lam):
        raise ValueError(f"{name} must be a finite number, got {lam!r}")
    return lam


class Model:
    """An isotropic hyperelastic energy Ψ̂(σ) with Lamé parameters μ and λ.

    Subclasses set ``model_id`` (the branch the compiled kernels take; checked by
    :mod:`~dolfinx_invertible.constitutive.models.registry`), ``name`` and
    ``requires_positive_volume`` (the energy is only defined for J > 0).

    ``mu`` and ``lam`` are real numbers or scalar ``dolfinx.fem.Constant`` objects; a Constant is
    read whenever the parameters are needed (each batch evaluation, each assembly), so setting
    its ``value`` changes the material without recompiling anything.
    """

    model_id: int = -1
    name: str = "model"
    requires_positive_volume: bool = False

    def __init__(self, mu, lam):
        self._mu = Parameter("mu", mu, check_positive)
        self._lam = Parameter("lam", lam, _check_lam)
        self.parameters  # noqa: B018 - checks the pair now

    @property
    def mu(self) -> float:
        """Current μ."""
        return self._mu.value

    @property
    def lam(self) -> float:
        """Current λ."""
        return self._lam.value

    @property
    def youngs_modulus(self) -> float:
        """E = μ(3λ + 2μ)/(λ + μ), the Young's modulus of the linearised model."""
        mu, lam = self.parameters
        return mu * (3.0 * lam + 2.0 * mu) / (lam + mu)

    @property
    def parameters(self) -> np.ndarray:
        """Current parameters in the order the kernels read them: [μ, λ]."""
        mu = self._mu.value
        lam = self._lam.value
        if not 3.0 * lam + 2.0 * mu > 0.0:
            raise ValueError(
                f"lam must be finite with 3 lam + 2 mu > 0 (Poisson ratio > -1), got lam={lam!r}"
            )
        return np.array([mu, lam])

    def parameter_sources(self) -> dict:
        """{position in :attr:`parameters`: the Constant it is read from}."""
        return {
            index: parameter.constant
            for index, parameter in enumerate((self._mu, self._lam))
            if parameter.constant is not None
        }

    def __repr__(self) -> str:
        return f"{type(self).__name__}(mu={self._mu!r}, lam={self._lam!r})"

    def __eq__(self, other) -> bool:
        return type(other) is type(self) and np.array_equal(other.parameters, self.parameters)

    def __hash__(self) -> int:
        return hash(type(self).__name__)
