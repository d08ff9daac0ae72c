"""The batch API: a model with an optional invertible extension, evaluated on arrays of F."""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.constitutive import pointwise
from dolfinx_invertible.constitutive.extensions.base import Extension
from dolfinx_invertible.constitutive.extensions.registry import NONE_ID
from dolfinx_invertible.constitutive.models.base import Model
from dolfinx_invertible.constitutive.principal import OVERFLOW_REGION, UNDEFINED_REGION
from dolfinx_invertible.constitutive.svd_path import svd_path_address
from dolfinx_invertible.constitutive.validation import as_deformation_gradients, as_singular_values

__all__ = ["Material", "NoEnergyError"]

_MAX_REPORTED = 5


class NoEnergyError(ValueError):
    """Raised when asking a stress-only extension (IFE) for an energy."""


class Material:
    """An isotropic hyperelastic model, optionally extended past an inversion threshold.

    Parameters
    ----------
    model
        The energy Ψ̂(σ), e.g. ``NeoHookean(mu=..., lam=...)``.
    extension
        ``C1(...)``, ``C2(...)``, ``IFE(...)`` or ``None`` for the plain model.

    Parameters of the model and the extension may be scalar ``dolfinx.fem.Constant`` objects:
    every evaluation (and every assembly of the DOLFINx forms) reads their current ``value``, so
    a parameter sweep changes ``mu.value`` and never recompiles. Each material compiles only its
    own model's and extension's chain, once, into numba's disk cache. Finite F never gives NaN:
    an energy that overflows is +inf, a stress or tangent that would overflow raises a
    ``ValueError`` naming the points.

    Examples
    --------
    >>> mu, lam = lame(1e5, 0.3)
    >>> material = Material(NeoHookean(mu=mu, lam=lam), extension=C2(eps=0.9))
    >>> material.energy(np.diag([1.0, 1.0, -0.5]))  # finite through inversion
    """

    def __init__(self, model: Model, extension: Extension | None = None):
        if not isinstance(model, Model):
            raise TypeError(f"model must be a Model (e.g. NeoHookean), got {model!r}")
        if extension is not None and not isinstance(extension, Extension):
            raise TypeError(f"extension must be C1, C2, IFE or None, got {extension!r}")
        self.model = model
        self.extension = extension
        self.parameters  # noqa: B018 - checks the parameters now

    @property
    def parameters(self) -> np.ndarray:
        """Flat parameter vector in kernel order, [μ, λ, ε, k], with Constants read now."""
        extension = self.extension
        extension_parameters = (
            np.zeros(2) if extension is None else extension.parameters(self.model)
        )
        return np.concatenate([self.model.parameters, extension_parameters])

    def parameter_sources(self) -> dict:
        """{position in :attr:`parameters`: the ``dolfinx.fem.Constant`` it is read from}."""
        sources = dict(self.model.parameter_sources())
        if self.extension is not None:
            offset = len(self.model.parameters)
            for index, constant in self.extension.parameter_sources().items():
                sources[offset + index] = constant
        return sources

    def parameter_constants(self) -> list:
        """Return the distinct Constants the parameters are read from, in parameter order."""
        constants = []
        for constant in self.parameter_sources().values():
            if not any(constant is known for known in constants):
                constants.append(constant)
        return constants

    def derived_stiffness(self) -> bool:
        """Tell whether the C1 stiffness is 20·E of μ, λ read from Constants (kernels follow)."""
        return self.extension is not None and self.extension.derived_stiffness(self.model)

    @property
    def extension_id(self) -> int:
        """Registry id of the extension (0 for none)."""
        return NONE_ID if self.extension is None else self.extension.extension_id

    @property
    def positive_only(self) -> bool:
        """The energy is undefined for J ≤ 0 (a plain model that needs positive volume)."""
        return self.extension is None and self.model.requires_positive_volume

    def __repr__(self) -> str:
        return f"Material({self.model!r}, extension={self.extension!r})"

    def _loop(self, kind: str, d: int):
        return pointwise.batch(kind, self.model.model_id, self.extension_id, d)

    def _svd_path(self, d: int) -> int:
        return svd_path_address(self.model.model_id, self.extension_id, d)

    def _require_energy(self):
        if self.extension is not None and not self.extension.has_energy:
            raise NoEnergyError(
                f"{type(self.extension).__name__} is a stress-only extension: it has no energy "
                "(use C1 or C2 for an energy-consistent extension)"
            )

    def _require_defined(self, region: np.ndarray, quantity: str):
        undefined = np.flatnonzero(region == UNDEFINED_REGION)
        if len(undefined):
            shown = ", ".join(str(int(i)) for i in undefined[:_MAX_REPORTED])
            raise ValueError(
                f"{type(self.model).__name__} without an extension has no {quantity} where "
                f"J <= 0; {len(undefined)} such points, first indices {shown}. Use an extension "
                "(C1 or C2) to evaluate inverted configurations."
            )

    def _require_finite(self, region: np.ndarray, values: np.ndarray, quantity: str):
        overflow = np.flatnonzero(region == OVERFLOW_REGION)
        if len(overflow):
            shown = ", ".join(str(int(i)) for i in overflow[:_MAX_REPORTED])
            largest = float(np.abs(values[overflow]).max())
            where = f"at {len(overflow)} points, first indices {shown}"
            if largest >= 1.0:
                raise ValueError(
                    f"F too large: entries up to {largest:.3g} overflow the {quantity} (it "
                    f"exceeds the largest double) {where}"
                )
            raise ValueError(
                f"F too close to singular: det F is so small that the {quantity} overflows "
                f"(exceeds the largest double) {where}"
            )

    def energy(self, F: np.ndarray) -> np.ndarray:
        """Energy density Ψ(F) for ``F`` of shape (n, d, d) -> (n,).

        +inf where the plain model is undefined (J ≤ 0) and where the energy overflows (finite
        but enormous F); never NaN for finite input.
        """
        self._require_energy()
        batch, single = as_deformation_gradients(F)
        energy = np.empty(len(batch))
        region = np.empty(len(batch), dtype=np.int64)
        d = batch.shape[1]
        self._loop("energy", d)(
            batch, self.positive_only, self.parameters, self._svd_path(d), energy, region
        )
        return energy[0] if single else energy

    def stress(self, F: np.ndarray) -> np.ndarray:
        """First Piola–Kirchhoff stress P = ∂Ψ/∂F, shape (n, d, d)."""
        batch, single = as_deformation_gradients(F)
        stress = np.empty_like(batch)
        region = np.empty(len(batch), dtype=np.int64)
        d = batch.shape[1]
        self._loop("stress", d)(
            batch, self.positive_only, self.parameters, self._svd_path(d), stress, region
        )
        self._require_defined(region, "stress")
        self._require_finite(region, batch, "stress")
        return stress[0] if single else stress

    def tangent(self, F: np.ndarray, project: bool = True) -> np.ndarray:
        """dP/dF as (n, d², d²): row i·d + j of P_ij, column k·d + l of F_kl.

        With ``project=True`` (default) the tangent is projected onto the positive
        semidefinite cone per principal block; ``project=False`` gives the exact derivative.
        """
        batch, single = as_deformation_gradients(F)
        d = batch.shape[1]
        tangent = np.empty((len(batch), d * d, d * d))
        region = np.empty(len(batch), dtype=np.int64)
        self._loop("tangent", d)(
            batch, self.positive_only, self.parameters, bool(project), self._svd_path(d), tangent,
            region,
        )  # fmt: skip
        self._require_defined(region, "tangent")
        self._require_finite(region, batch, "tangent")
        return tangent[0] if single else tangent

    def regions(self, F: np.ndarray) -> np.ndarray:
        """Extension region per point: 0 on the model, > 0 extended, -1 undefined."""
        batch, single = as_deformation_gradients(F)
        energy = np.empty(len(batch))
        region = np.empty(len(batch), dtype=np.int64)
        d = batch.shape[1]
        self._loop("energy", d)(
            batch, self.positive_only, self.parameters, self._svd_path(d), energy, region
        )
        return region[0] if single else region

    def _sigma_derivatives(self, sigma, order: int):
        given, single = as_singular_values(sigma)
        batch = canonical_singular_values(given)
        n, d = batch.shape
        energy = np.empty(n)
        # Zeros, not empty: the orders not computed still go through the sign flips below.
        gradient = np.zeros((n, d))
        hessian = np.zeros((n, d, d))
        region = np.empty(n, dtype=np.int64)
        self._loop("sigma", d)(
            batch, self.positive_only, self.parameters, order, energy, gradient, hessian, region
        )
        # Chain rule through the sign flips of the canonicalisation.
        flips = np.where(batch * given < 0.0, -1.0, 1.0)
        if order >= 1:
            gradient *= flips
        if order >= 2:
            hessian *= flips[:, :, np.newaxis] * flips[:, np.newaxis, :]
        return energy, gradient, hessian, region, single

    def energy_sigma(self, sigma: np.ndarray) -> np.ndarray:
        """Ψ̂ext(σ) for signed singular values of shape (n, d) -> (n,)."""
        self._require_energy()
        energy, _, _, _, single = self._sigma_derivatives(sigma, 0)
        return energy[0] if single else energy

    def stress_sigma(self, sigma: np.ndarray) -> np.ndarray:
        """∇Ψ̂ext(σ), shape (n, d): the principal stresses."""
        _, gradient, _, region, single = self._sigma_derivatives(sigma, 1)
        self._require_defined(region, "stress")
        self._require_finite(region, np.atleast_2d(sigma), "stress")
        return gradient[0] if single else gradient

    def hessian_sigma(self, sigma: np.ndarray) -> np.ndarray:
        """∇²Ψ̂ext(σ), shape (n, d, d), unprojected."""
        _, _, hessian, region, single = self._sigma_derivatives(sigma, 2)
        self._require_defined(region, "tangent")
        self._require_finite(region, np.atleast_2d(sigma), "tangent")
        return hessian[0] if single else hessian


def canonical_singular_values(sigma: np.ndarray) -> np.ndarray:
    """Map signed singular values to the polar convention of the same deformation.

    Flipping the signs of two singular values gives the same F (up to rotations), so an even
    number of negative entries becomes all positive and an odd number leaves only the entry of
    smallest magnitude negative. The order of the entries is kept.
    """
    magnitude = np.abs(sigma)
    odd = (np.count_nonzero(sigma < 0.0, axis=1) % 2) == 1
    smallest = np.argmin(magnitude, axis=1)
    result = magnitude.copy()
    rows = np.flatnonzero(odd)
    result[rows, smallest[rows]] *= -1.0
    return result
