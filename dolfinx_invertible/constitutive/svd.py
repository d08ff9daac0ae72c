"""Polar singular value decomposition of 2×2 and 3×3 matrices.

``F = U diag(sigma) Vᵀ`` with ``U`` and ``V`` proper rotations (det +1). When det F < 0 the
singular value of smallest magnitude carries the sign (the "invertible finite element"
convention of Irving et al. 2004), so at most one entry of ``sigma`` is negative and
``|sigma|`` is sorted in decreasing order.

The 3×3 decomposition is a one-sided (Hestenes) Jacobi iteration on the columns of ``F``: it
works on ``F`` itself rather than ``FᵀF``, so small singular values keep their relative accuracy,
and it needs no allocation. It starts from an estimate of ``V`` taken in closed form from the
eigenvectors of ``FᵀF``: that estimate alone would lose the small singular values (``FᵀF`` squares
the condition number), but as a starting point it leaves the Jacobi iteration rotations of
round-off size, which one first-order sweep (the three rotations applied at once) usually
finishes, instead of four sweeps from the identity. Where the estimate is poor (nearly isotropic
F) the ordinary sweeps follow; their convergence test, not the estimate, decides the accuracy.
``U`` is completed with cross products, which makes it a rotation even when ``F`` is rank
deficient.
"""

from __future__ import annotations

import functools

import numpy as np

from dolfinx_invertible.constitutive.compiled import compiled_only, python_callable
from dolfinx_invertible.constitutive.literal import dispatch_on_dimension
from dolfinx_invertible.constitutive.symmetric3 import angle, cross, dot, null_vector, spread

__all__ = ["polar_svd", "polar_svd_point"]

# Columns whose cosine is below this count as orthogonal (a few ulps).
_ORTHOGONALITY_TOLERANCE = 1e-15
_MAX_SWEEPS = 12
# Below this |γ/(β − α)| a rotation takes the small-angle formulas (truncation error 2τ⁴ < 1e-17).
_SMALL_ANGLE = 5e-5
# A sweep whose rotations all have |tan θ| below this leaves cosines of round-off size.
_CONVERGED_TANGENT = 1e-8
# Below this every |tan θ| of a sweep, the three rotations may be applied at once to first order:
# what that neglects (products of two tangents, 1 − cos θ) is below 1e-18, relative to each column.
_FIRST_ORDER_TANGENT = 1e-9
# A column this much shorter than the longest carries no direction information.
_RANK_TOLERANCE = 1e-13
# FᵀF closer than this (spread of eigenvalues over their mean, squared) to a multiple of the
# identity has no eigenvector information above round-off: the iteration starts from V = I.
_ISOTROPIC_TOLERANCE = 1e-24
_SQRT3 = 1.7320508075688772
# Inside these bounds on |F|² nothing the 3×3 routine forms (up to the fourth power of FᵀF, in the
# warm start's cross products) overflows or underflows, so F needs no scaling.
_UNSCALED_MIN = 1e-40
_UNSCALED_MAX = 1e40
# Starting points of the 3×3 iteration (returned for the tests): V = I, one plane rotation of an
# F whose columns are orthogonal but for one pair, eigenvectors with the rotation in the plane of
# a close pair, eigenvectors of both ends of the spectrum.
START_IDENTITY = 0
START_ONE_PAIR = 1
START_CLOSE_PAIR = 2
START_EIGENVECTORS = 3
# sin θ of the trigonometric formula below which the two eigenvalues nearest each other are too
# close (gap √3 sin θ times the spread) for the null-vector formula to give the second
# eigenvector to 1e-11: its error is about (1e-14 + round-off of A over the spread) / sin θ.
_SPLIT_SINE = 1e-3


@compiled_only
def _unit_perpendicular(x0, x1, x2):
    """Return a unit vector perpendicular to the unit vector (x0, x1, x2)."""
    # Cross with the axis along which x is smallest: the result is never short.
    if abs(x0) <= abs(x1) and abs(x0) <= abs(x2):
        y0, y1, y2 = 0.0, -x2, x1
    elif abs(x1) <= abs(x2):
        y0, y1, y2 = x2, 0.0, -x0
    else:
        y0, y1, y2 = -x1, x0, 0.0
    length = np.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
    return y0 / length, y1 / length, y2 / length


