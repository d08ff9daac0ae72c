"""Identity, degenerate and extreme deformation gradients."""

import numpy as np
import pytest
from constitutive_helpers import (
    DIMS,
    ENERGY_EXTENSION_NAMES,
    EXTENSION_NAMES,
    LAM,
    MODEL_NAMES,
    MU,
    make_material,
    matrices_with_sigma,
    model_lam,
    reference_energy,
)

EXTENSIONS = EXTENSION_NAMES


def special_sigmas(d):
    """identity, repeated stretch/compression, reflection, zero."""
    if d == 3:
        return [(1.0, 1.0, 1.0), (2.0, 2.0, 0.5), (1.0, 1.0, -1.0), (0.0, 0.0, 0.0)]
    return [(1.0, 1.0), (2.0, 0.5), (1.0, -1.0), (0.0, 0.0)]


def special_F(rng, d):
    """Each special matrix, plain diagonal and randomly rotated, times 1, 1e-8 and 1e8."""
    sig = np.array(special_sigmas(d))
    base = np.concatenate([np.array([np.diag(s) for s in sig]), matrices_with_sigma(rng, sig)])
    return np.concatenate([base * scale for scale in (1.0, 1e-8, 1e8)])


def elasticity_tensor(d, mu, lam):
    """dP/dF at F = I: mu (d_ik d_jl + d_il d_jk) + lam d_ij d_kl, rows ij, columns kl."""
    eye = np.eye(d)
    C = mu * (
        np.einsum("ik,jl->ijkl", eye, eye) + np.einsum("il,jk->ijkl", eye, eye)
    ) + lam * np.einsum("ij,kl->ijkl", eye, eye)
    return C.reshape(d * d, d * d)


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSIONS)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_identity_is_stress_free(rng, model, ext, d):
    m = make_material(model, ext)
    F = np.concatenate([np.eye(d)[None], matrices_with_sigma(rng, np.ones((5, d)))])
    P = m.stress(F)
    assert np.all(np.abs(P) <= 1e-13 * MU), np.abs(P).max()
    if ext != "IFE":
        e = m.energy(F)
        assert np.all(np.abs(e) <= 1e-13 * MU), e
    # at F = I exactly (at a rotation the tangent is the rotated tensor): linear elasticity
    C = elasticity_tensor(d, MU, model_lam(model))
    for project in (False, True):
        T = m.tangent(F[:1], project=project)
        err = np.abs(T - C).max()
        assert err <= 1e-12 * (MU + LAM), (project, err)


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", ENERGY_EXTENSION_NAMES)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_hessian_sigma_at_identity(model, ext, d):
    m = make_material(model, ext)
    H = m.hessian_sigma(np.ones((1, d)))
    expected = 2 * MU * np.eye(d) + model_lam(model) * np.ones((d, d))
    np.testing.assert_allclose(H[0], expected, rtol=0, atol=1e-12 * (MU + LAM))
    np.testing.assert_allclose(m.stress_sigma(np.ones((1, d))), 0.0, atol=1e-13 * MU)
    np.testing.assert_allclose(m.energy_sigma(np.ones((1, d))), 0.0, atol=1e-13 * MU)


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSIONS)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_special_matrices_finite(rng, model, ext, d):
    """No NaN/Inf for identity, diag(2,2,.5), reflections, zero, tiny and huge scales."""
    F = special_F(rng, d)
    if model == "NeoHookean" and ext is None:
        F = F[np.linalg.det(F) > 0]  # the plain model is undefined elsewhere (tested below)
    m = make_material(model, ext)
    n = F.shape[0]
    results = {"P": m.stress(F)}
    for project in (False, True):
        results[f"tangent(project={project})"] = m.tangent(F, project=project)
    if ext != "IFE":
        results["energy"] = m.energy(F)
    for name, r in results.items():
        assert r.shape[0] == n
        bad = np.flatnonzero(~np.all(np.isfinite(r.reshape(n, -1)), axis=1))
        assert bad.size == 0, (name, F[bad[:3]])


