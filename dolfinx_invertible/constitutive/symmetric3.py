"""Closed-form spectra of symmetric 3×3 matrices, on scalars and tuples (no array traffic).

Shared by the polar SVD's starting point (:mod:`~dolfinx_invertible.constitutive.svd`) and the
SVD-free projected tangent (:mod:`~dolfinx_invertible.constitutive.invariants`). A symmetric
matrix is passed as its six entries (a00, a11, a22, a01, a02, a12).
"""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.constitutive.compiled import compiled_only

__all__ = ["angle", "cross", "dot", "eigenvalues", "largest_cubic_root", "null_vector", "spread"]

_SQRT3 = 1.7320508075688772


@compiled_only
def dot(x, y):
    """Return the dot product of two 3-tuples."""
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]


@compiled_only
def cross(x, y):
    """Return the cross product of two 3-tuples."""
    return (x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0])


@compiled_only
def largest_cubic_root(r):
    """Largest root c of 4c³ − 3c = r for 0 ≤ r ≤ 1, i.e. cos(arccos(r)/3), in [√3/2, 1].

    The function is analytic on (−1, 1] (its branch point is r = −1), so a degree-6 Chebyshev
    interpolant on [0, 1] is within 9e-8 of it; one Newton step on the cubic, whose derivative
    12c² − 3 stays in [6, 9], takes that to 1.4e-14. This replaces arccos, cos and sin (and their
    latency) in the trigonometric formula for the eigenvalues of a symmetric 3×3 matrix.
    """
    c = 0.8660254934184151 + r * (
        0.16665781361554563
        + r
        * (
            -0.04796516703978661
            + r
            * (
                0.02373457681002681
                + r
                * (-0.012443532696727697 + r * (0.004995539940645294 - r * 0.0010047751159650683))
            )
        )
    )
    return c - (4.0 * c * c * c - 3.0 * c - r) / (12.0 * c * c - 3.0)


@compiled_only
def spread(a00, a11, a22, a01, a02, a12):
    """Return (q, p², B's diagonal) with A = q I + p B, tr B = 0 and tr B² = 6."""
    q = (a00 + a11 + a22) * (1.0 / 3.0)
    b00 = a00 - q
    b11 = a11 - q
    b22 = a22 - q
    p2 = (b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * (a01 * a01 + a02 * a02 + a12 * a12)) * (
        1.0 / 6.0
    )
    return q, p2, b00, b11, b22


@compiled_only
def angle(b00, b11, b22, a01, a02, a12, p2):
    """Return (p, sign, c, s) of the trigonometric formula for the eigenvalues (p² > 0).

    The eigenvalues are q + 2p cos θₖ with cos 3θₖ = r = det(B)/2. With c = cos θ the largest
    root for |r| and s = sin θ, the offsets are sign·2c (the end of the spectrum farthest from
    the middle) and sign·(−c ± √3 s); sin θ from sin 3θ = sin θ (4c² − 1), 1 − r² factored.
    """
    p = np.sqrt(p2)
    det_pb = (
        b00 * (b11 * b22 - a12 * a12)
        - a01 * (a01 * b22 - a12 * a02)
        + a02 * (a01 * a12 - b11 * a02)
    )
    r = 0.5 * det_pb / (p2 * p)
    sign = np.copysign(1.0, r)
    ar = min(1.0, abs(r))
    c = largest_cubic_root(ar)
    s = np.sqrt((1.0 - ar) * (1.0 + ar)) / (4.0 * c * c - 1.0)
    return p, sign, c, s


@compiled_only
def eigenvalues(a00, a11, a22, a01, a02, a12):
    """Return the eigenvalues of a symmetric 3×3 matrix, largest first (trigonometric formula).

    Each is within a few ulps of ‖A‖ of the exact one (absolute, not relative: a small
    eigenvalue of a matrix with a large one loses its relative accuracy).
    """
    q, p2, b00, b11, b22 = spread(a00, a11, a22, a01, a02, a12)
    if not p2 > 0.0:
        return q, q, q
    p, sign, c, s = angle(b00, b11, b22, a01, a02, a12, p2)
    if sign > 0.0:
        return q + 2.0 * p * c, q - p * (c - _SQRT3 * s), q - p * (c + _SQRT3 * s)
    return q + p * (c + _SQRT3 * s), q + p * (c - _SQRT3 * s), q - 2.0 * p * c


@compiled_only
def null_vector(a00, a11, a22, a01, a02, a12, lam):
    """Return a (non-unit) null vector of A − λI and its squared length.

    The longest of the cross products of two rows: for a simple eigenvalue λ the rows span the
    plane orthogonal to the eigenvector, and the longest product is the best conditioned.
    """
    r0 = (a00 - lam, a01, a02)
    r1 = (a01, a11 - lam, a12)
    r2 = (a02, a12, a22 - lam)
    c01 = cross(r0, r1)
    c02 = cross(r0, r2)
    c12 = cross(r1, r2)
    n01 = dot(c01, c01)
    n02 = dot(c02, c02)
    n12 = dot(c12, c12)
    if n01 >= n02 and n01 >= n12:
        return c01, n01
    if n02 >= n12:
        return c02, n02
    return c12, n12
