"""Derivatives in singular-value space of energies of *separable* form.

Every built-in model is written as

    Ψ̂(σ) = Σᵢ f(σᵢ) + c/2 (Σᵢ h(σᵢ))² + k₁ (J − 1) + k₂/2 (J − 1)²,   J = Πᵢ σᵢ,

so a model only supplies the scalar functions f, h with their first four derivatives (a
``(d, 5)`` table evaluated at each σᵢ), the constants c, k₁, k₂, and exact divided differences
of f′ and h′. This module turns that into Ψ̂ and its full gradient, Hessian and third and fourth
derivative tensors (the extensions need up to fourth order), and into the robust quotient
aᵢⱼ = (gᵢ − gⱼ)/(σᵢ − σⱼ) of the stress derivative's off-diagonal blocks.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["separable_derivatives", "separable_gradient_slope", "volume_derivative"]


@numba.njit(cache=True)
def volume_derivative(sigma, i, j, k, l):
    """Mixed partial of J = Πσ over the listed indices (−1 = unused).

    J is multilinear, so a repeated index gives 0 and distinct ones drop their factors.
    """
    d = sigma.shape[0]
    mask = 0
    for index in (i, j, k, l):
        if index >= 0:
            bit = 1 << index
            if mask & bit:
                return 0.0
            mask |= bit
    value = 1.0
    for m in range(d):
        if not mask & (1 << m):
            value *= sigma[m]
    return value


@numba.njit(cache=True)
def separable_derivatives(sigma, order, f, h, c, k1, k2, g, H, T, Q):
    """Ψ̂ and, up to ``order``, its derivative tensors ``g``, ``H``, ``T``, ``Q`` (overwritten)."""
    d = sigma.shape[0]
    S = 0.0
    J = 1.0
    psi = 0.0
    for i in range(d):
        psi += f[i, 0]
        S += h[i, 0]
        J *= sigma[i]
    psi += 0.5 * c * S * S + k1 * (J - 1.0) + 0.5 * k2 * (J - 1.0) ** 2
    if order < 1:
        return psi
    dK = k1 + k2 * (J - 1.0)
    for i in range(d):
        g[i] = f[i, 1] + c * S * h[i, 1] + dK * volume_derivative(sigma, i, -1, -1, -1)
    if order < 2:
        return psi
    for i in range(d):
        Ji = volume_derivative(sigma, i, -1, -1, -1)
        for j in range(d):
            Jj = volume_derivative(sigma, j, -1, -1, -1)
            value = c * h[i, 1] * h[j, 1] + k2 * Ji * Jj + dK * volume_derivative(sigma, i, j, -1, -1)
            if i == j:
                value += f[i, 2] + c * S * h[i, 2]
            H[i, j] = value
    if order < 3:
        return psi
    for i in range(d):
        for j in range(d):
            for k in range(d):
                Jij = volume_derivative(sigma, i, j, -1, -1)
                Jik = volume_derivative(sigma, i, k, -1, -1)
                Jjk = volume_derivative(sigma, j, k, -1, -1)
                value = k2 * (
                    Jij * volume_derivative(sigma, k, -1, -1, -1)
                    + Jik * volume_derivative(sigma, j, -1, -1, -1)
                    + Jjk * volume_derivative(sigma, i, -1, -1, -1)
                ) + dK * volume_derivative(sigma, i, j, k, -1)
                if i == j:
                    value += c * h[i, 2] * h[k, 1]
                if i == k:
                    value += c * h[i, 2] * h[j, 1]
                if j == k:
                    value += c * h[j, 2] * h[i, 1]
                if i == j and j == k:
                    value += f[i, 3] + c * S * h[i, 3]
                T[i, j, k] = value
    if order < 4:
        return psi
    for i in range(d):
        for j in range(d):
            for k in range(d):
                for l in range(d):
                    value = k2 * (
                        volume_derivative(sigma, i, j, -1, -1) * volume_derivative(sigma, k, l, -1, -1)
                        + volume_derivative(sigma, i, k, -1, -1) * volume_derivative(sigma, j, l, -1, -1)
                        + volume_derivative(sigma, i, l, -1, -1) * volume_derivative(sigma, j, k, -1, -1)
                        + volume_derivative(sigma, i, j, k, -1) * volume_derivative(sigma, l, -1, -1, -1)
                        + volume_derivative(sigma, i, j, l, -1) * volume_derivative(sigma, k, -1, -1, -1)
                        + volume_derivative(sigma, i, k, l, -1) * volume_derivative(sigma, j, -1, -1, -1)
                        + volume_derivative(sigma, j, k, l, -1) * volume_derivative(sigma, i, -1, -1, -1)
                    ) + dK * volume_derivative(sigma, i, j, k, l)
                    # Faà di Bruno for c/2 S² (S'' and higher of the square vanish beyond these).
                    if i == k and i == l:
                        value += c * h[i, 3] * h[j, 1]
                    if j == k and j == l:
                        value += c * h[j, 3] * h[i, 1]
                    if i == j and i == l:
                        value += c * h[i, 3] * h[k, 1]
                    if i == j and i == k:
                        value += c * h[i, 3] * h[l, 1]
                    if i == k and j == l:
                        value += c * h[i, 2] * h[j, 2]
                    if i == l and j == k:
                        value += c * h[i, 2] * h[j, 2]
                    if i == j and k == l:
                        value += c * h[i, 2] * h[k, 2]
                    if i == j and j == k and k == l:
                        value += f[i, 4] + c * S * h[i, 4]
                    Q[i, j, k, l] = value
    return psi


@numba.njit(cache=True)
def separable_gradient_slope(sigma, i, j, f_slope, h_slope, c, k1, k2, h):
    """aᵢⱼ = (gᵢ − gⱼ)/(σᵢ − σⱼ) without cancellation, from exact divided differences.

    ``f_slope`` and ``h_slope`` are the model's divided differences of f′ and h′ at (σᵢ, σⱼ);
    for the volume term (J/σᵢ − J/σⱼ)/(σᵢ − σⱼ) = −Π_{k≠i,j} σₖ exactly.
    """
    d = sigma.shape[0]
    S = 0.0
    J = 1.0
    for m in range(d):
        S += h[m, 0]
        J *= sigma[m]
    dK = k1 + k2 * (J - 1.0)
    return f_slope + c * S * h_slope - dK * volume_derivative(sigma, i, j, -1, -1)
