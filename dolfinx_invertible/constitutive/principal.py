"""Energy, gradient and Hessian in principal-stretch (signed singular value) space.

One dispatch on the extension id serves every kernel: the batch API, the σ-space API and the
DOLFINx cell kernels all come through :func:`principal_derivatives`. The dispatch is resolved at
compile time (the ids are literals, :mod:`~dolfinx_invertible.constitutive.literal`): each
registered extension's module provides ``derivatives``.
"""

from __future__ import annotations

import sys

import numpy as np

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.compiled import compiled_only, compiled_overload
from dolfinx_invertible.constitutive.extensions.registry import EXTENSIONS
from dolfinx_invertible.constitutive.literal import force_literal, literal_id
from dolfinx_invertible.constitutive.models.registry import (
    model_derivatives_into,
    model_gradient_slope,
)

__all__ = [
    "OVERFLOW_REGION",
    "UNDEFINED_REGION",
    "principal_derivatives",
    "gradient_slope",
    "quotient_slope",
    "rotation_slope",
    "sum_slope",
]

# Region code of a point where the unextended energy is not defined (J ≤ 0 for Neo-Hookean).
UNDEFINED_REGION = -1
# Region code of a point whose stress or tangent overflows the largest double (finite but huge
# F): its energy is +inf, and the kernels write zero stress and tangent for it.
OVERFLOW_REGION = -2
# Below this relative gap two singular values count as equal for the quotient aᵢⱼ.
_EQUAL_GAP = 1e-6
# |σᵢ + σⱼ| is bounded below by this (relative to max(1, |σ|)), keeping its sign: the energy has
# a kink there (paper §3.1), so bᵢⱼ is large but finite.
_KINK_GAP = 1e-8


def _plain_derivatives(model_id, positive_only, sigma, d, params, order, work):
    if positive_only:
        J = 1.0
        for i in range(d):
            J *= sigma[i]
        if not J > 0.0:
            ws.vector(work, ws.G, d)[:] = 0.0
            ws.matrix(work, ws.H, d)[:] = 0.0
            return np.inf, UNDEFINED_REGION
    return model_derivatives_into(model_id, sigma, d, params, order, work, ws.G, ws.H), 0


_plain_derivatives_compiled = compiled_only(_plain_derivatives)


def _extended_derivatives(extension_id, model_id, positive_only, sigma, d, params, order, work):
    extension = EXTENSIONS[extension_id]
    if extension is None:
        return _plain_derivatives_compiled(model_id, positive_only, sigma, d, params, order, work)
    module = sys.modules[extension.__module__]
    return module.derivatives(model_id, sigma, d, params, order, work)


@compiled_overload(_extended_derivatives, prefer_literal=True)
def _extended_derivatives_compiled(
    extension_id, model_id, positive_only, sigma, d, params, order, work
):
    # The extension resolved while typing: only the one in use is compiled.
    value = literal_id(extension_id)
    if value is None:
        return force_literal(_extended_derivatives)
    extension = EXTENSIONS[value]
    if extension is None:
        plain = _plain_derivatives_compiled

        def without_extension(extension_id, model_id, positive_only, sigma, d, params, order, work):
            return plain(model_id, positive_only, sigma, d, params, order, work)

        return without_extension
    derivatives = sys.modules[extension.__module__].derivatives

    def implementation(extension_id, model_id, positive_only, sigma, d, params, order, work):
        return derivatives(model_id, sigma, d, params, order, work)

    return implementation


@compiled_only
def principal_derivatives(model_id, extension_id, positive_only, sigma, d, params, order, work):
    """Ψ̂ext(σ) and, up to ``order`` (≤ 2), its gradient and Hessian into the G, H slots.

    Returns ``(energy, region)``: region 0 is the model itself, a positive value an extension
    region, :data:`UNDEFINED_REGION` a point where the unextended model is undefined (then the
    energy is +inf and the derivatives are zero). The ids and ``d``, the length of ``sigma``,
    are compile-time literals (:mod:`~dolfinx_invertible.constitutive.literal`).
    """
    return _extended_derivatives(
        extension_id, model_id, positive_only, sigma, d, params, order, work
    )


@compiled_only
def quotient_slope(sigma_i, sigma_j, g_i, g_j, h_ii, h_jj, h_ij):
    """(gᵢ − gⱼ)/(σᵢ − σⱼ) from scalars, with the symmetric limit for a tiny gap.

    The scalar core of :func:`gradient_slope` off the model: passing no arrays lets the caller
    inline it without the reference counting that every array argument or view costs.
    """
    gap = sigma_i - sigma_j
    if abs(gap) > _EQUAL_GAP * max(abs(sigma_i), abs(sigma_j)):
        return (g_i - g_j) / gap
    return 0.5 * (h_ii + h_jj) - h_ij


@compiled_only
def gradient_slope(model_id, region, sigma, params, work, i, j):
    """aᵢⱼ = (gᵢ − gⱼ)/(σᵢ − σⱼ), robust for σᵢ ≈ σⱼ.

    On the model (region 0) the model's closed form is exact. In an extension region the
    quotient is used while the gap is large; for a tiny gap the symmetric limit
    ½(Hᵢᵢ + Hⱼⱼ) − Hᵢⱼ, whose error is second order in the gap because aᵢⱼ is even in it.
    """
    d = sigma.shape[0]
    if region == 0:
        return model_gradient_slope(model_id, sigma, params, i, j, ws.table(work, ws.H_TABLE, d))
    gradient = ws.vector(work, ws.G, d)
    hessian = ws.matrix(work, ws.H, d)
    return quotient_slope(
        sigma[i], sigma[j], gradient[i], gradient[j], hessian[i, i], hessian[j, j], hessian[i, j]
    )


@compiled_only
def sum_slope(sigma_i, sigma_j, g_i, g_j):
    """(gᵢ + gⱼ)/(σᵢ + σⱼ) from scalars: the core of :func:`rotation_slope`."""
    total = sigma_i + sigma_j
    floor = _KINK_GAP * max(1.0, abs(sigma_i), abs(sigma_j))
    if abs(total) < floor:
        total = floor if total >= 0.0 else -floor
    return (g_i + g_j) / total


@compiled_only
def rotation_slope(sigma, g, i, j):
    """bᵢⱼ = (gᵢ + gⱼ)/(σᵢ + σⱼ) with the denominator kept away from 0 (sign preserved)."""
    return sum_slope(sigma[i], sigma[j], g[i], g[j])
