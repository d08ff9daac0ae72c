"""Polar singular value decomposition of 2×2 and 3×3 matrices.

``F = U diag(sigma) Vᵀ`` with ``U`` and ``V`` proper rotations (det +1). When det F < 0 the
singular value of smallest magnitude carries the sign (the "invertible finite element"
convention of Irving et al. 2004), so at most one entry of ``sigma`` is negative and
``|sigma|`` is sorted in decreasing order.

The decomposition is a one-sided (Hestenes) Jacobi iteration on the columns of ``F``: it works
on ``F`` itself rather than ``FᵀF``, so small singular values keep their relative accuracy, and
it needs no allocation. ``U`` is completed with cross products, which makes it a rotation even
when ``F`` is rank deficient.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["polar_svd", "polar_svd_point"]

# Columns whose cosine is below this count as orthogonal (a few ulps).
_ORTHOGONALITY_TOLERANCE = 1e-15
_MAX_SWEEPS = 12
# Below this |γ/(β − α)| a rotation takes the small-angle formulas (truncation error 2τ⁴ < 1e-17).
_SMALL_ANGLE = 5e-5
# A sweep whose rotations all have |tan θ| below this leaves cosines of round-off size.
_CONVERGED_TANGENT = 1e-8
# A column this much shorter than the longest carries no direction information.
_RANK_TOLERANCE = 1e-13


@numba.njit(cache=True)
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


@numba.njit(cache=True)
def _dot(x, y):
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]


@numba.njit(cache=True)
def _jacobi_pair(wp, wq, vp, vq):
    """Rotate columns p, q of W (and of V alongside) so that they become orthogonal.

    Columns are tuples so that the whole iteration stays in registers. Returns the new columns
    and |tan θ| of the rotation (0 when the pair was already orthogonal).
    """
    alpha = _dot(wp, wp)
    beta = _dot(wq, wq)
    gamma = _dot(wp, wq)
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


@numba.njit(cache=True)
def _negated(x):
    return (-x[0], -x[1], -x[2])


@numba.njit(cache=True)
def _polar_svd_3(F, U, sigma, V):
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
        return
    # Scaling by the largest entry keeps squared column norms far from overflow and underflow.
    inverse_scale = 1.0 / scale
    w0 = (F[0, 0] * inverse_scale, F[1, 0] * inverse_scale, F[2, 0] * inverse_scale)
    w1 = (F[0, 1] * inverse_scale, F[1, 1] * inverse_scale, F[2, 1] * inverse_scale)
    w2 = (F[0, 2] * inverse_scale, F[1, 2] * inverse_scale, F[2, 2] * inverse_scale)
    v0 = (1.0, 0.0, 0.0)
    v1 = (0.0, 1.0, 0.0)
    v2 = (0.0, 0.0, 1.0)
    for _ in range(_MAX_SWEEPS):
        w0, w1, v0, v1, t01 = _jacobi_pair(w0, w1, v0, v1)
        w0, w2, v0, v2, t02 = _jacobi_pair(w0, w2, v0, v2)
        w1, w2, v1, v2, t12 = _jacobi_pair(w1, w2, v1, v2)
        # Each rotation zeroes its pair's cosine; the later ones of a sweep bring back at most
        # the product of two tangents: below 1e-8 each, the sweep has converged to round-off.
        if max(t01, t02, t12) < _CONVERGED_TANGENT:
            break

    # Sort columns by decreasing length; each swap negates one column so det V stays +1.
    n0, n1, n2 = _dot(w0, w0), _dot(w1, w1), _dot(w2, w2)
    if n1 > n0:
        w0, w1, v0, v1, n0, n1 = w1, _negated(w0), v1, _negated(v0), n1, n0
    if n2 > n0:
        w0, w2, v0, v2, n0, n2 = w2, _negated(w0), v2, _negated(v0), n2, n0
    if n2 > n1:
        w1, w2, v1, v2, n1, n2 = w2, _negated(w1), v2, _negated(v1), n2, n1

    # W = F V / scale has orthogonal columns sigma_i u_i; build U as a rotation from them.
    first = np.sqrt(n0)
    inverse_first = 1.0 / first
    u0 = (w0[0] * inverse_first, w0[1] * inverse_first, w0[2] * inverse_first)
    # Re-orthogonalise the second column against the first before normalising it.
    projection = _dot(w1, u0)
    x = (w1[0] - projection * u0[0], w1[1] - projection * u0[1], w1[2] - projection * u0[2])
    second = np.sqrt(_dot(x, x))
    if second > _RANK_TOLERANCE * first:
        inverse_second = 1.0 / second
        u1 = (x[0] * inverse_second, x[1] * inverse_second, x[2] * inverse_second)
    else:
        u1 = _unit_perpendicular(u0[0], u0[1], u0[2])
    u2 = (
        u0[1] * u1[2] - u0[2] * u1[1],
        u0[2] * u1[0] - u0[0] * u1[2],
        u0[0] * u1[1] - u0[1] * u1[0],
    )
    # Projecting onto u2 gives the last singular value its sign: negative iff det F < 0.
    third = _dot(w2, u2)
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


@numba.njit(cache=True)
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


@numba.njit(cache=True)
def polar_svd_point(F, U, sigma, V):
    """Polar SVD of one ``d×d`` matrix (d = 2 or 3), written into ``U``, ``sigma``, ``V``."""
    if F.shape[0] == 2:
        _polar_svd_2(F, U, sigma, V)
    else:
        _polar_svd_3(F, U, sigma, V)


@numba.njit(cache=True)
def _polar_svd_batch(F, U, sigma, V):
    for n in range(F.shape[0]):
        polar_svd_point(F[n], U[n], sigma[n], V[n])


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
    _polar_svd_batch(batch, U, sigma, V)
    if single:
        return U[0], sigma[0], V[0]
    return U, sigma, V
