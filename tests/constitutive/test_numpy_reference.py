"""The numba material against the independent NumPy reference, and the reference against itself.

The reference (``numpy_reference.py`` beside this file) is first checked on its own: its stress,
Hessian and tangent must be finite differences of its energy and stress. Only then is it a fair
judge of the compiled :class:`dolfinx_invertible.Material`, which must agree with it to 1e-9
relative on random points in 2D and 3D, inverted ones and ones on both sides of J = eps included.
"""

from __future__ import annotations

import functools

import numpy as np
import numpy_reference as reference
import pytest
from constitutive_helpers import compiled_caller

from dolfinx_invertible import C2, Material, NeoHookean
from dolfinx_invertible.constitutive.extensions.c2 import threshold_parameter
from dolfinx_invertible.constitutive.polynomial import first_root_in_unit_interval

EPS = 0.9
# A compressible and a nearly incompressible parameter set (E = 1, nu = 0.3 and 0.45).
PARAMETERS = [(0.3846153846153846, 0.5769230769230769), (0.3448275862068966, 3.103448275862069)]
AGREEMENT = 1e-9
# Central differences with step 1e-6 are accurate to about 1e-9 relative here; 1e-6 leaves room
# while still catching any wrong term (those show up at 1e-2 or worse).
FINITE_DIFFERENCE = 1e-6
# The Hessian is continuous across J = EPS but its derivative jumps there, so a central difference
# of the stress that straddles the threshold is only first-order accurate (error ~ STEP).
STRADDLING_FINITE_DIFFERENCE = 1e-5
STEP = 1e-6


def _random_rotations(rng: np.random.Generator, count: int, dimension: int) -> np.ndarray:
    Q, R = np.linalg.qr(rng.standard_normal((count, dimension, dimension)))
    Q = Q * np.sign(np.diagonal(R, axis1=1, axis2=2))[:, None, :]
    Q[np.linalg.det(Q) < 0, :, 0] *= -1.0
    return Q


def sample_deformations(dimension: int, seed: int = 0) -> np.ndarray:
    """Random F: generic, inverted, J just above and below EPS, repeated singular values."""
    rng = np.random.default_rng(seed)
    generic = np.eye(dimension) + 0.35 * rng.standard_normal((120, dimension, dimension))
    reflection = np.eye(dimension)
    reflection[0, 0] = -1.0
    inverted = (np.eye(dimension) + 0.3 * rng.standard_normal((40, dimension, dimension))) @ (
        reflection
    )
    # J = EPS * (1 + offset) with offsets on both sides of the threshold, near and far.
    offsets = np.array([-0.3, -1e-3, -1e-6, 1e-6, 1e-3, 0.3])
    stretches = rng.uniform(0.6, 1.4, (offsets.size * 5, dimension))
    target = EPS * np.tile(1.0 + offsets, 5)
    stretches *= (target / np.prod(stretches, axis=1))[:, None] ** (1.0 / dimension)
    U = _random_rotations(rng, stretches.shape[0], dimension)
    V = _random_rotations(rng, stretches.shape[0], dimension)
    threshold = np.einsum("nik,nk,njk->nij", U, stretches, V)
    # Repeated singular values (the a_ij limit) on both sides of the threshold, plus inverted ones.
    if dimension == 2:
        repeated_stretches = np.array([[1.1, 1.1], [0.8, 0.8], [0.5, 0.5], [0.7, -0.4]])
    else:
        repeated_stretches = np.array(
            [[1.05, 1.05, 1.05], [0.5, 0.5, 0.5], [1.2, 1.2, 0.3], [0.9, 0.9, -0.5]]
        )
    U = _random_rotations(rng, repeated_stretches.shape[0], dimension)
    V = _random_rotations(rng, repeated_stretches.shape[0], dimension)
    repeated = np.einsum("nik,nk,njk->nij", U, repeated_stretches, V)
    F = np.concatenate([generic, inverted, threshold, repeated])
    assert np.any(np.linalg.det(F) < 0) and np.any(np.linalg.det(F) > EPS)
    return F


