"""The registry of models, and the compiled dispatch from a model id to that model's tables.

:data:`MODELS` lists every model once; a model's id is its position there. The kernels branch
on that integer id instead of being specialised per model: one compiled function (cached on
disk) serves every model, and the branch is perfectly predictable inside a batch. Adding a model
is a new module with ``constants``, ``tables`` and ``slopes`` (and, for a model written in
invariants, ``invariant_terms`` and ``invariant_curvature``), its class in :data:`MODELS` and
one branch per dispatcher here; the tests check every registered model is dispatched to its own
module.
"""

from __future__ import annotations

import numba

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.models import (
    arap,
    corotated,
    fixed_corotated,
    neo_hookean,
    stable_neo_hookean,
    stvk,
)
from dolfinx_invertible.constitutive.models.arap import ARAP
from dolfinx_invertible.constitutive.models.base import Model
from dolfinx_invertible.constitutive.models.corotated import Corotated
from dolfinx_invertible.constitutive.models.fixed_corotated import FixedCorotated
from dolfinx_invertible.constitutive.models.neo_hookean import NeoHookean
from dolfinx_invertible.constitutive.models.separable import (
    separable_derivatives,
    separable_gradient_slope,
)
from dolfinx_invertible.constitutive.models.stable_neo_hookean import StableNeoHookean
from dolfinx_invertible.constitutive.models.stvk import StVK

__all__ = [
    "MODELS",
    "model_derivatives",
    "model_derivatives_into",
    "model_gradient_slope",
    "model_invariant_terms",
    "model_invariant_curvature",
]


#: Every model, in id order: a model's id is its position here.
MODELS: tuple[type[Model], ...] = (
    NeoHookean,
    Corotated,
    FixedCorotated,
    StableNeoHookean,
    ARAP,
    StVK,
)
for _model_id, _model in enumerate(MODELS):
    _model.model_id = _model_id

# The ids as module constants, which the compiled dispatchers read as compile-time constants.
_NEO_HOOKEAN = NeoHookean.model_id
_COROTATED = Corotated.model_id
_FIXED_COROTATED = FixedCorotated.model_id
_STABLE_NEO_HOOKEAN = StableNeoHookean.model_id
_ARAP = ARAP.model_id
_STVK = StVK.model_id


@numba.njit(cache=True)
def _tables(model_id, sigma, mu, lam, f, h):
    if model_id == _NEO_HOOKEAN:
        return neo_hookean.tables(sigma, mu, lam, f, h)
    if model_id == _COROTATED:
        return corotated.tables(sigma, mu, lam, f, h)
    if model_id == _FIXED_COROTATED:
        return fixed_corotated.tables(sigma, mu, lam, f, h)
    if model_id == _STABLE_NEO_HOOKEAN:
        return stable_neo_hookean.tables(sigma, mu, lam, f, h)
    if model_id == _ARAP:
        return arap.tables(sigma, mu, lam, f, h)
    return stvk.tables(sigma, mu, lam, f, h)


@numba.njit(cache=True)
def _constants(model_id, mu, lam):
    if model_id == _NEO_HOOKEAN:
        return neo_hookean.constants(mu, lam)
    if model_id == _COROTATED:
        return corotated.constants(mu, lam)
    if model_id == _FIXED_COROTATED:
        return fixed_corotated.constants(mu, lam)
    if model_id == _STABLE_NEO_HOOKEAN:
        return stable_neo_hookean.constants(mu, lam)
    if model_id == _ARAP:
        return arap.constants(mu, lam)
    return stvk.constants(mu, lam)


@numba.njit(cache=True)
def _slopes(model_id, x, y, mu, lam):
    if model_id == _NEO_HOOKEAN:
        return neo_hookean.slopes(x, y, mu, lam)
    if model_id == _COROTATED:
        return corotated.slopes(x, y, mu, lam)
    if model_id == _FIXED_COROTATED:
        return fixed_corotated.slopes(x, y, mu, lam)
    if model_id == _STABLE_NEO_HOOKEAN:
        return stable_neo_hookean.slopes(x, y, mu, lam)
    if model_id == _ARAP:
        return arap.slopes(x, y, mu, lam)
    return stvk.slopes(x, y, mu, lam)