@pytest.mark.parametrize("d", DIMS)
def test_neohookean_c2_energy_at_zero_sigma(d):
    m = make_material("NeoHookean", "C2")
    z = np.zeros((2, d))
    z[1, -1] = -1e-300
    assert np.all(np.isfinite(m.energy_sigma(z)))
    assert np.all(np.isfinite(m.stress_sigma(z)))
    assert np.all(np.isfinite(m.hessian_sigma(z)))


@pytest.mark.parametrize("d", DIMS)
def test_plain_neohookean_inverted(rng, d):
    m = make_material("NeoHookean")
    sig = np.array([special_sigmas(d)[2], special_sigmas(d)[3], [0.5] * (d - 1) + [0.0]])
    # J = 0 only where it is exact: a rotated singular matrix is not singular after rounding
    F = np.concatenate([matrices_with_sigma(rng, sig[:1]), [np.diag(s) for s in sig]])
    e = m.energy(F)
    assert np.all(np.isposinf(e)), e
    assert np.all(np.isposinf(m.energy_sigma(sig))), m.energy_sigma(sig)
    # mixing valid and invalid points: the valid one keeps its value, the others are +inf
    G = np.concatenate([np.eye(d)[None] * 1.1, F])
    e = m.energy(G)
    np.testing.assert_allclose(e[0], reference_energy("NeoHookean", np.full((1, d), 1.1))[0])
    assert np.all(np.isposinf(e[1:]))
    for k in range(F.shape[0]):
        with pytest.raises(ValueError, match="J <= 0"):
            m.stress(F[k : k + 1])
        with pytest.raises(ValueError, match="J <= 0"):
            m.tangent(F[k : k + 1])


OVERFLOW_SCALES = (1e150, 1e200, 1e250, 1e300)


def overflow_F(rng, d):
    """Identity, a stretch, a rotated random F and an inverted one, each at every huge scale."""
    base = np.concatenate(
        [
            np.eye(d)[None],
            np.diag(np.linspace(2.0, 0.5, d))[None],
            matrices_with_sigma(rng, np.linspace(1.5, 0.7, d)[None]),
            matrices_with_sigma(rng, np.concatenate([np.ones(d - 1), [-0.5]])[None]),
        ]
    )
    return np.concatenate([base * scale for scale in OVERFLOW_SCALES])


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSIONS)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_huge_F_gives_no_nan(rng, model, ext, d):
    """Finite F of 1e150 to 1e300: energy finite or +inf; stress and tangent finite or a
    ValueError naming the points ("F too large"); never NaN."""
    F = overflow_F(rng, d)
    m = make_material(model, ext)
    if ext != "IFE":
        energy = m.energy(F)
        assert not np.any(np.isnan(energy)), energy
        assert np.all(np.isfinite(energy) | np.isposinf(energy)), energy
    defined = np.ones(len(F), dtype=bool)
    if model == "NeoHookean" and ext is None:
        defined = np.linalg.det(F / np.abs(F).max(axis=(1, 2), keepdims=True)) > 0
    for evaluate in (m.stress, lambda G: m.tangent(G, project=False), m.tangent):
        for k in np.flatnonzero(defined):
            try:
                value = evaluate(F[k : k + 1])
            except ValueError as error:
                assert "F too large" in str(error) and "first indices 0" in str(error), error
            else:
                assert np.all(np.isfinite(value)), (model, ext, k, value)


def test_overflow_error_names_the_points(rng):
    m = make_material("NeoHookean", "C2")
    F = np.concatenate([np.eye(3)[None] * 1.1, np.eye(3)[None] * 1e200, np.eye(3)[None]])
    with pytest.raises(ValueError, match=r"F too large: entries up to 1e\+200 .* first indices 1"):
        m.stress(F)
    with pytest.raises(ValueError, match="first indices 1"):
        m.tangent(F)
    energy = m.energy(F)
    assert np.isfinite(energy[0]) and np.isposinf(energy[1]) and energy[2] == 0.0
    assert np.isposinf(m.energy(1e200 * np.eye(3)))
