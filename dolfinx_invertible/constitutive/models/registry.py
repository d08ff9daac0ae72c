"""The registry of models, and the compiled dispatch from a model id to that model's tables.

:data:`MODELS` lists every model once, in the order of the ``model_id`` each model class
declares; the registry checks at import that the ids are unique and run 0, 1, ... without a gap.
The kernels take that integer id as a compile-time literal, so each compiled chain (cached on
disk) holds the one model it serves: a scene compiles its own model, not all of them. Adding a
model is a new module with ``constants``, ``tables`` and ``slopes`` (and, for a model written in
invariants, ``invariant_terms`` and ``invariant_curvature``; ``USES_SECOND_INVARIANT = True`` if
those read I₂) and its class, with the next free ``model_id``, in :data:`MODELS`: the
dispatchers here look the module up. The tests check every registered model is dispatched to its
own module.
"""

from __future__ import annotations

import sys

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.compiled import compiled_only, compiled_overload
from dolfinx_invertible.constitutive.literal import force_literal, literal_id
from dolfinx_invertible.constitutive.models.arap import ARAP
from dolfinx_invertible.constitutive.models.base import Model
from dolfinx_invertible.constitutive.models.corotated import Corotated
from dolfinx_invertible.constitutive.models.fixed_corotated import FixedCorotated
from dolfinx_invertible.constitutive.models.neo_hookean import NeoHookean
from dolfinx_invertible.constitutive.models.separable import (
    separable_anchor_derivatives,
    separable_derivatives,
    separable_gradient_slope,
)
from dolfinx_invertible.constitutive.models.stable_neo_hookean import StableNeoHookean
from dolfinx_invertible.constitutive.models.stvk import StVK
from dolfinx_invertible.constitutive.registry_ids import ordered_by_id

__all__ = [
    "MODELS",
    "model_anchor_derivatives",
    "model_derivatives",
    "model_derivatives_into",
    "model_gradient_slope",
    "model_invariant_terms",
    "model_invariant_curvature",
    "model_uses_second_invariant",
]


#: Every model, in the order of the ``model_id`` each declares: ``MODELS[model.model_id]``.
MODELS: tuple[type[Model], ...] = ordered_by_id(
    (NeoHookean, Corotated, FixedCorotated, StableNeoHookean, ARAP, StVK), "model_id", first=0
)

_MODULES = tuple(sys.modules[model.__module__] for model in MODELS)


# Each dispatcher below is a Python function (callable as such, from Python) with a compiled
# overload that resolves the model at compile time: the kernels pass the model id as a literal
# (see :mod:`~dolfinx_invertible.constitutive.literal`), so a compiled chain contains the model it
# serves and no other. A caller that passes a run-time id is made to pass a literal instead.
def _tables(model_id, sigma, mu, lam, f, h):
    return _MODULES[model_id].tables(sigma, mu, lam, f, h)


@compiled_overload(_tables, prefer_literal=True)
def _tables_compiled(model_id, sigma, mu, lam, f, h):
    value = literal_id(model_id)
    if value is None:
        return force_literal(_tables)
    tables = _MODULES[value].tables

    def implementation(model_id, sigma, mu, lam, f, h):
        return tables(sigma, mu, lam, f, h)

    return implementation


def _constants(model_id, mu, lam):
    return _MODULES[model_id].constants(mu, lam)


@compiled_overload(_constants, prefer_literal=True)
def _constants_compiled(model_id, mu, lam):
    value = literal_id(model_id)
    if value is None:
        return force_literal(_constants)
    constants = _MODULES[value].constants

    def implementation(model_id, mu, lam):
        return constants(mu, lam)

    return implementation


def _slopes(model_id, x, y, mu, lam):
    return _MODULES[model_id].slopes(x, y, mu, lam)


@compiled_overload(_slopes, prefer_literal=True)
def _slopes_compiled(model_id, x, y, mu, lam):
    value = literal_id(model_id)
    if value is None:
        return force_literal(_slopes)
    slopes = _MODULES[value].slopes

    def implementation(model_id, x, y, mu, lam):
        return slopes(x, y, mu, lam)

    return implementation


def model_invariant_terms(model_id, I1, I2, J, d, params):
    """(available, Ψ, ∂Ψ/∂I₁, ∂Ψ/∂I₂, ∂Ψ/∂J) for models written in I₁ = tr C, I₂ = tr C², J.

    Such models need no SVD where their extension is inactive; ``available`` is False for the
    others (their energy needs the singular values themselves).
    """
    module = _MODULES[model_id]
    if not hasattr(module, "invariant_terms"):
        return False, 0.0, 0.0, 0.0, 0.0
    return (True, *module.invariant_terms(I1, I2, J, d, params[0], params[1]))


