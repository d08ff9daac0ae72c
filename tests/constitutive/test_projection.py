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
    make_material,
    matrices_with_sigma,
    random_sigma,
    sigma_cases,
    sym_norm_rel,
)

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


def _fast_path_tangent(material):
    """A compiled loop over point_tangent that also reports which points took the SVD."""
    import numba

    from dolfinx_invertible.constitutive import workspace as ws
    from dolfinx_invertible.constitutive.pointwise import point_tangent

    model_id, extension_id = material.model.model_id, material.extension_id

    def loop(F, params, positive_only, C, through_svd):
        work = ws.new_workspace(ws.stack_buffer())
        P = np.empty((F.shape[1], F.shape[1]))
        for n in range(F.shape[0]):
            _, _, through_svd[n] = point_tangent(
                F[n], model_id, extension_id, positive_only, params, True, work, P, C[n]
            )

    return numba.njit(loop)


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", ["NeoHookean", "StableNeoHookean"])
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
    _fast_path_tangent(m)(F, m.parameters, m.positive_only, projected, through_svd)
    assert not through_svd.any(), np.flatnonzero(through_svd)
    assert_rel_close(projected, nearest, 1e-12, MU + LAM, f"{model} {d}D fast projection")
    assert_rel_close(m.tangent(F, project=True), nearest, 1e-12, MU + LAM, "batch API")
