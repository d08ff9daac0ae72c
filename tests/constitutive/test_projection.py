"""Tangent symmetry and the SPD projection."""

import numpy as np
import pytest
from constitutive_helpers import (
    DIMS,
    ENERGY_EXTENSION_NAMES,
    EXTENSION_NAMES,
    LAM,
    MODEL_NAMES,
    MU,
    assert_rel_close,
    compiled_caller,
    make_material,
    matrices_with_sigma,
    model_lam,
    random_sigma,
    sigma_cases,
    sym_norm_rel,
)

import dolfinx_invertible as di

# Rounding in sums of d^2 rank-one terms of O(|T|): symmetric / PSD to a few ulp of |T|.
SYM_TOL = 1e-12
PSD_TOL = 1e-12
EXTENSIONS = ENERGY_EXTENSION_NAMES


def general_F(rng, model, ext, d):
    """Well separated samples of the extension plus unstructured random matrices."""
    F = [matrices_with_sigma(rng, sigma_cases(rng, model, ext, d))]
    G = np.eye(d) + 0.5 * rng.standard_normal((20, d, d))
    if model == "NeoHookean" and ext is None:
        G = G[np.linalg.det(G) > 1e-3]
    F.append(G)
    return np.concatenate(F)


def min_eig_rel(T):
    """Smallest eigenvalue relative to |T| (a projected tangent may legitimately be zero, e.g.
    StVK under strong compression, where every mode has negative stiffness)."""
    norm = np.maximum(np.linalg.norm(T, axis=(1, 2)), np.finfo(float).tiny)
    return np.linalg.eigvalsh(T)[:, 0] / norm


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSION_NAMES)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_projected_is_symmetric_psd(rng, model, ext, d):
    F = general_F(rng, model, ext, d)
    T = make_material(model, ext).tangent(F, project=True)
    assert T.shape == (F.shape[0], d * d, d * d)
    assert np.all(np.isfinite(T))
    asym = sym_norm_rel(T)
    assert np.all(asym <= SYM_TOL), asym.max()
    lam_min = min_eig_rel(T)
    assert np.all(lam_min >= -PSD_TOL), (lam_min.min(), F[np.argmin(lam_min)])


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSIONS)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_unprojected_is_symmetric(rng, model, ext, d):
    """It is the Hessian of the energy."""
    F = general_F(rng, model, ext, d)
    T = make_material(model, ext).tangent(F, project=False)
    assert np.all(np.isfinite(T))
    asym = sym_norm_rel(T)
    assert np.all(asym <= SYM_TOL), asym.max()


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSIONS)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_projection_changes_indefinite_tangents(rng, model, ext, d):
    """Where the unprojected tangent has a clearly negative eigenvalue, the two must differ."""
    F = general_F(rng, model, ext, d)
    m = make_material(model, ext)
    T0 = m.tangent(F, project=False)
    indefinite = min_eig_rel(T0) < -1e-6
    assert indefinite.sum() >= 1  # these energies are not convex: some samples must be indefinite
    T1 = m.tangent(F[indefinite], project=True)
    assert np.all(np.linalg.norm(T1 - T0[indefinite], axis=(1, 2)) > 0)


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSION_NAMES)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_projection_is_identity_on_psd(rng, model, ext, d):
    """Small pure stretches (all sigma in (1, 1.05)): every model has g > 0, a_ij > 0 and A close
    to 2 mu I + lam 1 1^T, so the exact tangent is already SPD and projection must not change it.
    """
    sig = random_sigma(rng, 30, d, 1.001, 1.05, min_gap=1e-3)
    F = matrices_with_sigma(rng, sig)
    m = make_material(model, ext)
    T0 = m.tangent(F, project=False)
    T1 = m.tangent(F, project=True)
    # premise of the test, itself a property of the correct tangent
    assert np.all(min_eig_rel(T0) > 0), min_eig_rel(T0).min()
    assert_rel_close(T1, T0, 1e-12, MU + LAM, f"{model}+{ext} {d}D projected vs exact")


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", MODEL_NAMES)
@pytest.mark.extensions(None)
def test_projection_near_identity_general(rng, model, d):
    """Random small strains (rotations included): wherever the exact tangent is SPD, projection
    leaves it alone; and some samples must be SPD for the test to mean anything."""
    n = 80
    F = matrices_with_sigma(rng, np.ones((n, d))) + 1e-3 * rng.standard_normal((n, d, d))
    m = make_material(model)
    T0 = m.tangent(F, project=False)
    T1 = m.tangent(F, project=True)
    spd = min_eig_rel(T0) > 1e-10
    assert spd.sum() >= 1
    assert_rel_close(T1[spd], T0[spd], 1e-10, MU + LAM, f"{model} {d}D near identity")