def _near_threshold(determinants: np.ndarray) -> np.ndarray:
    """Points whose finite-difference stencil may cross J = EPS."""
    near = np.abs(determinants / EPS - 1.0) < 1e-4
    assert np.any(near) and not np.all(near)
    return near


def _central_difference(function, x: np.ndarray) -> np.ndarray:
    """Derivative of a batched function (n, ...) -> (n, ...) in every entry of x (n, ...)."""
    count = x.shape[0]
    flat = x.reshape(count, -1)
    columns = []
    for index in range(flat.shape[1]):
        plus = flat.copy()
        minus = flat.copy()
        plus[:, index] += STEP
        minus[:, index] -= STEP
        difference = function(plus.reshape(x.shape)) - function(minus.reshape(x.shape))
        columns.append(difference.reshape(count, -1) / (2.0 * STEP))
    return np.stack(columns, axis=-1)


@pytest.mark.parametrize("dimension", [2, 3])
@pytest.mark.parametrize("mu, lam", PARAMETERS)
def test_reference_stress_is_derivative_of_energy(dimension, mu, lam):
    F = sample_deformations(dimension)
    stress = reference.stress(F, mu, lam, EPS)
    numerical = _central_difference(lambda G: reference.energy(G, mu, lam, EPS), F)
    assert reference.max_relative_difference(numerical.reshape(F.shape), stress) < (
        FINITE_DIFFERENCE
    )


@pytest.mark.parametrize("dimension", [2, 3])
@pytest.mark.parametrize("mu, lam", PARAMETERS)
def test_reference_tangent_is_derivative_of_stress(dimension, mu, lam):
    F = sample_deformations(dimension)
    tangent = reference.tangent(F, mu, lam, EPS, project=False)
    numerical = _central_difference(lambda G: reference.stress(G, mu, lam, EPS), F)
    near = _near_threshold(np.linalg.det(F))
    assert reference.max_relative_difference(numerical[~near], tangent[~near]) < FINITE_DIFFERENCE
    assert reference.max_relative_difference(numerical[near], tangent[near]) < (
        STRADDLING_FINITE_DIFFERENCE
    )
    projected = reference.tangent(F, mu, lam, EPS, project=True)
    scale = np.abs(projected).max(axis=(1, 2))
    assert np.all(np.linalg.eigvalsh(projected).min(axis=1) >= -1e-12 * scale)


@pytest.mark.parametrize("dimension", [2, 3])
def test_reference_sigma_derivatives(dimension):
    mu, lam = PARAMETERS[1]
    _, sigma, _ = reference.polar_svd(sample_deformations(dimension, seed=1))
    gradient = reference.stress_sigma(sigma, mu, lam, EPS)
    hessian = reference.hessian_sigma(sigma, mu, lam, EPS)
    numerical_gradient = _central_difference(
        lambda s: reference.energy_sigma(s, mu, lam, EPS)[:, None], sigma
    )[:, 0, :]
    numerical_hessian = _central_difference(
        lambda s: reference.stress_sigma(s, mu, lam, EPS), sigma
    )
    assert reference.max_relative_difference(numerical_gradient, gradient) < FINITE_DIFFERENCE
    near = _near_threshold(np.prod(sigma, axis=1))
    assert reference.max_relative_difference(numerical_hessian[~near], hessian[~near]) < (
        FINITE_DIFFERENCE
    )
    assert reference.max_relative_difference(numerical_hessian[near], hessian[near]) < (
        STRADDLING_FINITE_DIFFERENCE
    )


def test_reference_root_is_smallest_root():
    rng = np.random.default_rng(2)
    sigma = rng.uniform(-0.8, 1.5, (60, 3))
    sigma = sigma[np.prod(sigma, axis=1) < EPS]
    a = sigma - 1.0
    roots = reference.c2_root(a, EPS)
    for a_point, root in zip(a, roots):
        assert root == pytest.approx(_smallest_root(a_point, EPS), abs=1e-12)


