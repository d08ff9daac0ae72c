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

__all__ = ["separable_derivatives", "separable_gradient_slope", "volume_derivative"]


@numba.njit(cache=True)
def volume_derivative(sigma, i, j, k, l):
    """Mixed partial of J = Πσ over ``i`` and the listed indices (−1 = unused), for d ≤ 3.

    J is multilinear, so a repeated index gives 0 and distinct ones drop their factors.
    """
    d = sigma.shape[0]
    if j < 0:
        if d == 2:
            return sigma[1 - i]
        return sigma[(i + 1) % 3] * sigma[(i + 2) % 3]
    if i == j:
        return 0.0
    if k < 0:
        return 1.0 if d == 2 else sigma[3 - i - j]
    if d == 2 or k == i or k == j:
        return 0.0
    # Three distinct indices in 3D: J_ijk = 1 and any fourth index repeats one of them.
    return 1.0 if l < 0 else 0.0


@numba.njit(cache=True)
def _volume_third(sigma, i, j, k):
    """Third derivative of K(J) = k₂/2 (J − 1)² + k₁ (J − 1), without the constants."""
    return (
        volume_derivative(sigma, i, j, -1, -1) * volume_derivative(sigma, k, -1, -1, -1)
        + volume_derivative(sigma, i, k, -1, -1) * volume_derivative(sigma, j, -1, -1, -1)
        + volume_derivative(sigma, j, k, -1, -1) * volume_derivative(sigma, i, -1, -1, -1)
    )


@numba.njit(cache=True)
def _volume_fourth(sigma, i, j, k, l):
    return (
        volume_derivative(sigma, i, j, -1, -1) * volume_derivative(sigma, k, l, -1, -1)
        + volume_derivative(sigma, i, k, -1, -1) * volume_derivative(sigma, j, l, -1, -1)
        + volume_derivative(sigma, i, l, -1, -1) * volume_derivative(sigma, j, k, -1, -1)
        + volume_derivative(sigma, i, j, k, -1) * volume_derivative(sigma, l, -1, -1, -1)
        + volume_derivative(sigma, i, j, l, -1) * volume_derivative(sigma, k, -1, -1, -1)
        + volume_derivative(sigma, i, k, l, -1) * volume_derivative(sigma, j, -1, -1, -1)
        + volume_derivative(sigma, j, k, l, -1) * volume_derivative(sigma, i, -1, -1, -1)
    )


@numba.njit(cache=True)
def separable_derivatives(sigma, order, f, h, c, k1, k2, g, H, T, Q):
    """Ψ̂ and, up to ``order``, its derivative tensors ``g``, ``H``, ``T``, ``Q`` (overwritten).

    Terms whose constant is zero are skipped: most models have either the c or the k terms.
    """
    if sigma.shape[0] == 3:
        return _separable_derivatives_3d(sigma, order, f, h, c, k1, k2, g, H, T, Q)
    return _separable_derivatives_2d(sigma, order, f, h, c, k1, k2, g, H, T, Q)


def _specialised_separable_derivatives(d: int):
    """Compile :func:`separable_derivatives` for one dimension.

    Constant loop bounds unroll and the index tests fold away.
    """

    @numba.njit(cache=True)
    def specialised(sigma, order, f, h, c, k1, k2, g, H, T, Q):
        has_sum = c != 0.0
        has_volume = k1 != 0.0 or k2 != 0.0
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
            g[i] = f[i, 1] + c * S * h[i, 1]
            if has_volume:
                g[i] += dK * volume_derivative(sigma, i, -1, -1, -1)
        if order < 2:
            return psi
        for i in range(d):
            for j in range(d):
                value = c * h[i, 1] * h[j, 1]
                if has_volume:
                    value += k2 * volume_derivative(sigma, i, -1, -1, -1) * volume_derivative(
                        sigma, j, -1, -1, -1
                    ) + dK * volume_derivative(sigma, i, j, -1, -1)
                if i == j:
                    value += f[i, 2] + c * S * h[i, 2]
                H[i, j] = value
        if order < 3:
            return psi
        for i in range(d):
            for j in range(d):
                for k in range(d):
                    value = 0.0
                    if has_volume:
                        value += k2 * _volume_third(sigma, i, j, k) + dK * volume_derivative(
                            sigma, i, j, k, -1
                        )
                    if has_sum:
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
                        value = 0.0
                        # J is multilinear in 3D, so its fourth derivative vanishes.
                        if has_volume:
                            value += k2 * _volume_fourth(sigma, i, j, k, l)
                        # Faà di Bruno for c/2 S²: products of derivatives of S, at most two
                        # factors.
                        if has_sum:
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

    return specialised


_separable_derivatives_2d = _specialised_separable_derivatives(2)
_separable_derivatives_3d = _specialised_separable_derivatives(3)


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
