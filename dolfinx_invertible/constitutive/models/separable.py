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

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.constitutive.literal import dispatch_on_dimension, run_time_integers

__all__ = [
    "separable_anchor_derivatives",
    "separable_derivatives",
    "separable_gradient_slope",
    "volume_derivative",
]


# The unused index, not a literal: volume_derivative compiles once, not per argument pattern.
(_UNUSED,) = run_time_integers(-1)


@compiled_only
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


@compiled_only
def _volume_third(sigma, i, j, k):
    """Third derivative of K(J) = k₂/2 (J − 1)² + k₁ (J − 1), without the constants."""
    return (
        volume_derivative(sigma, i, j, _UNUSED, _UNUSED)
        * volume_derivative(sigma, k, _UNUSED, _UNUSED, _UNUSED)
        + volume_derivative(sigma, i, k, _UNUSED, _UNUSED)
        * volume_derivative(sigma, j, _UNUSED, _UNUSED, _UNUSED)
        + volume_derivative(sigma, j, k, _UNUSED, _UNUSED)
        * volume_derivative(sigma, i, _UNUSED, _UNUSED, _UNUSED)
    )


@compiled_only
def _volume_fourth(sigma, i, j, k, l):
    return (
        volume_derivative(sigma, i, j, _UNUSED, _UNUSED)
        * volume_derivative(sigma, k, l, _UNUSED, _UNUSED)
        + volume_derivative(sigma, i, k, _UNUSED, _UNUSED)
        * volume_derivative(sigma, j, l, _UNUSED, _UNUSED)
        + volume_derivative(sigma, i, l, _UNUSED, _UNUSED)
        * volume_derivative(sigma, j, k, _UNUSED, _UNUSED)
        + volume_derivative(sigma, i, j, k, _UNUSED)
        * volume_derivative(sigma, l, _UNUSED, _UNUSED, _UNUSED)
        + volume_derivative(sigma, i, j, l, _UNUSED)
        * volume_derivative(sigma, k, _UNUSED, _UNUSED, _UNUSED)
        + volume_derivative(sigma, i, k, l, _UNUSED)
        * volume_derivative(sigma, j, _UNUSED, _UNUSED, _UNUSED)
        + volume_derivative(sigma, j, k, l, _UNUSED)
        * volume_derivative(sigma, i, _UNUSED, _UNUSED, _UNUSED)
    )


def _specialised_separable_derivatives(d: int):
    """Compile :func:`separable_derivatives` for one dimension.

    Constant loop bounds unroll and the index tests fold away.
    """

    @compiled_only
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
                g[i] += dK * volume_derivative(sigma, i, _UNUSED, _UNUSED, _UNUSED)
        if order < 2:
            return psi
        for i in range(d):
            for j in range(d):
                value = c * h[i, 1] * h[j, 1]
                if has_volume:
                    value += k2 * volume_derivative(
                        sigma, i, _UNUSED, _UNUSED, _UNUSED
                    ) * volume_derivative(
                        sigma, j, _UNUSED, _UNUSED, _UNUSED
                    ) + dK * volume_derivative(sigma, i, j, _UNUSED, _UNUSED)
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
                            sigma, i, j, k, _UNUSED
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


def separable_derivatives(sigma, d, order, f, h, c, k1, k2, g, H, T, Q):
    """Ψ̂ and, up to ``order``, its derivative tensors ``g``, ``H``, ``T``, ``Q`` (overwritten).

    Terms whose constant is zero are skipped: most models have either the c or the k terms.
    ``d`` is the length of ``sigma``, a compile-time literal in compiled code.
    """
    return _SEPARABLE_DERIVATIVES[d](sigma, order, f, h, c, k1, k2, g, H, T, Q)


_SEPARABLE_DERIVATIVES = {d: _specialised_separable_derivatives(d) for d in (2, 3)}
dispatch_on_dimension(separable_derivatives, _SEPARABLE_DERIVATIVES)


@compiled_only
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
    return f_slope + c * S * h_slope - dK * volume_derivative(sigma, i, j, _UNUSED, _UNUSED)


@compiled_only
def _volume_first(q0, q1, q2, d, i):
    """∂J/∂σᵢ from scalars (q2 unused in 2D)."""
    if d == 2:
        return q1 if i == 0 else q0
    if i == 0:
        return q1 * q2
    if i == 1:
        return q0 * q2
    return q0 * q1


@compiled_only
def _volume_second(q0, q1, q2, d, i, j):
    """∂²J/∂σᵢ∂σⱼ from scalars."""
    if i == j:
        return 0.0
    if d == 2:
        return 1.0
    other = 3 - i - j
    if other == 0:
        return q0
    if other == 1:
        return q1
    return q2