def _fast_path_tangent(material, d):
    """A compiled loop over point_tangent that also reports which points took the SVD."""
    import numba

    from dolfinx_invertible.constitutive import workspace as ws
    from dolfinx_invertible.constitutive.pointwise import point_tangent
    from dolfinx_invertible.constitutive.svd_path import svd_path_address

    model_id, extension_id = material.model.model_id, material.extension_id

    def loop(F, params, positive_only, svd_path, C, through_svd):
        work = ws.new_workspace(ws.stack_buffer())
        P = np.empty((d, d))
        for n in range(F.shape[0]):
            _, _, through_svd[n] = point_tangent(
                F[n], d, model_id, extension_id, positive_only, params, True, svd_path, work, P,
                C[n],
            )  # fmt: skip

    compiled = numba.njit(loop)
    svd_path = svd_path_address(model_id, extension_id, d)
    return lambda F, params, positive_only, C, through_svd: compiled(
        F, params, positive_only, svd_path, C, through_svd
    )


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", ["NeoHookean", "StableNeoHookean"])
@pytest.mark.extensions("C2")
def test_near_rest_projection_skips_the_svd(rng, model, d):
    """Near rest the exact tangent is indefinite only in its twist (rotational) modes, under
    compressive stress, or merely semidefinite at P = 0. The fast path projects that block
    without an SVD and accepts the result by a tolerance-aware factorisation: it must equal
    the Frobenius-nearest positive semidefinite matrix (eigenvalues of the exact tangent
    clamped at 0) and take the SVD for none of the points."""
    n = 200
    F = np.eye(d) + 0.01 * rng.standard_normal((n, d, d))
    F = np.concatenate([F, matrices_with_sigma(rng, np.ones((20, d)))])  # P = 0 exactly
    m = make_material(model, "C2")
    exact = m.tangent(F, project=False)
    w, Q = np.linalg.eigh(exact)
    nearest = np.einsum("nij,nj,nkj->nik", Q, np.maximum(w, 0.0), Q)
    assert np.mean(w[:, 0] < -1e-8 * np.abs(w).max(axis=1)) > 0.2  # many are indefinite
    projected = np.empty_like(exact)
    through_svd = np.zeros(len(F), dtype=np.bool_)
    _fast_path_tangent(m, d)(F, m.parameters, m.positive_only, projected, through_svd)
    assert not through_svd.any(), np.flatnonzero(through_svd)
    assert_rel_close(projected, nearest, 1e-12, MU + LAM, f"{model} {d}D fast projection")
    assert_rel_close(m.tangent(F, project=True), nearest, 1e-12, MU + LAM, "batch API")


_INVARIANT_MODELS = ["NeoHookean", "StableNeoHookean", "StVK"]


def _spectral(model, F, exact, lam=None):
    """Run ``spectral_projection`` on each exact tangent; return the codes and the results."""
    import sys

    from dolfinx_invertible.constitutive.invariants import spectral_projection

    lam = model_lam(model) if lam is None else lam
    m = make_material(model)
    module = sys.modules[type(m.model).__module__]
    d = F.shape[1]
    codes = np.empty(len(F), dtype=int)
    result = exact.copy()
    for n, f in enumerate(F):
        C = f.T @ f
        I1, I2, J = np.trace(C), np.trace(C @ C), np.linalg.det(f)
        _, d1, d2, dJ = compiled_caller(module.invariant_terms)(I1, I2, J, d, MU, lam)
        curvature = compiled_caller(module.invariant_curvature)(I1, I2, J, d, MU, lam)
        codes[n] = compiled_caller(spectral_projection)(f, d, J, d1, d2, dJ, *curvature, result[n])
    return codes, result


