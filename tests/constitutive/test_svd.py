"""polar_svd: F = U diag(sigma) V^T with rotations U, V and signed sigma."""

from fractions import Fraction

import numba
import numpy as np
import pytest
from constitutive_helpers import compose, matrices_with_sigma, random_rotations, random_sigma

from dolfinx_invertible import polar_svd
from dolfinx_invertible.constitutive import svd as svd_module

# Backward-stable SVDs reconstruct F to a few ulp of |F|; 1e-12 leaves room for 3x3 Jacobi
# sweeps and the sign fix-up while still catching any real error (which would be O(1)).
RECON_RTOL = 1e-12
ORTHO_TOL = 1e-12


def check_polar_svd(F):
    """The contract's invariants; returns (U, sigma, V)."""
    return check_decomposition(F, *polar_svd(F))


def check_decomposition(F, U, sigma, V):
    """The contract's invariants for a given decomposition of F; returns (U, sigma, V)."""
    n, d, _ = F.shape
    assert U.shape == (n, d, d) and V.shape == (n, d, d) and sigma.shape == (n, d)
    assert np.all(np.isfinite(U)) and np.all(np.isfinite(V)) and np.all(np.isfinite(sigma))

    recon = compose(sigma, U, V)
    err = np.linalg.norm(recon - F, axis=(1, 2))
    assert np.all(err <= RECON_RTOL * np.linalg.norm(F, axis=(1, 2))), err

    eye = np.eye(d)
    for W, name in ((U, "U"), (V, "V")):
        ortho = np.linalg.norm(np.swapaxes(W, 1, 2) @ W - eye, axis=(1, 2))
        assert np.all(ortho <= ORTHO_TOL), (name, ortho)
        assert np.allclose(np.linalg.det(W), 1.0, atol=ORTHO_TOL), (name, np.linalg.det(W))

    mags = np.abs(sigma)
    scale = np.max(mags, axis=1, keepdims=True)
    tol = 1e-13 * scale
    # sorted by magnitude, descending
    assert np.all(np.diff(mags, axis=1) <= tol), sigma
    # at most one negative value, and it is (one of) the smallest in magnitude
    neg = sigma < 0
    assert np.all(neg.sum(axis=1) <= 1), sigma
    rows, cols = np.nonzero(neg)
    assert np.all(mags[rows, cols] <= mags[rows].min(axis=1) + tol[rows, 0]), sigma
    # the sign of prod(sigma) is the sign of det F
    detF = np.linalg.det(F)
    clear = np.abs(detF) > 1e-10 * scale[:, 0] ** d
    assert np.all(np.sign(np.prod(sigma, axis=1))[clear] == np.sign(detF)[clear]), sigma
    return U, sigma, V


def expected_sigma(sigma):
    """Signed singular values the contract prescribes for F = R1 diag(sigma) R2^T."""
    sigma = np.atleast_2d(sigma)
    mags = -np.sort(-np.abs(sigma), axis=1)
    flip = np.prod(np.sign(sigma), axis=1) < 0
    mags[flip, -1] *= -1
    return mags


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("inverted", [False, True])
def test_random(rng, d, inverted):
    F = rng.standard_normal((40, d, d))
    detF = np.linalg.det(F)
    F[(detF < 0) != inverted, :, 0] *= -1.0
    assert np.all((np.linalg.det(F) < 0) == inverted)
    _, sigma, _ = check_polar_svd(F)
    ref = np.linalg.svd(F, compute_uv=False)
    np.testing.assert_allclose(np.abs(sigma), ref, rtol=1e-12, atol=1e-14)
    assert np.all((sigma[:, -1] < 0) == inverted)


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("inverted", [False, True])
def test_prescribed_sigma(rng, d, inverted):
    sig = random_sigma(rng, 30, d, 0.1, 3.0, inverted=inverted, min_gap=1e-3)
    F = matrices_with_sigma(rng, sig)
    _, sigma, _ = check_polar_svd(F)
    np.testing.assert_allclose(sigma, sig, rtol=1e-12, atol=1e-13)


