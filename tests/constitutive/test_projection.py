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