def _clamped(T):
    w, Q = np.linalg.eigh(T)
    return np.einsum("nij,nj,nkj->nik", Q, np.maximum(w, 0.0), Q)


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", _INVARIANT_MODELS)
@pytest.mark.extensions(None)
def test_spectral_projection_each_twist_count(rng, model, d):
    """The SVD-free projection decides from σ (eigenvalues of FᵀF) and the invariant
    derivatives. Stretches spread around 1 give every number of negative twist stiffnesses
    (0 to 3 in 3D, 0 or 1 in 2D, each clamped by its own branch); every result must equal the
    eigenvalue clamp of the exact tangent, and no point may be left undecided."""
    n = 400
    sigma = np.exp(rng.uniform(-0.06, 0.04, (n, d)))
    F = matrices_with_sigma(rng, sigma)
    exact = make_material(model).tangent(F, project=False)
    codes, projected = _spectral(model, F, exact)
    counts = np.bincount(codes[codes >= 0], minlength=2 if d == 2 else 4)
    assert (codes >= 0).all(), np.flatnonzero(codes < 0)
    assert (counts >= 3).all(), counts
    assert_rel_close(projected, _clamped(exact), 1e-12, MU + LAM, f"{model} {d}D spectral")
    untouched = codes == 0
    np.testing.assert_array_equal(projected[untouched], exact[untouched])


@pytest.mark.parametrize("d", DIMS)
def test_spectral_projection_leaves_undecided_points_to_the_svd(rng, d):
    """A stretch stiffness that is negative (Neo-Hookean with λ = 25μ under volumetric tension,
    J = 2.8) or singular values too spread to take from FᵀF: the tangent is left untouched and
    the point goes to the SVD path."""
    stiff = di.Material(di.NeoHookean(mu=MU, lam=25 * MU))
    tension = matrices_with_sigma(rng, np.full((10, d), 2.8 ** (1.0 / d)))
    exact = stiff.tangent(tension, project=False)
    assert (np.linalg.eigvalsh(exact)[:, 0] < -1e-3 * MU).all()  # a negative stretch mode
    codes, result = _spectral("NeoHookean", tension, exact, lam=25 * MU)
    assert (codes == -1).all(), codes
    np.testing.assert_array_equal(result, exact)
    # Spread singular values, J = 0.98: the tangent is indefinite only in its twist modes.
    row = [[12.0, 0.98 / 12.0], [12.0, 0.5, 0.98 / 6.0]][d - 2]
    spread = matrices_with_sigma(rng, np.array([row] * 10))
    exact = make_material("NeoHookean").tangent(spread, project=False)
    codes, result = _spectral("NeoHookean", spread, exact)
    if d == 2:
        # 2D takes only σ₁ from FᵀF (σ₂ = J/σ₁): no spread is too wide.
        assert (codes == 1).all(), codes
        assert_rel_close(result, _clamped(exact), 1e-12, MU + LAM, "spread")
    else:
        assert (codes == -1).all(), codes
        np.testing.assert_array_equal(result, exact)


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", _INVARIANT_MODELS)
@pytest.mark.parametrize("lam", [0.1 * MU, LAM, 25.0 * MU])
@pytest.mark.extensions(None)
def test_spectral_projection_far_from_rest(rng, model, d, lam):
    """Singular values over e^±1.5 (inverted ones excluded: the fast path does not see them
    for these models with an extension): whatever the spectral test accepts must be the
    projected tangent, and it must accept a good share of them."""
    F = matrices_with_sigma(rng, np.exp(rng.uniform(-1.5, 1.5, (1500, d))))
    material = di.Material(getattr(di, model)(mu=MU, lam=lam))
    exact = material.tangent(F, project=False)
    codes, result = _spectral(model, F, exact, lam=lam)
    decided = codes >= 0
    assert decided.mean() > 0.05, decided.mean()
    assert_rel_close(result[decided], _clamped(exact[decided]), 1e-11, MU + lam, model)
    np.testing.assert_array_equal(result[~decided], exact[~decided])