def _specialised_separable_anchor(d: int):
    """Compile :func:`separable_anchor_derivatives` for one dimension."""

    @compiled_only
    def specialised(order, c, k1, k2, work):
        q = ws.Q_POINT
        a = ws.A_OFFSET
        f = ws.F_TABLE
        h = ws.H_TABLE
        has_volume = k1 != 0.0 or k2 != 0.0
        q0 = work[q]
        q1 = work[q + 1]
        q2 = work[q + 2] if d == 3 else 0.0
        S = 0.0
        J = 1.0
        psi = 0.0
        for i in range(d):
            psi += work[f + 5 * i]
            S += work[h + 5 * i]
            J *= work[q + i]
        psi += 0.5 * c * S * S + k1 * (J - 1.0) + 0.5 * k2 * (J - 1.0) ** 2
        if order < 1:
            return psi
        dK = k1 + k2 * (J - 1.0)
        for i in range(d):
            value = work[f + 5 * i + 1] + c * S * work[h + 5 * i + 1]
            if has_volume:
                value += dK * _volume_first(q0, q1, q2, d, i)
            work[ws.MODEL_G + i] = value
        if order < 2:
            return psi
        for i in range(d):
            for j in range(d):
                value = c * work[h + 5 * i + 1] * work[h + 5 * j + 1]
                if has_volume:
                    value += k2 * _volume_first(q0, q1, q2, d, i) * _volume_first(
                        q0, q1, q2, d, j
                    ) + dK * _volume_second(q0, q1, q2, d, i, j)
                if i == j:
                    value += work[f + 5 * i + 2] + c * S * work[h + 5 * i + 2]
                work[ws.MODEL_H + d * i + j] = value
        if order < 3:
            return psi
        # Contractions with a of h′ and of J's derivatives: J_a = ∇J·a, (J_a)ₖ = Σᵢ Jᵢₖ aᵢ,
        # J_aa = aᵀ∇²J a, and in 3D Σᵢ Jᵢₖₘ aᵢ = a of the third index (k ≠ m).
        slope_h = 0.0
        volume_a = 0.0
        for i in range(d):
            slope_h += work[h + 5 * i + 1] * work[a + i]
            volume_a += _volume_first(q0, q1, q2, d, i) * work[a + i]
        for k in range(d):
            volume_ak = 0.0
            for i in range(d):
                volume_ak += _volume_second(q0, q1, q2, d, i, k) * work[a + i]
            work[ws.Q3 + k] = volume_ak  # scratch until the extension fills Q3
        for k in range(d):
            a_k = work[a + k]
            t2 = 0.0
            for m in range(d):
                a_m = work[a + m]
                value = c * (a_k * work[h + 5 * k + 2] * work[h + 5 * m + 1])
                value += c * (a_m * work[h + 5 * m + 2] * work[h + 5 * k + 1])
                if has_volume:
                    volume_akm = 0.0
                    if d == 3 and k != m:
                        volume_akm = work[a + 3 - k - m]
                    value += (
                        k2
                        * (
                            work[ws.Q3 + k] * _volume_first(q0, q1, q2, d, m)
                            + work[ws.Q3 + m] * _volume_first(q0, q1, q2, d, k)
                            + _volume_second(q0, q1, q2, d, k, m) * volume_a
                        )
                        + dK * volume_akm
                    )
                if k == m:
                    value += c * work[h + 5 * k + 2] * slope_h
                    value += a_k * (work[f + 5 * k + 3] + c * S * work[h + 5 * k + 3])
                work[ws.T1 + d * k + m] = value
                t2 += value * a_m
            work[ws.T2 + k] = t2
        if order < 4:
            return psi
        curvature_h = 0.0
        volume_aa = 0.0
        for i in range(d):
            curvature_h += work[h + 5 * i + 2] * work[a + i] * work[a + i]
            volume_aa += work[ws.Q3 + i] * work[a + i]
        for k in range(d):
            a_k = work[a + k]
            for m in range(d):
                a_m = work[a + m]
                value = c * (
                    2.0 * a_k * work[h + 5 * k + 2] * a_m * work[h + 5 * m + 2]
                    + work[h + 5 * k + 1] * work[h + 5 * m + 3] * a_m * a_m
                    + work[h + 5 * m + 1] * work[h + 5 * k + 3] * a_k * a_k
                )
                if has_volume:
                    volume_akm = 0.0
                    if d == 3 and k != m:
                        volume_akm = work[a + 3 - k - m]
                    # Σᵢⱼ Jᵢⱼₖ aᵢ aⱼ: in 3D twice the product of the two other offsets.
                    volume_aak = 0.0
                    volume_aam = 0.0
                    if d == 3:
                        volume_aak = 2.0 * work[a + (k + 1) % 3] * work[a + (k + 2) % 3]
                        volume_aam = 2.0 * work[a + (m + 1) % 3] * work[a + (m + 2) % 3]
                    value += k2 * (
                        volume_aa * _volume_second(q0, q1, q2, d, k, m)
                        + 2.0 * work[ws.Q3 + k] * work[ws.Q3 + m]
                        + volume_aak * _volume_first(q0, q1, q2, d, m)
                        + volume_aam * _volume_first(q0, q1, q2, d, k)
                        + 2.0 * volume_a * volume_akm
                    )
                if k == m:
                    value += c * (
                        curvature_h * work[h + 5 * k + 2]
                        + 2.0 * slope_h * work[h + 5 * k + 3] * a_k
                    )
                    value += a_k * a_k * (work[f + 5 * k + 4] + c * S * work[h + 5 * k + 4])
                work[ws.Q2 + d * k + m] = value
        return psi

    return specialised


def separable_anchor_derivatives(q, d, order, c, k1, k2, work):
    """Ψ̂(q) with g, H and the contractions of the third and fourth derivatives with a.

    An extension evaluated at an anchor q only needs T[a, ·, ·] and Q[a, a, ·, ·] for the
    offset a of its segment, which the separable form gives directly, without the d³ and d⁴
    tensors of :func:`separable_derivatives`. Everything is read from and written to ``work``
    by offset (slots Q_POINT, A_OFFSET, F_TABLE, H_TABLE in; MODEL_G, MODEL_H, T1, T2, Q2 out):
    each array view costs two out-of-line reference-count calls, more than the arithmetic.
    Up to ``order`` (≤ 4): g at 1, H at 2, T[a, ·, ·] and T[a, a, ·] at 3, Q[a, a, ·, ·] at 4.
    """
    return _SEPARABLE_ANCHOR[d](order, c, k1, k2, work)


_SEPARABLE_ANCHOR = {d: _specialised_separable_anchor(d) for d in (2, 3)}
dispatch_on_dimension(separable_anchor_derivatives, _SEPARABLE_ANCHOR)
