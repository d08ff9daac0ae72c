"""The first positive root of quadratics, elementwise over NumPy arrays.

Straight-path crossings reduce to it: along x + α p the gap to a plane is linear in α and the
squared distances that define a sphere, cylinder or cone are quadratic, so the first α at which
a point reaches such a shape is the first positive root of a polynomial of degree at most two.
(The cubic's first root on (0, 1], which the compiled kernels need, is
:mod:`dolfinx_invertible.constitutive.polynomial`.)
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["first_positive_root_quadratic"]


def first_positive_root_quadratic(c0: ArrayLike, c1: ArrayLike, c2: ArrayLike) -> np.ndarray:
    """First α > 0 where c₀ + c₁α + c₂α² falls to 0, elementwise, given c₀ > 0; else inf.

    With c₀ > 0 the first positive root, when there is one, is 2c₀ / (−c₁ + √(c₁² − 4c₀c₂))
    in all cases (c₂ of either sign or zero): this form of the smaller root does not cancel.
    A non-positive denominator or a negative discriminant means no positive root.

    Parameters
    ----------
    c0, c1, c2
        The coefficients, scalars or arrays of one shape.

    Returns
    -------
    numpy.ndarray
        The roots, at least one-dimensional.
    """
    c0 = np.asarray(c0, dtype=np.float64)
    c1 = np.asarray(c1, dtype=np.float64)
    c2 = np.asarray(c2, dtype=np.float64)
    discriminant = c1 * c1 - 4.0 * c0 * c2
    root = np.sqrt(np.maximum(discriminant, 0.0))
    denominator = -c1 + root
    crossing = discriminant >= 0.0
    crossing &= denominator > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        alpha = np.where(crossing, 2.0 * c0 / np.where(crossing, denominator, 1.0), math.inf)
    return np.atleast_1d(alpha)