@numba.njit(cache=True)
def model_invariant_terms(model_id, I1, I2, J, d, params):
    """(available, Ψ, ∂Ψ/∂I₁, ∂Ψ/∂I₂, ∂Ψ/∂J) for models written in I₁ = tr C, I₂ = tr C², J.

    Such models need no SVD where their extension is inactive; ``available`` is False for the
    others (their energy needs the singular values themselves).
    """
    mu = params[0]
    lam = params[1]
    if model_id == _NEO_HOOKEAN:
        psi, d1, d2, dJ = neo_hookean.invariant_terms(I1, I2, J, d, mu, lam)
        return True, psi, d1, d2, dJ
    if model_id == _STABLE_NEO_HOOKEAN:
        psi, d1, d2, dJ = stable_neo_hookean.invariant_terms(I1, I2, J, d, mu, lam)
        return True, psi, d1, d2, dJ
    if model_id == _STVK:
        psi, d1, d2, dJ = stvk.invariant_terms(I1, I2, J, d, mu, lam)
        return True, psi, d1, d2, dJ
    return False, 0.0, 0.0, 0.0, 0.0


@numba.njit(cache=True)
def model_invariant_curvature(model_id, I1, I2, J, d, params):
    """(Ψ₁₁, Ψ₂₂, Ψ_JJ, Ψ₁₂, Ψ₁J, Ψ₂J) for the models :func:`model_invariant_terms` serves."""
    mu = params[0]
    lam = params[1]
    if model_id == _NEO_HOOKEAN:
        return neo_hookean.invariant_curvature(I1, I2, J, d, mu, lam)
    if model_id == _STABLE_NEO_HOOKEAN:
        return stable_neo_hookean.invariant_curvature(I1, I2, J, d, mu, lam)
    return stvk.invariant_curvature(I1, I2, J, d, mu, lam)


@numba.njit(cache=True)
def model_derivatives(model_id, sigma, params, order, g, H, T, Q, f, h):
    """Ψ̂(σ) of model ``model_id``; derivative tensors up to ``order`` go to g, H, T, Q.

    ``params`` starts with [μ, λ]; ``f`` and ``h`` are ``(d, 5)`` scratch tables, left holding
    the model's tables at ``sigma`` for :func:`model_gradient_slope`.
    """
    _tables(model_id, sigma, params[0], params[1], f, h)
    c, k1, k2 = _constants(model_id, params[0], params[1])
    return separable_derivatives(sigma, order, f, h, c, k1, k2, g, H, T, Q)


@numba.njit(cache=True)
def model_gradient_slope(model_id, sigma, params, i, j, h):
    """(gᵢ − gⱼ)/(σᵢ − σⱼ) in closed form, exact also for σᵢ = σⱼ.

    ``h`` must hold the tables that :func:`model_derivatives` left for the same ``sigma``.
    """
    mu = params[0]
    lam = params[1]
    c, k1, k2 = _constants(model_id, mu, lam)
    f_slope, h_slope = _slopes(model_id, sigma[i], sigma[j], mu, lam)
    return separable_gradient_slope(sigma, i, j, f_slope, h_slope, c, k1, k2, h)


@numba.njit(cache=True)
def model_derivatives_into(model_id, sigma, params, order, work, gradient_slot, hessian_slot):
    """:func:`model_derivatives` with the gradient and Hessian written to workspace slots."""
    d = sigma.shape[0]
    return model_derivatives(
        model_id,
        sigma,
        params,
        order,
        ws.vector(work, gradient_slot, d),
        ws.matrix(work, hessian_slot, d),
        ws.tensor3(work, ws.MODEL_T, d),
        ws.tensor4(work, ws.MODEL_Q, d),
        ws.table(work, ws.F_TABLE, d),
        ws.table(work, ws.H_TABLE, d),
    )
