"""The first crossing of a cubic through zero on (0, 1], robustly and without allocation.

Both the C2 extension (where the segment from the rest point meets J = ε) and the
inversion-free line search (where a cell's volume falls to a fraction of its current value) ask
the same question of a polynomial of degree ≤ 3 in the step parameter.
"""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.constitutive.compiled import compiled_only

__all__ = ["first_root_in_unit_interval"]


@compiled_only
def _value(t, c0, c1, c2, c3):
    return c0 + t * (c1 + t * (c2 + t * c3))


@compiled_only
def _slope(t, c1, c2, c3):
    return c1 + t * (2.0 * c2 + 3.0 * t * c3)


@compiled_only
def _bracketed_root(lo, hi, c0, c1, c2, c3):
    """Root in [lo, hi] where the cubic is monotone and goes from > 0 to ≤ 0.

    Newton from the secant point of the bracket, bisection when Newton would leave it. A Newton
    step below 1e-9 (relative) leaves an error of about its square: that step is the last.
    """
    value_lo = _value(lo, c0, c1, c2, c3)
    value_hi = _value(hi, c0, c1, c2, c3)
    t = 0.5 * (lo + hi)
    if value_lo - value_hi > 0.0:
        secant = lo + (hi - lo) * value_lo / (value_lo - value_hi)
        if lo < secant < hi:
            t = secant
    for _ in range(100):
        value = _value(t, c0, c1, c2, c3)
        if value > 0.0:
            lo = t
        else:
            hi = t
        slope = _slope(t, c1, c2, c3)
        newton = slope < 0.0
        candidate = t - value / slope if newton else 0.5 * (lo + hi)
        # Newton while it stays inside the bracket, bisection otherwise.
        if not (lo < candidate < hi):
            candidate = 0.5 * (lo + hi)
            newton = False
        step = abs(candidate - t)
        size = max(t, 1e-300)
        if (newton and step <= 1e-9 * size) or step <= 1e-16 * size or hi - lo <= 1e-17:
            return candidate
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