@compiled_overload(model_invariant_terms, prefer_literal=True)
def _model_invariant_terms_compiled(model_id, I1, I2, J, d, params):
    value = literal_id(model_id)
    if value is None:
        return force_literal(model_invariant_terms)
    module = _MODULES[value]
    if not hasattr(module, "invariant_terms"):

        def unavailable(model_id, I1, I2, J, d, params):
            return False, 0.0, 0.0, 0.0, 0.0

        return unavailable
    terms = module.invariant_terms

    def implementation(model_id, I1, I2, J, d, params):
        psi, d1, d2, dJ = terms(I1, I2, J, d, params[0], params[1])
        return True, psi, d1, d2, dJ

    return implementation


def model_invariant_curvature(model_id, I1, I2, J, d, params):
    """(Ψ₁₁, Ψ₂₂, Ψ_JJ, Ψ₁₂, Ψ₁J, Ψ₂J) for the models :func:`model_invariant_terms` serves."""
    module = _MODULES[model_id]
    if not hasattr(module, "invariant_curvature"):
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    return module.invariant_curvature(I1, I2, J, d, params[0], params[1])


@compiled_overload(model_invariant_curvature, prefer_literal=True)
def _model_invariant_curvature_compiled(model_id, I1, I2, J, d, params):
    value = literal_id(model_id)
    if value is None:
        return force_literal(model_invariant_curvature)
    module = _MODULES[value]
    if not hasattr(module, "invariant_curvature"):

        def unavailable(model_id, I1, I2, J, d, params):
            return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0

        return unavailable
    curvature = module.invariant_curvature

    def implementation(model_id, I1, I2, J, d, params):
        return curvature(I1, I2, J, d, params[0], params[1])

    return implementation


def model_uses_second_invariant(model_id):
    """Tell whether the model's invariant form reads I₂ = tr C² (``USES_SECOND_INVARIANT``).

    A compile-time constant in compiled code.
    """
    return bool(getattr(_MODULES[model_id], "USES_SECOND_INVARIANT", False))


@compiled_overload(model_uses_second_invariant, prefer_literal=True)
def _model_uses_second_invariant_compiled(model_id):
    value = literal_id(model_id)
    if value is None:
        return force_literal(model_uses_second_invariant)
    flag = model_uses_second_invariant(value)

    def implementation(model_id):
        return flag

    return implementation


@compiled_only
def model_derivatives(model_id, sigma, d, params, order, g, H, T, Q, f, h):
    """Ψ̂(σ) of model ``model_id``; derivative tensors up to ``order`` go to g, H, T, Q.

    ``d`` is the length of ``sigma``, a compile-time literal like the id. ``params`` starts
    with [μ, λ]; ``f`` and ``h`` are ``(d, 5)`` scratch tables, left holding the model's tables
    at ``sigma`` for :func:`model_gradient_slope`.
    """
    _tables(model_id, sigma, params[0], params[1], f, h)
    c, k1, k2 = _constants(model_id, params[0], params[1])
    return separable_derivatives(sigma, d, order, f, h, c, k1, k2, g, H, T, Q)


@compiled_only
def model_gradient_slope(model_id, sigma, params, i, j, h):
    """(gᵢ − gⱼ)/(σᵢ − σⱼ) in closed form, exact also for σᵢ = σⱼ.

    ``h`` must hold the tables that :func:`model_derivatives` left for the same ``sigma``.
    """
    mu = params[0]
    lam = params[1]
    c, k1, k2 = _constants(model_id, mu, lam)
    f_slope, h_slope = _slopes(model_id, sigma[i], sigma[j], mu, lam)
    return separable_gradient_slope(sigma, i, j, f_slope, h_slope, c, k1, k2, h)


@compiled_only
def model_derivatives_into(model_id, sigma, d, params, order, work, gradient_slot, hessian_slot):
    """:func:`model_derivatives` with the gradient and Hessian written to workspace slots."""
    return model_derivatives(
        model_id,
        sigma,
        d,
        params,
        order,
        ws.vector(work, gradient_slot, d),
        ws.matrix(work, hessian_slot, d),
        ws.tensor3(work, ws.MODEL_T, d),
        ws.tensor4(work, ws.MODEL_Q, d),
        ws.table(work, ws.F_TABLE, d),
        ws.table(work, ws.H_TABLE, d),
    )


@compiled_only
def model_anchor_derivatives(model_id, q, d, params, order, work):
    """Ψ̂ at ``q`` (the workspace's Q_POINT) with its derivatives contracted with A_OFFSET.

    See :func:`~dolfinx_invertible.constitutive.models.separable.separable_anchor_derivatives`
    for what goes where; the tables at q are left in F_TABLE and H_TABLE.
    """
    mu = params[0]
    lam = params[1]
    _tables(model_id, q, mu, lam, ws.table(work, ws.F_TABLE, d), ws.table(work, ws.H_TABLE, d))
    c, k1, k2 = _constants(model_id, mu, lam)
    return separable_anchor_derivatives(q, d, order, c, k1, k2, work)
