"""Independent vectorised NumPy reference: Neo-Hookean with the C2 extension.

This module is the baseline a careful NumPy user would write for the material that
:mod:`dolfinx_invertible` evaluates with numba kernels. It shares no code with the package on
purpose: it exists to check the compiled kernels and to give the material benchmark
(``benchmarks/material.py``) something honest to compare against. Every operation works on a
whole batch at once (batched SVD, ``einsum``); the only Python loops run over iterations of the
root solver or over the at most three index pairs, never over points.

Maths (see ``docs/design.md``). With signed singular values ``sigma`` of ``F`` (polar
convention) the Neo-Hookean energy is

    Psi(s) = mu/2 (sum s_i^2 - d) - mu sum ln s_i + lam/2 (sum ln s_i)^2.

The C2 extension keeps ``Psi`` where ``J = prod(sigma) >= eps``. Below, with ``a = sigma - 1`` and
``t`` the smallest root in (0, 1) of ``prod(1 + t a_i) = eps``, the point ``q = 1 + t a`` lies on
``J = eps`` and the energy is the second-order Taylor expansion of ``Psi`` at ``q`` evaluated at
``sigma``. The stress is ``P = U diag(g) V^T`` and the tangent is assembled from the Hessian ``A``
in ``sigma`` and the pair terms ``a_ij``, ``b_ij`` as rank-one modes, which makes the SPD
projection a clamp of the mode eigenvalues.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "polar_svd",
    "neo_hookean_derivatives",
    "c2_root",
    "energy_sigma",
    "stress_sigma",
    "hessian_sigma",
    "energy",
    "stress",
    "tangent",
    "max_relative_difference",
]

# Below this relative gap between two singular values the divided difference
# (g_i - g_j)/(s_i - s_j) loses more digits to cancellation (~1e-16 / gap) than the symmetric limit
# 1/2 (H_ii + H_jj) - H_ij loses to truncation (~gap^2, as a_ij is even in the gap).
_EQUAL_SINGULAR_VALUES = 1e-6
# |s_i + s_j| is bounded from below by this (keeping its sign): the energy has a kink where two
# singular values cancel, and b_ij would otherwise blow up there. Kept tiny so the unprojected
# tangent stays the exact derivative everywhere except within 1e-12 of the kink.
_SUM_FLOOR = 1e-12


def polar_svd(F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed (polar) singular value decomposition of a batch of matrices.

    Parameters
    ----------
    F : numpy.ndarray
        Deformation gradients, shape ``(n, d, d)``.

    Returns
    -------
    U, sigma, V : numpy.ndarray
        ``F = U diag(sigma) V^T`` with ``U`` and ``V`` rotations (determinant +1), shapes
        ``(n, d, d)``, ``(n, d)``, ``(n, d, d)``. If ``det F < 0`` the singular value of smallest
        magnitude is negative, so at most one entry of ``sigma`` is negative.
    """
    U, sigma, V_transposed = np.linalg.svd(F)
    V = np.swapaxes(V_transposed, -1, -2).copy()
    # LAPACK sorts singular values in decreasing order, so the last one is the smallest; flipping
    # it together with a column of U (or V) turns a reflection into a rotation without changing F.
    reflect_u = np.linalg.det(U) < 0
    U[reflect_u, :, -1] *= -1.0
    sigma[reflect_u, -1] *= -1.0
    reflect_v = np.linalg.det(V) < 0
    V[reflect_v, :, -1] *= -1.0
    sigma[reflect_v, -1] *= -1.0
    return U, sigma, V