@compiled_only
def _jacobi_pair(wp, wq, vp, vq):
    """Rotate columns p, q of W (and of V alongside) so that they become orthogonal.

    Columns are tuples so that the whole iteration stays in registers. Returns the new columns
    and |tan θ| of the rotation (0 when the pair was already orthogonal).
    """
    alpha = dot(wp, wp)
    beta = dot(wq, wq)
    gamma = dot(wp, wq)
    # Squared test: no square root on the (frequent) converged path.
    if gamma * gamma <= _ORTHOGONALITY_TOLERANCE**2 * (alpha * beta):
        return wp, wq, vp, vq, 0.0
    difference = beta - alpha
    if abs(gamma) < _SMALL_ANGLE * abs(difference):
        # Small angle (the last sweeps): t = τ − τ³ + O(τ⁵) with τ = γ/(β − α) and
        # c = 1 − t²/2 + O(t⁴), both exact to round-off here; one division instead of the
        # chain of two square roots and three divisions.
        tau = gamma / difference
        t = tau * (1.0 - tau * tau)
        c = 1.0 - 0.5 * t * t
    else:
        zeta = difference / (2.0 * gamma)
        t = 1.0 / (abs(zeta) + np.sqrt(1.0 + zeta * zeta))
        if zeta < 0.0:
            t = -t
        c = 1.0 / np.sqrt(1.0 + t * t)
    s = c * t
    wp_new = (c * wp[0] - s * wq[0], c * wp[1] - s * wq[1], c * wp[2] - s * wq[2])
    wq_new = (s * wp[0] + c * wq[0], s * wp[1] + c * wq[1], s * wp[2] + c * wq[2])
    vp_new = (c * vp[0] - s * vq[0], c * vp[1] - s * vq[1], c * vp[2] - s * vq[2])
    vq_new = (s * vp[0] + c * vq[0], s * vp[1] + c * vq[1], s * vp[2] + c * vq[2])
    return wp_new, wq_new, vp_new, vq_new, abs(t)


@compiled_only
def _times(w0, w1, w2, v):
    """Return the matrix with columns w0, w1, w2 times the vector v."""
    return (
        w0[0] * v[0] + w1[0] * v[1] + w2[0] * v[2],
        w0[1] * v[0] + w1[1] * v[1] + w2[1] * v[2],
        w0[2] * v[0] + w1[2] * v[1] + w2[2] * v[2],
    )