REPEATED_AND_SPECIAL = {
    "repeated_2_2_05": (2.0, 2.0, 0.5),
    "identity_rotated": (1.0, 1.0, 1.0),
    "isotropic_3": (3.0, 3.0, 3.0),
    "repeated_small": (1.5, 0.5, 0.5),
    "repeated_inverted": (2.0, 2.0, -0.5),
    "rank2": (2.0, 1.0, 0.0),
    "rank2_repeated": (1.0, 1.0, 0.0),
    "rank1": (3.0, 0.0, 0.0),
    "reflection": (1.0, 1.0, -1.0),
    "reflection_2d": (-1.0, 1.0),
    "repeated_2d": (2.0, 2.0),
    "rank1_2d": (2.0, 0.0),
    "inverted_2d": (1.5, -0.5),
}


@pytest.mark.parametrize("case", sorted(REPEATED_AND_SPECIAL))
@pytest.mark.parametrize("rotated", [False, True])
def test_special_singular_values(rng, case, rotated):
    sig = np.array(REPEATED_AND_SPECIAL[case], dtype=float)
    d = sig.size
    n = 20 if rotated else 1
    if rotated:
        F = matrices_with_sigma(rng, np.tile(sig, (n, 1)))
    else:
        F = np.diag(sig)[None]
    _, sigma, _ = check_polar_svd(F)
    expected = np.tile(expected_sigma(sig), (n, 1))
    # Order among equal magnitudes is free (check_polar_svd checks the ordering rules), and zero
    # singular values carry no sign: compare the sorted signed values with zeros made unsigned.
    tol = 1e-13 * np.max(np.abs(sig))
    got = np.where(np.abs(sigma) <= tol, 0.0, sigma)
    np.testing.assert_allclose(np.sort(got, axis=1), np.sort(expected, axis=1), atol=tol)
    assert d == F.shape[-1]


@pytest.mark.parametrize("d", [2, 3])
def test_zero_matrix(d):
    F = np.zeros((3, d, d))
    U, sigma, V = check_polar_svd(F)
    assert np.array_equal(sigma, np.zeros((3, d)))
    np.testing.assert_array_equal(U, np.broadcast_to(np.eye(d), U.shape))
    np.testing.assert_array_equal(V, np.broadcast_to(np.eye(d), V.shape))


# 1e-8 and 1e8 stay in the 3x3 routine's unscaled range of |F|² (1e-40 to 1e40), the others go
# through its scaling by the largest entry.
@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("scale", [1e-100, 1e-30, 1e-8, 1e8, 1e30, 1e100])
def test_scaled(rng, d, scale):
    """Relative accuracy does not depend on the magnitude of F."""
    sig = np.concatenate(
        [
            random_sigma(rng, 10, d, 0.2, 2.0, min_gap=1e-2),
            random_sigma(rng, 10, d, 0.2, 2.0, inverted=True, min_gap=1e-2),
        ]
    )
    F = matrices_with_sigma(rng, sig) * scale
    _, sigma, _ = check_polar_svd(F)
    np.testing.assert_allclose(sigma, sig * scale, rtol=1e-12)