def _delta_tensors(dimension: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Kronecker deltas of order 2, 3 and 4 in ``dimension`` dimensions."""
    identity = np.eye(dimension)
    delta3 = np.einsum("ij,ik->ijk", identity, identity)
    delta4 = np.einsum("ij,ik,il->ijkl", identity, identity, identity)
    return identity, delta3, delta4


def neo_hookean_derivatives(s: np.ndarray, mu: float, lam: float, order: int) -> list:
    """Neo-Hookean energy and its derivatives in the singular values, up to ``order``.

    Parameters
    ----------
    s : numpy.ndarray
        Positive singular values, shape ``(n, d)``.
    mu, lam : float
        Lame parameters.
    order : int
        Highest derivative returned, 0 to 4.

    Returns
    -------
    list of numpy.ndarray
        ``[Psi, g, H, T3, T4][: order + 1]`` with shapes ``(n,)``, ``(n, d)``, ``(n, d, d)``,
        ``(n, d, d, d)``, ``(n, d, d, d, d)``.
    """
    dimension = s.shape[-1]
    identity, delta3, delta4 = _delta_tensors(dimension)
    log_j = np.sum(np.log(s), axis=-1)
    z = 1.0 / s
    z2 = z * z
    z3 = z2 * z
    results = [0.5 * mu * (np.sum(s * s, axis=-1) - dimension) - mu * log_j + 0.5 * lam * log_j**2]
    if order >= 1:
        results.append(mu * s - mu * z + lam * log_j[:, None] * z)
    if order >= 2:
        diagonal = mu + (mu - lam * log_j)[:, None] * z2
        results.append(
            np.einsum("ij,ni->nij", identity, diagonal) + lam * np.einsum("ni,nj->nij", z, z)
        )
    if order >= 3:
        # Only -mu ln J and lam/2 (ln J)^2 contribute beyond the Hessian; the latter couples
        # indices through products of z = 1/s, hence the symmetrised delta terms.
        cross = np.einsum("ni,nk->nik", z2, z)
        results.append(
            np.einsum("ijk,ni->nijk", delta3, 2.0 * (lam * log_j - mu)[:, None] * z3)
            - lam
            * (
                np.einsum("ij,nik->nijk", identity, cross)
                + np.einsum("ik,nij->nijk", identity, cross)
                + np.einsum("jk,nji->nijk", identity, cross)
            )
        )
    if order >= 4:
        # Outer products first, then one delta pattern each: einsum over four or five operands
        # at once is several times slower on large batches.
        cube_cross = np.einsum("ni,nl->nil", z3, z)
        square_cross = np.einsum("ni,nk->nik", z2, z2)
        results.append(
            np.einsum("ijkl,ni->nijkl", delta4, 6.0 * (mu - lam * log_j)[:, None] * z2 * z2)
            + 2.0
            * lam
            * (
                np.einsum("ijk,nil->nijkl", delta3, cube_cross)
                + np.einsum("ijl,nik->nijkl", delta3, cube_cross)
                + np.einsum("ikl,nij->nijkl", delta3, cube_cross)
                + np.einsum("jkl,nji->nijkl", delta3, cube_cross)
            )
            + lam
            * (
                np.einsum("ij,kl,nik->nijkl", identity, identity, square_cross)
                + np.einsum("ik,jl,nij->nijkl", identity, identity, square_cross)
                + np.einsum("il,jk,nij->nijkl", identity, identity, square_cross)
            )
        )
    return results


def _product_and_derivative(t: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``prod_i (1 + t a_i)`` and its derivative in ``t``, by the product rule (no division)."""
    factors = 1.0 + t[:, None] * a
    derivative = np.zeros_like(t)
    for i in range(a.shape[1]):
        others = np.delete(factors, i, axis=1)
        derivative += a[:, i] * np.prod(others, axis=1)
    return np.prod(factors, axis=1), derivative


def c2_root(a: np.ndarray, eps: float, max_iterations: int = 200) -> np.ndarray:
    """Smallest root ``t`` in (0, 1) of ``prod(1 + t a_i) = eps`` for points with ``J < eps``.

    Parameters
    ----------
    a : numpy.ndarray
        ``sigma - 1``, shape ``(n, d)``, for points with ``prod(sigma) < eps``.
    eps : float
        Threshold on ``J``, in (0, 1).
    max_iterations : int
        Cap on safeguarded Newton iterations (bisection alone needs about 55).

    Returns
    -------
    numpy.ndarray
        The roots, shape ``(n,)``.

    Notes
    -----
    While every factor ``1 + t a_i`` is positive, ``ln prod(1 + t a_i)`` is concave in ``t`` and
    starts at 0 > ln eps, so it crosses ln eps exactly once there. That crossing is the smallest
    root, bracketed by ``[0, min(1, t_zero)]`` where ``t_zero`` is the first factor's zero: at the
    upper end the product is either ``J < eps`` or 0. Newton steps that leave the bracket are
    replaced by bisection, so this converges for every point.
    """
    count = a.shape[0]
    with np.errstate(divide="ignore"):
        first_zero = np.where(a < 0.0, -1.0 / np.where(a < 0.0, a, -1.0), np.inf).min(axis=1)
    low = np.zeros(count)
    high = np.minimum(1.0, first_zero)
    t = 0.5 * high
    for _ in range(max_iterations):
        product, derivative = _product_and_derivative(t, a)
        residual = product - eps
        low = np.where(residual > 0.0, t, low)
        high = np.where(residual < 0.0, t, high)
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = t - residual / derivative
        inside = np.isfinite(newton) & (newton > low) & (newton < high)
        t_new = np.where(residual == 0.0, t, np.where(inside, newton, 0.5 * (low + high)))
        change = np.max(np.abs(t_new - t), initial=0.0)
        t = t_new
        # t is in (0, 1), so an absolute step of a few ulps of 1 means converged.
        if change <= 4.0 * np.finfo(float).eps:
            break
    return t


def _c2_sigma(
    sigma: np.ndarray, mu: float, lam: float, eps: float, order: int
) -> tuple[np.ndarray, ...]:
    """Return extended energy and, up to ``order``, its gradient and Hessian in ``sigma``.

    Notes
    -----
    Below the threshold, with ``e = sigma - q``, ``Q = dq/dsigma = t I + a (grad t)^T`` and
    ``c = T3[e, e, .]`` (derivatives of ``Psi`` taken at ``q``)::

        grad = g + H e + 1/2 Q^T c
        Hess = H + T3[e] Q + Q^T T3[e] - Q^T T3[e] Q + 1/2 Q^T T4[e, e] Q
               + 1/2 (c (grad t)^T + (grad t) c^T + (a . c) Hess t)

    Moving the expansion point ``q`` changes the Taylor polynomial only through its remainder,
    which is why nothing but third and fourth derivatives contracted with ``e`` appears. ``t`` is
    differentiated implicitly through ``sum ln(1 + t a_i) = ln eps``. All of this is checked
    against finite differences in ``tests/test_numpy_reference.py``.
    """
    if not 0.0 < eps < 1.0:
        raise ValueError(f"eps must lie in (0, 1), got {eps}")
    count, dimension = sigma.shape
    energy_values = np.empty(count)
    gradient = np.empty((count, dimension))
    hessian = np.empty((count, dimension, dimension))

    plain = np.prod(sigma, axis=1) >= eps
    plain_results = neo_hookean_derivatives(sigma[plain], mu, lam, order)
    energy_values[plain] = plain_results[0]
    if order >= 1:
        gradient[plain] = plain_results[1]
    if order >= 2:
        hessian[plain] = plain_results[2]

    extended = ~plain
    if np.any(extended):
        a = sigma[extended] - 1.0
        t = c2_root(a, eps)
        q = 1.0 + t[:, None] * a
        offset = (1.0 - t)[:, None] * a  # sigma - q
        derivatives = neo_hookean_derivatives(q, mu, lam, order + 2)
        psi_q, g_q, h_q = derivatives[:3]
        h_offset = np.einsum("nij,nj->ni", h_q, offset)
        energy_values[extended] = (
            psi_q
            + np.einsum("ni,ni->n", g_q, offset)
            + 0.5 * np.einsum("ni,ni->n", offset, h_offset)
        )
        if order >= 1:
            t3_offset = np.einsum("nijk,ni->njk", derivatives[3], offset)  # T3[e, ., .]
            t3_offset2 = np.einsum("njk,nj->nk", t3_offset, offset)  # T3[e, e, .]
            # Implicit differentiation of h(t, sigma) = sum ln(1 + t a_i) - ln eps = 0.
            z = 1.0 / q
            h_t = np.einsum("ni,ni->n", a, z)
            t_gradient = -t[:, None] * z / h_t[:, None]
            # dq/dsigma = t I + a (grad t)^T; the Taylor form's dependence on q reduces to
            # 1/2 T3[e, e, .] pulled back through dq/dsigma.
            q_jacobian = np.einsum("n,ij->nij", t, np.eye(dimension)) + np.einsum(
                "ni,nj->nij", a, t_gradient
            )
            gradient[extended] = (
                g_q + h_offset + 0.5 * np.einsum("nji,nj->ni", q_jacobian, t3_offset2)
            )
        if order >= 2:
            t4_offset2 = np.einsum("nijkl,ni,nj->nkl", derivatives[4], offset, offset)
            h_tt = -np.einsum("ni,ni->n", a * a, z * z)
            h_t_sigma = z * z
            h_sigma_sigma = -np.einsum("n,ij,ni->nij", t * t, np.eye(dimension), z * z)
            t_hessian = (
                -(
                    h_sigma_sigma
                    + np.einsum("ni,nj->nij", h_t_sigma, t_gradient)
                    + np.einsum("ni,nj->nij", t_gradient, h_t_sigma)
                    + h_tt[:, None, None] * np.einsum("ni,nj->nij", t_gradient, t_gradient)
                )
                / h_t[:, None, None]
            )
            t3_q = np.einsum("nij,njk->nik", t3_offset, q_jacobian)
            a_dot_t3 = np.einsum("ni,ni->n", a, t3_offset2)
            hessian[extended] = (
                h_q
                + t3_q
                + np.swapaxes(t3_q, 1, 2)
                - np.einsum("nji,njk->nik", q_jacobian, t3_q)
                + 0.5 * np.einsum("nji,njk,nkl->nil", q_jacobian, t4_offset2, q_jacobian)
                + 0.5
                * (
                    np.einsum("ni,nj->nij", t3_offset2, t_gradient)
                    + np.einsum("ni,nj->nij", t_gradient, t3_offset2)
                    + a_dot_t3[:, None, None] * t_hessian
                )
            )
    return energy_values, gradient, hessian


def _check_sigma(sigma: np.ndarray) -> np.ndarray:
    sigma = np.asarray(sigma, dtype=float)
    if sigma.ndim != 2 or sigma.shape[1] not in (2, 3):
        raise ValueError(f"sigma must have shape (n, d) with d in {{2, 3}}, got {sigma.shape}")
    return sigma


def _check_deformation(F: np.ndarray) -> np.ndarray:
    F = np.asarray(F, dtype=float)
    if F.ndim != 3 or F.shape[1] != F.shape[2] or F.shape[1] not in (2, 3):
        raise ValueError(f"F must have shape (n, d, d) with d in {{2, 3}}, got {F.shape}")
    return F


def energy_sigma(sigma: np.ndarray, mu: float, lam: float, eps: float) -> np.ndarray:
    """Return the extended energy ``Psi_ext(sigma)`` (n,) of signed singular values (n, d)."""
    return _c2_sigma(_check_sigma(sigma), mu, lam, eps, order=0)[0]


def stress_sigma(sigma: np.ndarray, mu: float, lam: float, eps: float) -> np.ndarray:
    """Gradient of ``Psi_ext`` in ``sigma``, shape ``(n, d)``."""
    return _c2_sigma(_check_sigma(sigma), mu, lam, eps, order=1)[1]


def hessian_sigma(sigma: np.ndarray, mu: float, lam: float, eps: float) -> np.ndarray:
    """Hessian of ``Psi_ext`` in ``sigma`` (unprojected), shape ``(n, d, d)``."""
    return _c2_sigma(_check_sigma(sigma), mu, lam, eps, order=2)[2]


def energy(F: np.ndarray, mu: float, lam: float, eps: float) -> np.ndarray:
    """Energy density of Neo-Hookean with the C2 extension.

    Parameters
    ----------
    F : numpy.ndarray
        Deformation gradients, shape ``(n, d, d)`` with d = 2 or 3.
    mu, lam : float
        Lame parameters.
    eps : float
        C2 threshold on ``J``, in (0, 1).

    Returns
    -------
    numpy.ndarray
        ``Psi_ext``, shape ``(n,)``.
    """
    _, sigma, _ = polar_svd(_check_deformation(F))
    return _c2_sigma(sigma, mu, lam, eps, order=0)[0]


def stress(F: np.ndarray, mu: float, lam: float, eps: float) -> np.ndarray:
    """First Piola-Kirchhoff stress ``P = dPsi_ext/dF``, shape ``(n, d, d)``.

    Parameters are as for :func:`energy`.
    """
    U, sigma, V = polar_svd(_check_deformation(F))
    gradient = _c2_sigma(sigma, mu, lam, eps, order=1)[1]
    return np.einsum("nik,nk,njk->nij", U, gradient, V)


def tangent(F: np.ndarray, mu: float, lam: float, eps: float, project: bool = True) -> np.ndarray:
    """Tangent ``dP/dF``, optionally projected onto the symmetric positive semi-definite cone.

    Parameters
    ----------
    F : numpy.ndarray
        Deformation gradients, shape ``(n, d, d)`` with d = 2 or 3.
    mu, lam : float
        Lame parameters.
    eps : float
        C2 threshold on ``J``, in (0, 1).
    project : bool
        Clamp the eigenvalues of every mode at 0; ``False`` gives the exact derivative of
        :func:`stress`.

    Returns
    -------
    numpy.ndarray
        Shape ``(n, d*d, d*d)``; row ``i*d + j`` is ``P_ij``, column ``k*d + l`` is ``F_kl``.
    """
    U, sigma, V = polar_svd(_check_deformation(F))
    count, dimension = sigma.shape
    _, gradient, hessian = _c2_sigma(sigma, mu, lam, eps, order=2)

    # Diagonal block: eigen-modes of the Hessian in sigma, D_m = diag(v_m).
    eigenvalues, eigenvectors = np.linalg.eigh(hessian)
    modes = [np.einsum("nik,nkm,njk->nmij", U, eigenvectors, V)]
    mode_values = [eigenvalues]

    # Off-diagonal 2x2 blocks: a_ij acts on the symmetric, b_ij on the antisymmetric combination.
    for i in range(dimension):
        for j in range(i + 1, dimension):
            difference = sigma[:, i] - sigma[:, j]
            scale = np.maximum(np.abs(sigma[:, i]), np.abs(sigma[:, j]))
            nearly_equal = np.abs(difference) <= _EQUAL_SINGULAR_VALUES * scale
            limit = 0.5 * (hessian[:, i, i] + hessian[:, j, j]) - hessian[:, i, j]
            divided = (gradient[:, i] - gradient[:, j]) / np.where(nearly_equal, 1.0, difference)
            a_pair = np.where(nearly_equal, limit, divided)
            total = sigma[:, i] + sigma[:, j]
            bounded = np.where(
                np.abs(total) < _SUM_FLOOR, np.where(total < 0.0, -_SUM_FLOOR, _SUM_FLOOR), total
            )
            b_pair = (gradient[:, i] + gradient[:, j]) / bounded
            outer_ij = np.einsum("ni,nj->nij", U[:, :, i], V[:, :, j])
            outer_ji = np.einsum("ni,nj->nij", U[:, :, j], V[:, :, i])
            modes.append(((outer_ij + outer_ji) / np.sqrt(2.0))[:, None])
            modes.append(((outer_ij - outer_ji) / np.sqrt(2.0))[:, None])
            mode_values += [a_pair[:, None], b_pair[:, None]]

    vectors = np.concatenate(modes, axis=1).reshape(count, dimension**2, dimension**2)
    values = np.concatenate(mode_values, axis=1)
    if project:
        values = np.maximum(values, 0.0)
    # sum_m values_m vec(M_m) vec(M_m)^T, with the modes stacked as rows of `vectors`.
    return np.matmul(np.swapaxes(vectors, 1, 2) * values[:, None, :], vectors)


def max_relative_difference(result: np.ndarray, reference: np.ndarray) -> float:
    """Largest difference relative to the size of the reference, point by point.

    Each point's difference is divided by the largest absolute entry of that point's reference
    (at least 1e-300), so entries that happen to be near zero do not inflate the measure.

    Parameters
    ----------
    result, reference : numpy.ndarray
        Arrays of equal shape whose first axis runs over points.

    Returns
    -------
    float
        ``max_n max|result_n - reference_n| / max|reference_n|``; ``inf`` if shapes differ or
        any entry is not finite.
    """
    result = np.asarray(result, dtype=float)
    reference = np.asarray(reference, dtype=float)
    if result.shape != reference.shape:
        return float("inf")
    if not (np.all(np.isfinite(result)) and np.all(np.isfinite(reference))):
        return float("inf")
    if result.size == 0:
        return 0.0
    count = reference.shape[0]
    difference = np.abs(result - reference).reshape(count, -1).max(axis=1)
    scale = np.maximum(np.abs(reference).reshape(count, -1).max(axis=1), 1e-300)
    return float(np.max(difference / scale))
