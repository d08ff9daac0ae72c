"""Compiled dispatch from a model id to that model's tables.

The kernels branch on an integer id instead of being specialised per model: one compiled
function (cached on disk) serves every model, and the branch is perfectly predictable inside a
batch. Adding a model is a new module with ``tables``/``slopes`` plus one branch here.
"""

from __future__ import annotations

import numba

from dolfinx_invertible import workspace as ws
from dolfinx_invertible.models import (
    arap,
    corotated,
    fixed_corotated,
    neo_hookean,
    stable_neo_hookean,
    stvk,
)
from dolfinx_invertible.models.separable import separable_derivatives, separable_gradient_slope

__all__ = [
    "model_derivatives",
    "model_derivatives_into",
    "model_gradient_slope",
    "model_invariant_terms",
    "model_invariant_curvature",
]


@numba.njit(cache=True)
def _tables(model_id, sigma, mu, lam, f, h):
    if model_id == neo_hookean.MODEL_ID:
        return neo_hookean.tables(sigma, mu, lam, f, h)
    if model_id == corotated.MODEL_ID:
        return corotated.tables(sigma, mu, lam, f, h)
    if model_id == fixed_corotated.MODEL_ID:
        return fixed_corotated.tables(sigma, mu, lam, f, h)
    if model_id == stable_neo_hookean.MODEL_ID:
        return stable_neo_hookean.tables(sigma, mu, lam, f, h)
    if model_id == arap.MODEL_ID:
        return arap.tables(sigma, mu, lam, f, h)
    return stvk.tables(sigma, mu, lam, f, h)


@numba.njit(cache=True)
def _constants(model_id, mu, lam):
    if model_id == neo_hookean.MODEL_ID:
        return neo_hookean.constants(mu, lam)
    if model_id == corotated.MODEL_ID:
        return corotated.constants(mu, lam)
    if model_id == fixed_corotated.MODEL_ID:
        return fixed_corotated.constants(mu, lam)
    if model_id == stable_neo_hookean.MODEL_ID:
        return stable_neo_hookean.constants(mu, lam)
    if model_id == arap.MODEL_ID:
        return arap.constants(mu, lam)
    return stvk.constants(mu, lam)


@numba.njit(cache=True)
def _slopes(model_id, x, y, mu, lam):
    if model_id == neo_hookean.MODEL_ID:
        return neo_hookean.slopes(x, y, mu, lam)
    if model_id == corotated.MODEL_ID:
        return corotated.slopes(x, y, mu, lam)
    if model_id == fixed_corotated.MODEL_ID:
        return fixed_corotated.slopes(x, y, mu, lam)
    if model_id == stable_neo_hookean.MODEL_ID:
        return stable_neo_hookean.slopes(x, y, mu, lam)
    if model_id == arap.MODEL_ID:
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
    if model_id == neo_hookean.MODEL_ID:
        psi, d1, d2, dJ = neo_hookean.invariant_terms(I1, I2, J, d, mu, lam)
        return True, psi, d1, d2, dJ
    if model_id == stable_neo_hookean.MODEL_ID:
        psi, d1, d2, dJ = stable_neo_hookean.invariant_terms(I1, I2, J, d, mu, lam)
        return True, psi, d1, d2, dJ
    if model_id == stvk.MODEL_ID:
        psi, d1, d2, dJ = stvk.invariant_terms(I1, I2, J, d, mu, lam)
        return True, psi, d1, d2, dJ
    return False, 0.0, 0.0, 0.0, 0.0


@numba.njit(cache=True)
def model_invariant_curvature(model_id, I1, I2, J, d, params):
    """(Ψ₁₁, Ψ₂₂, Ψ_JJ, Ψ₁₂, Ψ₁J, Ψ₂J) for the models :func:`model_invariant_terms` serves."""
    mu = params[0]
    lam = params[1]
    if model_id == neo_hookean.MODEL_ID:
        return neo_hookean.invariant_curvature(I1, I2, J, d, mu, lam)
    if model_id == stable_neo_hookean.MODEL_ID:
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