def exact_det(F):
    """det of a 3x3 float matrix in exact rational arithmetic."""
    a = [[Fraction(float(x)) for x in row] for row in F]
    return (
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    )


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_small_singular_values_relative_accuracy(rng, sign):
    """diag(1, 1e-3, 1e-9) rotated: the tiny values must come out to 1e-6 relative accuracy.

    An SVD through eigenvalues of F^T F loses sigma_3 = 1e-9 completely (sigma_3^2 = 1e-18 is below
    the rounding of the O(1) entries). The reference for sigma_3 is |det F| of the *rounded* F,
    computed exactly, divided by sigma_1 sigma_2 (both well conditioned); so rounding in building F
    does not count against the implementation.
    """
    n = 20
    sig = np.tile([1.0, 1e-3, sign * 1e-9], (n, 1))
    F = compose(sig, random_rotations(rng, n, 3), random_rotations(rng, n, 3))
    _, sigma, _ = polar_svd(F)
    big = np.linalg.svd(F, compute_uv=False)[:, :2]
    ref3 = np.array([float(exact_det(f)) for f in F]) / (big[:, 0] * big[:, 1])
    np.testing.assert_allclose(sigma[:, :2], big, rtol=1e-9)
    np.testing.assert_allclose(sigma[:, 2], ref3, rtol=1e-6)
    np.testing.assert_allclose(sigma[:, 2], sign * 1e-9, rtol=1e-5)


@pytest.mark.parametrize("d", [2, 3])
def test_single_matrix(rng, d):
    F = rng.standard_normal((d, d))
    U, sigma, V = polar_svd(F)
    assert U.shape == (d, d) and sigma.shape == (d,) and V.shape == (d, d)
    np.testing.assert_allclose(U @ np.diag(sigma) @ V.T, F, atol=1e-13 * np.linalg.norm(F))


# --------------------------------------------------------------------------------------------
# The 3x3 paths: closed-form warm start (eigenvectors of F^T F), first-order sweep, and the
# Jacobi sweeps as fallback; the cold start (V = I, sweeps only) is the reference path.
# --------------------------------------------------------------------------------------------
@numba.njit(cache=False)
def _svd_3_paths(F, warm):
    n = F.shape[0]
    U = np.empty((n, 3, 3))
    V = np.empty((n, 3, 3))
    sigma = np.empty((n, 3))
    sweeps = np.empty(n, dtype=np.int64)
    starts = np.empty(n, dtype=np.int64)
    for i in range(n):
        sweeps[i], starts[i] = svd_module._polar_svd_3_sweeps(F[i], U[i], sigma[i], V[i], warm)
    return U, sigma, V, sweeps, starts


@numba.njit(cache=False)
def _warm_start_V(F):
    n = F.shape[0]
    V = np.empty((n, 3, 3))
    B = np.empty((n, 3, 3))
    for i in range(n):
        f = F[i]
        b0, b1, b2, v0, v1, v2, _ = svd_module._warm_start(
            (f[0, 0], f[1, 0], f[2, 0]), (f[0, 1], f[1, 1], f[2, 1]), (f[0, 2], f[1, 2], f[2, 2])
        )
        for k in range(3):
            B[i, k, 0], B[i, k, 1], B[i, k, 2] = b0[k], b1[k], b2[k]
            V[i, k, 0], V[i, k, 1], V[i, k, 2] = v0[k], v1[k], v2[k]
    return V, B


def _ensemble(rng, name, n=200):
    if name == "random":
        return rng.standard_normal((n, 3, 3))
    if name == "near rest":
        return 0.95 * np.eye(3) + 0.01 * rng.standard_normal((n, 3, 3))
    values = {
        "close pair": [2.0, 1.0 + 1e-7, 1.0],
        "tiny": [1.0, 1e-3, -1e-9],
        "rank 1": [3.0, 0.0, 0.0],
        "near isotropic": 1.0 + 1e-12 * rng.standard_normal((n, 3)),
        "wide": np.exp(rng.uniform(-12.0, 0.0, (n, 3))) * rng.choice([-1.0, 1.0], (n, 3)),
    }[name]
    sigma = np.broadcast_to(np.asarray(values, dtype=float), (n, 3))
    return compose(sigma, random_rotations(rng, n, 3), random_rotations(rng, n, 3))


ENSEMBLES = ["random", "near rest", "close pair", "tiny", "rank 1", "near isotropic", "wide"]