@compiled_only
def _warm_start(w0, w1, w2):
    """Return the Jacobi starting point (F V, V) column by column, V a rotation, and its code.

    When F's columns are orthogonal but for at most one pair, V is the exact rotation of that
    pair. Otherwise V holds eigenvectors of A = FᵀF, eigenvalues from the trigonometric formula.
    First x, the eigenvector of the eigenvalue farthest from the other two, as the null vector of
    A − λI. Then, when the other two are well apart (sin θ ≥ `_SPLIT_SINE`, below), y, the
    eigenvector of the other end of the spectrum, the same way and side by side with x,
    orthogonalised against it; otherwise (a near double eigenvalue, or a spread so wide that the
    small end is round-off of the large one) the exact Jacobi rotation in the plane orthogonal to
    x, which needs no gap. The cross product completes V. The error of the result is about
    round-off over the relative eigenvalue gaps, which the sweeps that follow remove. V = I
    covers an A with no eigenvector information (a multiple of the identity to round-off) and a
    non-finite A.
    """
    a00 = dot(w0, w0)
    a11 = dot(w1, w1)
    a22 = dot(w2, w2)
    a01 = dot(w0, w1)
    a02 = dot(w0, w2)
    a12 = dot(w1, w2)
    q, p2, b00, b11, b22 = spread(a00, a11, a22, a01, a02, a12)
    identity = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
    if not p2 > _ISOTROPIC_TOLERANCE * q * q:
        return w0, w1, w2, identity[0], identity[1], identity[2], START_IDENTITY
    # Columns already orthogonal (diagonal or axis-aligned F, often a benchmark's or a test's)
    # but for at most one pair: one exact rotation of that pair is cheaper than eigenvectors,
    # and it leaves the others orthogonal (both new columns stay in the pair's plane).
    tolerance = _ORTHOGONALITY_TOLERANCE**2
    coupled01 = not a01 * a01 <= tolerance * (a00 * a11)
    coupled02 = not a02 * a02 <= tolerance * (a00 * a22)
    coupled12 = not a12 * a12 <= tolerance * (a11 * a22)
    if int(coupled01) + int(coupled02) + int(coupled12) <= 1:
        v0, v1, v2 = identity
        if coupled01:
            w0, w1, v0, v1, _ = _jacobi_pair(w0, w1, v0, v1)
        elif coupled02:
            w0, w2, v0, v2, _ = _jacobi_pair(w0, w2, v0, v2)
        elif coupled12:
            w1, w2, v1, v2, _ = _jacobi_pair(w1, w2, v1, v2)
        return w0, w1, w2, v0, v1, v2, START_ONE_PAIR
    # The roots are sign·c (the end farthest from the middle) and −sign·(c ± √3 sin θ)/2.
    p, sign, c, s = angle(b00, b11, b22, a01, a02, a12, p2)
    x, nx = null_vector(a00, a11, a22, a01, a02, a12, q + sign * (2.0 * p) * c)
    if not nx > 0.0:
        return w0, w1, w2, identity[0], identity[1], identity[2], START_IDENTITY
    if s < _SPLIT_SINE:
        inverse = 1.0 / np.sqrt(nx)
        x = (x[0] * inverse, x[1] * inverse, x[2] * inverse)
        y = _unit_perpendicular(x[0], x[1], x[2])
        z = cross(x, y)
        fy, fz, y, z, _ = _jacobi_pair(_times(w0, w1, w2, y), _times(w0, w1, w2, z), y, z)
        # (x, y, z) and its cyclic shift are rotations; x goes where the sort would put it.
        if sign > 0.0:
            return _times(w0, w1, w2, x), fy, fz, x, y, z, START_CLOSE_PAIR
        return fy, fz, _times(w0, w1, w2, x), y, z, x, START_CLOSE_PAIR
    y, ny = null_vector(a00, a11, a22, a01, a02, a12, q - sign * p * (c + _SQRT3 * s))
    inverse = 1.0 / np.sqrt(nx)
    # y minus its component along x, using x before normalisation (no wait for the square root).
    projection = dot(x, y) / nx
    y = (y[0] - projection * x[0], y[1] - projection * x[1], y[2] - projection * x[2])
    x = (x[0] * inverse, x[1] * inverse, x[2] * inverse)
    length2 = dot(y, y)
    if length2 > _RANK_TOLERANCE**2 * ny:
        inverse = 1.0 / np.sqrt(length2)
        y = (y[0] * inverse, y[1] * inverse, y[2] * inverse)
    else:
        y = _unit_perpendicular(x[0], x[1], x[2])
    # Columns by decreasing eigenvalue: (x, y × x, y) for r ≥ 0, (y, x × y, x) for r < 0; both
    # are cyclic shifts of (a, b, a × b), rotations.
    if sign > 0.0:
        z = cross(y, x)
        fx, fz, fy = _times(w0, w1, w2, x), _times(w0, w1, w2, z), _times(w0, w1, w2, y)
        return fx, fz, fy, x, z, y, START_EIGENVECTORS
    z = cross(x, y)
    fy, fz, fx = _times(w0, w1, w2, y), _times(w0, w1, w2, z), _times(w0, w1, w2, x)
    return fy, fz, fx, y, z, x, START_EIGENVECTORS


@compiled_only
def _first_order_tangent(alpha, beta, gamma):
    """Return tan θ of the rotation that makes a pair orthogonal, or inf if it is not small.

    Same rotation as `_jacobi_pair` (α, β the squared lengths, γ the dot product), to first order
    in τ = γ/(β − α); inf when |τ| ≥ `_FIRST_ORDER_TANGENT`, including β = α with γ ≠ 0.
    """
    if gamma * gamma <= _ORTHOGONALITY_TOLERANCE**2 * (alpha * beta):
        return 0.0
    difference = beta - alpha
    if abs(gamma) < _FIRST_ORDER_TANGENT * abs(difference):
        return gamma / difference
    return np.inf


@compiled_only
def _first_order_sweep(w0, w1, w2, v0, v1, v2):
    """Orthogonalise nearly orthogonal columns with the three rotations of a sweep at once.

    Returns whether every rotation was small enough (`_FIRST_ORDER_TANGENT`) and the new columns
    (W and V times I + T, T the antisymmetric matrix of the tangents). Unlike a sweep, the three
    tangents are independent, so their divisions do not wait for each other. On False the columns
    are returned unchanged.
    """
    a0 = dot(w0, w0)
    a1 = dot(w1, w1)
    a2 = dot(w2, w2)
    t01 = _first_order_tangent(a0, a1, dot(w0, w1))
    t02 = _first_order_tangent(a0, a2, dot(w0, w2))
    t12 = _first_order_tangent(a1, a2, dot(w1, w2))
    if not max(abs(t01), abs(t02), abs(t12)) < _FIRST_ORDER_TANGENT:
        return False, w0, w1, w2, v0, v1, v2
    x0, x1, x2 = _times_identity_plus(w0, w1, w2, t01, t02, t12)
    y0, y1, y2 = _times_identity_plus(v0, v1, v2, t01, t02, t12)
    return True, x0, x1, x2, y0, y1, y2


