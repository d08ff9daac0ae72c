"""Parameter and input validation, and the documented defaults."""

import re

import numpy as np
import pytest
from constitutive_helpers import (
    DIMS,
    EPS_C1,
    EXTENSION_NAMES,
    LAM,
    MODEL_NAMES,
    MU,
    make_extension,
    make_material,
    make_model,
    model_lam,
    random_sigma,
    youngs_modulus,
)

import dolfinx_invertible as di


@pytest.mark.parametrize("E,nu", [(1.0, 0.3), (210e9, 0.28), (5e3, 0.49), (3.0, -0.5), (7.0, 0.0)])
def test_lame(E, nu):
    mu, lam = di.lame(E, nu)
    np.testing.assert_allclose(mu, E / (2 * (1 + nu)), rtol=1e-14)
    np.testing.assert_allclose(lam, E * nu / ((1 + nu) * (1 - 2 * nu)), rtol=1e-14, atol=0)


def test_lame_round_trip():
    """The E used by the C1 default stiffness is the inverse of lame()."""
    mu, lam = di.lame(4.0, 0.3)
    np.testing.assert_allclose(youngs_modulus(mu, lam), 4.0, rtol=1e-14)


@pytest.mark.parametrize(
    "E,nu,name", [(1.0, 0.5, "nu"), (1.0, 0.7, "nu"), (1.0, -1.0, "nu"), (1.0, -1.5, "nu"),
                  (0.0, 0.3, "E"), (-1.0, 0.3, "E")],
)  # fmt: skip
def test_lame_rejects(E, nu, name):
    with pytest.raises(ValueError, match=rf"\b{name}\b"):
        di.lame(E, nu)


@pytest.mark.parametrize("mu", [0.0, -1.0])
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_model_rejects_mu(model, mu):
    with pytest.raises(ValueError, match=r"\bmu\b"):
        di.Material(make_model(model, mu=mu, lam=LAM))


@pytest.mark.parametrize("model", MODEL_NAMES)
def test_model_attributes(model):
    m = make_model(model)
    assert m.mu == MU
    assert m.lam == model_lam(model)


@pytest.mark.parametrize("eps", [0.0, 1.0, -0.2, 1.5])
@pytest.mark.parametrize("ext", [name for name in EXTENSION_NAMES if name is not None])
def test_extension_rejects_eps(ext, eps):
    with pytest.raises(ValueError, match=r"\beps\b"):
        di.Material(make_model("NeoHookean"), extension=make_extension(ext, eps=eps))


def test_c1_rejects_negative_k():
    with pytest.raises(ValueError, match=r"\bk\b"):
        di.Material(make_model("NeoHookean"), extension=di.C1(eps=EPS_C1, k=-1.0))


# ---------------------------------------------------------------------------------------------
# Input arrays
# ---------------------------------------------------------------------------------------------
def evaluators():
    m = make_material("NeoHookean", "C2")
    return {
        "energy": m.energy,
        "stress": m.stress,
        "tangent": m.tangent,
        "tangent_unprojected": lambda F: m.tangent(F, project=False),
        "polar_svd": di.polar_svd,
    }


EVALUATORS = ["energy", "stress", "tangent", "tangent_unprojected", "polar_svd"]


@pytest.mark.parametrize("shape", [(5, 3, 2), (5, 4, 4), (3,), (5, 1, 1), (2, 2, 3, 3), (4, 4)])
@pytest.mark.parametrize("func", EVALUATORS)
def test_wrong_shape(func, shape):
    F = np.ones(shape)
    with pytest.raises(ValueError) as info:
        evaluators()[func](F)
    # the offending shape appears in the message, e.g. "(5, 3, 2)"
    pattern = r"\D+".join(str(s) for s in shape)
    assert re.search(pattern, str(info.value)), str(info.value)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("func", EVALUATORS)
@pytest.mark.parametrize("d", DIMS)
def test_non_finite_entries(rng, func, d, bad):
    F = np.eye(d) + 0.1 * rng.standard_normal((20, d, d))
    F[13, d - 1, 0] = bad
    F[17, 0, d - 1] = bad
    with pytest.raises(ValueError) as info:
        evaluators()[func](F)
    msg = str(info.value)
    assert re.search(r"\b13\b", msg) and re.search(r"\b17\b", msg), msg


@pytest.mark.parametrize("d", DIMS)
def test_single_matrix(rng, d):
    m = make_material("FixedCorotated", "C1")
    F = np.eye(d) + 0.3 * rng.standard_normal((d, d))
    e, P, T = m.energy(F), m.stress(F), m.tangent(F)
    assert np.shape(e) == () and P.shape == (d, d) and T.shape == (d * d, d * d)
    np.testing.assert_array_equal(e, m.energy(F[None])[0])
    np.testing.assert_array_equal(P, m.stress(F[None])[0])
    np.testing.assert_array_equal(T, m.tangent(F[None])[0])


# ---------------------------------------------------------------------------------------------
# IFE has no energy
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("d", DIMS)
def test_ife_has_no_energy(d):
    assert issubclass(di.NoEnergyError, ValueError)
    m = make_material("NeoHookean", "IFE")
    with pytest.raises(di.NoEnergyError):
        m.energy(np.eye(d)[None])
    with pytest.raises(di.NoEnergyError):
        m.energy_sigma(np.ones((1, d)))
    assert np.all(np.isfinite(m.stress(np.eye(d)[None])))


# ---------------------------------------------------------------------------------------------
# C1 stiffness k: inside the extended region the energy is multilinear in each (sigma_i - eps)
# apart from k/2 (sigma_i - eps)^2, so d^2 Psi / d sigma_i^2 = k exactly there.
# ---------------------------------------------------------------------------------------------
def below_eps_sigma(rng, d, n=10):
    return random_sigma(rng, n, d, 0.02, 1.5, keep=lambda s: s[-1] < EPS_C1 - 0.05)


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", MODEL_NAMES)
@pytest.mark.extensions("C1")
def test_c1_default_k_is_20_E(rng, model, d):
    sig = below_eps_sigma(rng, d)
    H = make_material(model, "C1").hessian_sigma(sig)
    k = 20 * youngs_modulus(MU, model_lam(model))
    below = sig < EPS_C1
    np.testing.assert_allclose(np.diagonal(H, axis1=1, axis2=2)[below], k, rtol=1e-10)


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("k", [0.0, 3.5, 1e4])
def test_c1_explicit_k(rng, d, k):
    sig = below_eps_sigma(rng, d)
    H = make_material("StableNeoHookean", "C1", k=k).hessian_sigma(sig)
    below = sig < EPS_C1
    np.testing.assert_allclose(np.diagonal(H, axis1=1, axis2=2)[below], k, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", ["Corotated", "NeoHookean"])
@pytest.mark.extensions("C1")
def test_c1_default_k_energy_growth(model, d):
    """Deep below eps the penalty dominates: with sigma_d = eps - t the extended energy is
    Psi(q) - t dPsi(q) + k t^2 / 2, so its second difference in t is k t^2 with k = 20 E.
    The other singular values are larger still, so sigma stays in the polar convention (the
    negative entry has the smallest magnitude)."""
    m = make_material(model, "C1")
    t = 10.0
    sig = np.full((3, d), 25.0)
    sig[:, -1] = EPS_C1 - np.array([0.0, t, 2 * t])
    e = m.energy_sigma(sig)
    k_seen = (e[2] - 2 * e[1] + e[0]) / t**2
    np.testing.assert_allclose(k_seen, 20 * youngs_modulus(MU, LAM), rtol=1e-10)
    assert e[2] > e[1] > e[0]