@pytest.mark.parametrize("name", ENSEMBLES)
def test_warm_start_agrees_with_cold_start(rng, name):
    """Both starts satisfy the contract and give the same singular values."""
    F = _ensemble(rng, name)
    U, sigma, V, _, _ = _svd_3_paths(F, True)
    check_decomposition(F, U, sigma, V)
    U0, sigma0, V0, _, _ = _svd_3_paths(F, False)
    check_decomposition(F, U0, sigma0, V0)
    scale = np.abs(sigma0[:, :1])
    np.testing.assert_allclose(sigma, sigma0, rtol=1e-12, atol=1e-15 * scale.max())
    # Each value to relative accuracy where it is far enough from round-off of the largest.
    big = np.abs(sigma0) > 1e-6 * scale
    np.testing.assert_allclose(sigma[big], sigma0[big], rtol=1e-9)
    ref = np.linalg.svd(F, compute_uv=False)
    np.testing.assert_allclose(np.abs(sigma), ref, rtol=1e-12, atol=1e-14 * scale.max())
    # Both paths are backward stable to a few ulps, tighter than the contract's 1e-12.
    for W, s, X in ((U, sigma, V), (U0, sigma0, V0)):
        err = np.linalg.norm(compose(s, W, X) - F, axis=(1, 2)) / np.linalg.norm(F, axis=(1, 2))
        assert err.max() < 1e-14, err.max()
        for Q in (W, X):
            assert np.abs(np.swapaxes(Q, 1, 2) @ Q - np.eye(3)).max() < 1e-14


def test_warm_start_needs_no_sweep(rng):
    """Separated singular values: the first-order sweep finishes what the cold start's sweeps do."""
    sig = random_sigma(rng, 200, 3, 0.2, 3.0, min_gap=1e-2)
    F = matrices_with_sigma(rng, sig)
    _, sigma, _, sweeps, starts = _svd_3_paths(F, True)
    assert np.all(sweeps == 0), np.bincount(sweeps)
    assert np.all(starts == svd_module.START_EIGENVECTORS)
    _, _, _, cold, _ = _svd_3_paths(F, False)
    # From V = I the first sweep's rotations are O(1) for these F, and only a sweep whose
    # tangents are all below 1e-8 ends the iteration: at least two sweeps.
    assert np.all(cold >= 2), np.bincount(cold)
    np.testing.assert_allclose(sigma, sig, rtol=1e-12)


def test_warm_start_falls_back_to_sweeps(rng):
    """All three values within 1e-12: the warm start is noise, sweeps finish; both paths occur."""
    F = _ensemble(rng, "near isotropic", 400)
    U, sigma, V, sweeps, _ = _svd_3_paths(F, True)
    assert np.any(sweeps == 0) and np.any(sweeps >= 1), np.bincount(sweeps)
    check_decomposition(F, U, sigma, V)
    np.testing.assert_allclose(sigma, np.linalg.svd(F, compute_uv=False), rtol=1e-12)


@pytest.mark.parametrize("c", [1.0, 2.5, -0.7])
def test_warm_start_isotropic_keeps_identity(rng, c):
    """F = c R: F^T F = c² I has no eigenvectors to find, and V stays I (the guard's branch).

    Up to the sort, which may reorder columns whose lengths differ by round-off: V is a signed
    permutation (a warm start from round-off would be a random rotation).
    """
    R = random_rotations(rng, 20, 3)
    F = c * R
    U, sigma, V, sweeps, starts = _svd_3_paths(F, True)
    assert np.all(sweeps == 0)
    assert np.all(starts == svd_module.START_IDENTITY)
    np.testing.assert_allclose(np.sort(np.abs(V), axis=2)[:, :, :2], 0.0, atol=1e-15)
    np.testing.assert_allclose(np.abs(sigma), abs(c), rtol=1e-14)
    check_decomposition(F, U, sigma, V)


