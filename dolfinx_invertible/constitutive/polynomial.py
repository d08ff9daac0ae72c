"""The first crossing of a cubic through zero on (0, 1], robustly and without allocation.

Both the C2 extension (where the segment from the rest point meets J = ε) and the
inversion-free line search (where a cell's volume falls to a fraction of its current value) ask
the same question of a polynomial of degree ≤ 3 in the step parameter.
"""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.constitutive.compiled import compiled_only

__all__ = ["first_root_in_unit_interval", "single_root_in_unit_interval"]


@compiled_only
def _value(t, c0, c1, c2, c3):
    return c0 + t * (c1 + t * (c2 + t * c3))


@compiled_only
def _slope(t, c1, c2, c3):
    return c1 + t * (2.0 * c2 + 3.0 * t * c3)


@compiled_only
def _curvature(t, c2, c3):
    return 2.0 * c2 + 6.0 * t * c3


@compiled_only
def _bracketed_root(lo, hi, c0, c1, c2, c3):
    """Return the one root in [lo, hi] of a cubic that is > 0 left of it and ≤ 0 right of it.

    Halley's method from the secant point of the bracket, bisection where Halley would leave
    the bracket, the cubic is not falling, or Newton's step is not at most half the step before
    (the iterate is not yet converging to the root). Halley's error after a step is about the
    cube of that step, so once Newton's step, the distance to the root to first order, is below
    1e-6 (relative), the Halley step taken from there is the last. Halley's own step is no such
    measure: it also vanishes at a critical point of the cubic (slope 0, value not 0).
    """
    value_lo = _value(lo, c0, c1, c2, c3)
    value_hi = _value(hi, c0, c1, c2, c3)
    t = 0.5 * (lo + hi)
    if value_lo - value_hi > 0.0:
        secant = lo + (hi - lo) * value_lo / (value_lo - value_hi)
        if lo < secant < hi:
            t = secant
    previous = hi - lo
    for _ in range(100):
        value = _value(t, c0, c1, c2, c3)
        if value > 0.0:
            lo = t
        else:
            hi = t
        slope = _slope(t, c1, c2, c3)
        denominator = 2.0 * slope * slope - value * _curvature(t, c2, c3)
        halley = slope < 0.0 and denominator > 0.0 and 2.0 * abs(value) <= -previous * slope
        candidate = t - 2.0 * value * slope / denominator if halley else 0.5 * (lo + hi)
        # Halley while it stays inside the bracket, bisection otherwise.
        if not (lo < candidate < hi):
            candidate = 0.5 * (lo + hi)
            halley = False
        step = abs(candidate - t)
        size = max(t, 1e-300)
        converged = halley and abs(value) <= -1e-6 * size * slope
        if converged or step <= 1e-16 * size or hi - lo <= 1e-17:
            return candidate
        previous = step
        t = candidate
    return t


@compiled_only
def first_root_in_unit_interval(c0, c1, c2, c3):
    """Smallest t in (0, 1] where c0 + c1 t + c2 t² + c3 t³ falls to 0, given c0 > 0.

    Returns 2.0 when the cubic stays positive on (0, 1]. The critical points split [0, 1] into
    monotone pieces; the first piece whose right end is ≤ 0 holds the first crossing.
    """
    first = 2.0
    second = 2.0
    if c3 != 0.0:
        discriminant = 4.0 * c2 * c2 - 12.0 * c1 * c3
        if discriminant >= 0.0:
            root = np.sqrt(discriminant)
            half = -0.5 * (2.0 * c2 + (root if c2 >= 0.0 else -root))
            if half != 0.0:
                first = half / (3.0 * c3)
                second = c1 / half
    elif c2 != 0.0:
        first = -c1 / (2.0 * c2)
    if second < first:
        first, second = second, first
    lo = 0.0
    for hi in (first, second, 1.0):
        if not (lo < hi <= 1.0):
            continue
        if _value(hi, c0, c1, c2, c3) <= 0.0:
            return _bracketed_root(lo, hi, c0, c1, c2, c3)
        lo = hi
    return 2.0


@compiled_only
def single_root_in_unit_interval(c0, c1, c2, c3):
    """Return where in (0, 1] a cubic known to change sign there once crosses 0.

    The caller knows the cubic is > 0 on [0, t) and < 0 on (t, 1] (c0 > 0 ≥ its value at 1),
    so the bracket needs no search for critical points, unlike
    :func:`first_root_in_unit_interval`. Returns 1.0 if the value at 1 is still > 0 (round-off
    at a crossing right at 1).
    """
    if _value(1.0, c0, c1, c2, c3) > 0.0:
        return 1.0
    return _bracketed_root(0.0, 1.0, c0, c1, c2, c3)