def _smallest_root(a_point: np.ndarray, eps: float) -> float:
    # prod(1 + t a_i) - eps as a polynomial in t, highest power first.
    polynomial = functools.reduce(np.polymul, [[value, 1.0] for value in a_point])
    polynomial[-1] -= eps
    candidates = np.roots(polynomial)
    real = candidates[np.abs(candidates.imag) < 1e-9].real
    return float(np.min(real[(real > 0) & (real <= 1 + 1e-12)]))


@pytest.mark.parametrize("dimension", [2, 3])
def test_threshold_parameter_is_the_smallest_root(dimension):
    # Compressed, stretched-and-compressed (the cubic rises before it falls) and inverted points
    # (a factor crosses zero inside (0, 1), beyond which the cubic may rise again).
    rng = np.random.default_rng(5)
    sigma = rng.uniform(-0.8, 1.8, (400, dimension))
    sigma[:, 1:] = np.abs(sigma[:, 1:])  # at most one negative value, as the polar SVD gives
    sigma = sigma[np.prod(sigma, axis=1) < EPS]
    assert np.any(sigma < 0.0) and np.any(sigma > 1.2)
    threshold = compiled_caller(threshold_parameter)
    for point in sigma:
        a = point - 1.0
        s = threshold(a, EPS)
        assert s == pytest.approx(_smallest_root(a, EPS), rel=1e-13, abs=1e-15)
        assert np.prod(1.0 + s * a) == pytest.approx(EPS, rel=1e-14)


def _secant_on_the_maximum(stretch: float, middle: float) -> np.ndarray:
    """σ = (x, middle, 1 − stretch) whose cubic Π(1 + t aᵢ) − EPS peaks at the secant point.

    The root finder starts at the secant point of [0, 1]; where the cubic (rising, then
    falling) has its maximum there, Halley's step from it is zero without a root: the point a
    scatter at 24³ × 6 cells met (σ = (1.72459071, 1.31258886, 0.27332553), where C2's energy
    came out 368 instead of 659 and its stress 10⁹ instead of 10³).
    """

    def mismatch(first: float) -> float:
        a = np.array([first, middle, -stretch]) - np.array([1.0, 1.0, 0.0])
        c3, c2, c1, _ = functools.reduce(np.polymul, [[value, 1.0] for value in a])
        secant = (1.0 - EPS) / (1.0 - np.prod(1.0 + a))
        peak = max(np.roots([3.0 * c3, 2.0 * c2, c1]).real)
        return secant - peak

    # From a trace of 3 (the cubic peaks at 0, left of the secant point) to where the peak is
    # furthest right of it.
    low = 2.0 + stretch - middle
    candidates = np.linspace(low, EPS / (middle * (1.0 - stretch)), 200)[1:-1]
    high = candidates[np.argmin([mismatch(first) for first in candidates])]
    assert mismatch(low) > 0.0 > mismatch(high)
    for _ in range(100):
        centre = 0.5 * (low + high)
        low, high = (centre, high) if mismatch(centre) > 0.0 else (low, centre)
    return np.array([0.5 * (low + high), middle, 1.0 - stretch])


@pytest.mark.parametrize("stretch, middle", [(0.72667, 1.31259), (0.8, 1.2), (0.9, 1.6)])
def test_threshold_parameter_where_the_cubic_peaks_at_the_first_iterate(stretch, middle):
    threshold = compiled_caller(threshold_parameter)
    material = Material(NeoHookean(mu=345.0, lam=3103.0), extension=C2(eps=EPS))
    centre = _secant_on_the_maximum(stretch, middle)
    assert np.prod(centre) < EPS
    # A line through the point, finer than the band (1e-9 wide) where the old test stopped.
    offsets = np.linspace(-1e-7, 1e-7, 401)
    sigma = centre + offsets[:, None] * np.array([1.0, 0.3, -0.2])
    for point in sigma:
        s = threshold(point - 1.0, EPS)
        assert s == pytest.approx(_smallest_root(point - 1.0, EPS), rel=1e-12, abs=1e-15)
    # The energy is Lipschitz along the line with the stress as its constant.
    energy = material.energy_sigma(sigma)
    stress = np.linalg.norm(material.stress_sigma(sigma), axis=1)
    assert np.max(stress) < 1e4
    step = np.linalg.norm(sigma[1] - sigma[0])
    assert np.max(np.abs(np.diff(energy))) <= 2.0 * np.max(stress) * step + 1e-9