def _assert_eigenvectors(F, V, tol, ordered):
    """V's columns are unit eigenvectors of F^T F (by decreasing eigenvalue if ``ordered``)."""
    _, vectors = np.linalg.eigh(np.swapaxes(F, 1, 2) @ F)
    vectors = vectors[:, :, ::-1]
    overlap = np.abs(np.einsum("nij,nik->njk", V, vectors))
    if ordered:
        np.testing.assert_allclose(np.diagonal(overlap, axis1=1, axis2=2), 1.0, atol=tol)
    else:
        np.testing.assert_allclose(overlap.max(axis=2), 1.0, atol=tol)
    np.testing.assert_allclose(np.linalg.det(V), 1.0, atol=1e-14)
    eye = np.broadcast_to(np.eye(3), V.shape)
    np.testing.assert_allclose(np.swapaxes(V, 1, 2) @ V, eye, atol=1e-14)


@pytest.mark.parametrize(
    "values, tol, ordered",
    [
        # Both ends well apart from the middle: each end's null vector, side by side (the
        # largest eigenvalue isolated, then the smallest), columns by decreasing eigenvalue.
        ((3.0, 1.0, 0.9), 1e-12, True),
        ((3.0, 2.9, 1.0), 1e-12, True),
        ((1.2, -1.0, 0.8), 1e-12, True),
        # A pair 1e-7 apart: the plane rotation next to the isolated eigenvector (the pair's end
        # by its null vector would be off by about 1e-7), the pair in either order.
        ((2.0, 1.0 + 1e-7, 1.0), 1e-8, False),
        ((2.0, 2.0 - 1e-7, 1.0), 1e-8, False),
    ],
)
def test_warm_start_eigenvectors(rng, values, tol, ordered):
    n = 50
    F = compose(np.tile(values, (n, 1)), random_rotations(rng, n, 3), random_rotations(rng, n, 3))
    V, B = _warm_start_V(F)
    _assert_eigenvectors(F, V, tol, ordered)
    np.testing.assert_allclose(B, F @ V, atol=1e-14 * np.abs(F).max())
    # Accurate enough that the first-order sweep finishes it.
    _, sigma, _, sweeps, starts = _svd_3_paths(F, True)
    assert np.all(sweeps == 0), np.bincount(sweeps)
    close = svd_module.START_CLOSE_PAIR
    assert np.all(starts == (svd_module.START_EIGENVECTORS if ordered else close))
    np.testing.assert_allclose(sigma, np.tile(expected_sigma(np.array(values)), (n, 1)), rtol=1e-12)


@pytest.mark.parametrize("pair", [(0, 1), (0, 2), (1, 2), None])
def test_warm_start_one_coupled_pair(rng, pair):
    """Columns orthogonal but for one pair (or none): one plane rotation, no eigenvectors.

    V is then a rotation in that pair's plane (the other column of V an axis, exactly).
    """
    n = 40
    F = np.zeros((n, 3, 3))
    F[:, [0, 1, 2], [0, 1, 2]] = rng.uniform(0.5, 2.0, (n, 3))
    if pair is not None:
        i, j = pair
        F[:, i, j] = rng.uniform(-0.3, 0.3, n)
        F[:, j, i] = rng.uniform(-0.3, 0.3, n)
    # Rotating the rows keeps the columns' dot products.
    F = random_rotations(rng, n, 3) @ F
    U, sigma, V, sweeps, starts = _svd_3_paths(F, True)
    assert np.all(starts == svd_module.START_ONE_PAIR)
    assert np.all(sweeps == 0)
    check_decomposition(F, U, sigma, V)
    np.testing.assert_allclose(np.abs(sigma), np.linalg.svd(F, compute_uv=False), rtol=1e-12)
    # The uncoupled axis stays a column of V (up to the sort's order and sign).
    axis = 2 if pair is None else ({0, 1, 2} - set(pair)).pop()
    assert np.all(np.max(np.abs(V[:, axis, :]), axis=1) == 1.0)