@compiled_only
def _times_identity_plus(c0, c1, c2, t01, t02, t12):
    """Columns of [c0 c1 c2] (I + T), T antisymmetric with T₀₁ = t01, T₀₂ = t02, T₁₂ = t12."""
    return (
        (
            c0[0] - t01 * c1[0] - t02 * c2[0],
            c0[1] - t01 * c1[1] - t02 * c2[1],
            c0[2] - t01 * c1[2] - t02 * c2[2],
        ),
        (
            c1[0] + t01 * c0[0] - t12 * c2[0],
            c1[1] + t01 * c0[1] - t12 * c2[1],
            c1[2] + t01 * c0[2] - t12 * c2[2],
        ),
        (
            c2[0] + t02 * c0[0] + t12 * c1[0],
            c2[1] + t02 * c0[1] + t12 * c1[1],
            c2[2] + t02 * c0[2] + t12 * c1[2],
        ),
    )


@compiled_only
def _negated(x):
    return (-x[0], -x[1], -x[2])


@compiled_only
def _polar_svd_3_sweeps(F, U, sigma, V, warm):
    """Compute the 3×3 polar SVD; return the number of Jacobi sweeps and the starting point.

    ``warm`` chooses the closed-form starting point (else V = I), so that the tests can compare
    both starts and see which path a matrix takes. 0 sweeps: the starting point needed only the
    first-order sweep. The starting point is one of the ``START_*`` codes.
    """
    w0 = (F[0, 0], F[1, 0], F[2, 0])
    w1 = (F[0, 1], F[1, 1], F[2, 1])
    w2 = (F[0, 2], F[1, 2], F[2, 2])
    # Outside the unscaled bounds on |F|² (or for a non-finite F) the columns are scaled by the
    # largest entry first.
    scale = 1.0
    norm2 = dot(w0, w0) + dot(w1, w1) + dot(w2, w2)
    if not _UNSCALED_MIN < norm2 < _UNSCALED_MAX:
        scale = 0.0
        for i in range(3):
            for j in range(3):
                scale = max(scale, abs(F[i, j]))
        if scale == 0.0:
            for i in range(3):
                sigma[i] = 0.0
                for j in range(3):
                    U[i, j] = 1.0 if i == j else 0.0
                    V[i, j] = U[i, j]
            return 0, START_IDENTITY
        inverse_scale = 1.0 / scale
        w0 = (w0[0] * inverse_scale, w0[1] * inverse_scale, w0[2] * inverse_scale)
        w1 = (w1[0] * inverse_scale, w1[1] * inverse_scale, w1[2] * inverse_scale)
        w2 = (w2[0] * inverse_scale, w2[1] * inverse_scale, w2[2] * inverse_scale)
    if warm:
        w0, w1, w2, v0, v1, v2, start = _warm_start(w0, w1, w2)
        done, w0, w1, w2, v0, v1, v2 = _first_order_sweep(w0, w1, w2, v0, v1, v2)
    else:
        v0 = (1.0, 0.0, 0.0)
        v1 = (0.0, 1.0, 0.0)
        v2 = (0.0, 0.0, 1.0)
        done = False
        start = START_IDENTITY
    sweeps = 0
    while not done and sweeps < _MAX_SWEEPS:
        sweeps += 1
        w0, w1, v0, v1, t01 = _jacobi_pair(w0, w1, v0, v1)
        w0, w2, v0, v2, t02 = _jacobi_pair(w0, w2, v0, v2)
        w1, w2, v1, v2, t12 = _jacobi_pair(w1, w2, v1, v2)
        # Each rotation zeroes its pair's cosine; the later ones of a sweep bring back at most
        # the product of two tangents: below 1e-8 each, the sweep has converged to round-off.
        done = max(t01, t02, t12) < _CONVERGED_TANGENT

    # Sort columns by decreasing length; each swap negates one column so det V stays +1.
    n0, n1, n2 = dot(w0, w0), dot(w1, w1), dot(w2, w2)
    if n1 > n0:
        w0, w1, v0, v1, n0, n1 = w1, _negated(w0), v1, _negated(v0), n1, n0
    if n2 > n0:
        w0, w2, v0, v2, n0, n2 = w2, _negated(w0), v2, _negated(v0), n2, n0
    if n2 > n1:
        w1, w2, v1, v2, n1, n2 = w2, _negated(w1), v2, _negated(v1), n2, n1

    # W = F V / scale has orthogonal columns sigma_i u_i; build U as a rotation from them. The
    # iteration stops only with every cosine between columns at round-off (relative to both
    # lengths, however short), so u0 and u1 are the normalised columns, computed side by side.
    first = np.sqrt(n0)
    second = np.sqrt(n1)
    inverse_first = 1.0 / first
    u0 = (w0[0] * inverse_first, w0[1] * inverse_first, w0[2] * inverse_first)
    if second > _RANK_TOLERANCE * first:
        inverse_second = 1.0 / second
        u1 = (w1[0] * inverse_second, w1[1] * inverse_second, w1[2] * inverse_second)
    else:
        u1 = _unit_perpendicular(u0[0], u0[1], u0[2])
    u2 = cross(u0, u1)
    # Projecting onto u2 gives the last singular value its sign: negative iff det F < 0.
    third = dot(w2, u2)
    for i in range(3):
        U[i, 0] = u0[i]
        U[i, 1] = u1[i]
        U[i, 2] = u2[i]
        V[i, 0] = v0[i]
        V[i, 1] = v1[i]
        V[i, 2] = v2[i]
    sigma[0] = first * scale
    sigma[1] = second * scale
    sigma[2] = third * scale
    return sweeps, start