def test_first_root_in_unit_interval_is_the_first_crossing():
    # Cubics through three chosen roots, one to three of them in (0, 1], and c0 > 0: the line
    # search's volume caps, where the cubic may cross zero, turn back and cross again.
    rng = np.random.default_rng(6)
    first_root = compiled_caller(first_root_in_unit_interval)
    for _ in range(300):
        roots = rng.uniform(-0.5, 1.5, 3)
        scale = rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(-3, 3)
        c3, c2, c1, c0 = scale * np.poly(roots)
        if c0 <= 0.0:
            c3, c2, c1, c0 = -c3, -c2, -c1, -c0
        inside = np.sort(roots[(roots > 0.0) & (roots <= 1.0)])
        # Roots that touch zero without a sign change are not crossings: keep them apart.
        if len(inside) == 0 or np.min(np.abs(np.diff(np.sort(roots)))) < 1e-3:
            continue
        # The root is determined to the cubic's rounding error over its slope there.
        root = inside[0]
        slope = abs(c1 + root * (2.0 * c2 + 3.0 * root * c3))
        rounding = 8.0 * np.finfo(float).eps * (abs(c0) + abs(c1) + abs(c2) + abs(c3)) / slope
        assert abs(first_root(c0, c1, c2, c3) - root) <= rounding + 1e-15 * root


def test_reference_polar_svd():
    F = sample_deformations(3)
    U, sigma, V = reference.polar_svd(F)
    assert np.allclose(np.einsum("nik,nk,njk->nij", U, sigma, V), F, atol=1e-13)
    assert np.allclose(np.linalg.det(U), 1.0) and np.allclose(np.linalg.det(V), 1.0)
    assert np.all(np.sum(sigma < 0, axis=1) == (np.linalg.det(F) < 0))


@pytest.mark.parametrize("dimension", [2, 3])
@pytest.mark.parametrize("mu, lam", PARAMETERS)
def test_numba_matches_reference(dimension, mu, lam):
    F = sample_deformations(dimension, seed=3)
    material = Material(NeoHookean(mu=mu, lam=lam), extension=C2(eps=EPS))
    pairs = {
        "energy": (material.energy(F), reference.energy(F, mu, lam, EPS)),
        "stress": (material.stress(F), reference.stress(F, mu, lam, EPS)),
        "projected tangent": (
            material.tangent(F, project=True),
            reference.tangent(F, mu, lam, EPS, project=True),
        ),
        "exact tangent": (
            material.tangent(F, project=False),
            reference.tangent(F, mu, lam, EPS, project=False),
        ),
    }
    differences = {
        name: reference.max_relative_difference(numba_result, numpy_result)
        for name, (numba_result, numpy_result) in pairs.items()
    }
    assert all(value < AGREEMENT for value in differences.values()), differences


@pytest.mark.parametrize("dimension", [2, 3])
def test_numba_sigma_functions_match_reference(dimension):
    mu, lam = PARAMETERS[0]
    _, sigma, _ = reference.polar_svd(sample_deformations(dimension, seed=4))
    material = Material(NeoHookean(mu=mu, lam=lam), extension=C2(eps=EPS))
    differences = {
        "energy_sigma": reference.max_relative_difference(
            material.energy_sigma(sigma), reference.energy_sigma(sigma, mu, lam, EPS)
        ),
        "stress_sigma": reference.max_relative_difference(
            material.stress_sigma(sigma), reference.stress_sigma(sigma, mu, lam, EPS)
        ),
        "hessian_sigma": reference.max_relative_difference(
            material.hessian_sigma(sigma), reference.hessian_sigma(sigma, mu, lam, EPS)
        ),
    }
    assert all(value < AGREEMENT for value in differences.values()), differences