@compiled_only
def _polar_svd_3(F, U, sigma, V):
    _polar_svd_3_sweeps(F, U, sigma, V, True)


@compiled_only
def _polar_svd_2(F, U, sigma, V):
    a, b, c, d = F[0, 0], F[0, 1], F[1, 0], F[1, 1]
    # F = (E I + H J) + (G K + Q L) with J a quarter turn and K, L reflections; the first part is a
    # scaled rotation by angle phi, the second a scaled reflection about angle theta/2.
    E = 0.5 * (a + d)
    G = 0.5 * (a - d)
    H = 0.5 * (c - b)
    Q = 0.5 * (c + b)
    similarity = np.hypot(E, H)
    reflection = np.hypot(G, Q)
    phi = np.arctan2(H, E)
    theta = np.arctan2(Q, G)
    left = 0.5 * (phi + theta)
    right = 0.5 * (theta - phi)
    first = similarity + reflection
    # det F = similarity^2 - reflection^2; dividing it by the first value avoids cancellation.
    second = (a * d - b * c) / first if first > 0.0 else 0.0
    cl, sl = np.cos(left), np.sin(left)
    cr, sr = np.cos(right), np.sin(right)
    U[0, 0], U[0, 1], U[1, 0], U[1, 1] = cl, -sl, sl, cl
    V[0, 0], V[0, 1], V[1, 0], V[1, 1] = cr, -sr, sr, cr
    sigma[0] = first
    sigma[1] = second


def polar_svd_point(F, d, U, sigma, V):
    """Polar SVD of one ``d×d`` matrix (d = 2 or 3), written into ``U``, ``sigma``, ``V``.

    In compiled code ``d`` is a compile-time literal: only that dimension's SVD is compiled.
    """
    _POLAR_SVD[d](F, U, sigma, V)


_POLAR_SVD = {2: _polar_svd_2, 3: _polar_svd_3}
dispatch_on_dimension(polar_svd_point, _POLAR_SVD)


@functools.cache
def _polar_svd_batch(d: int):
    """Return the compiled loop over a batch of ``d×d`` matrices.

    ``d`` is a captured integer, a literal inside, as in the batch loops of
    :mod:`~dolfinx_invertible.constitutive.pointwise`: a Python int argument would make numba
    type the loop again on every call before it finds the literal's compiled version.
    """

    def batch(F, U, sigma, V):
        for n in range(F.shape[0]):
            polar_svd_point(F[n], d, U[n], sigma[n], V[n])

    return python_callable(batch)


def polar_svd(F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Polar SVD of a batch of matrices.

    Parameters
    ----------
    F
        Array of shape ``(n, d, d)`` or ``(d, d)`` with ``d`` 2 or 3.

    Returns
    -------
    U, sigma, V
        Rotations ``U``, ``V`` (same shape as ``F``) and signed singular values ``sigma`` of shape
        ``(n, d)`` (or ``(d,)``) with ``F = U diag(sigma) Vᵀ``.
    """
    from dolfinx_invertible.constitutive.validation import as_deformation_gradients

    batch, single = as_deformation_gradients(F)
    U = np.empty_like(batch)
    V = np.empty_like(batch)
    sigma = np.empty(batch.shape[:2])
    _polar_svd_batch(batch.shape[1])(batch, U, sigma, V)
    if single:
        return U[0], sigma[0], V[0]
    return U, sigma, V
