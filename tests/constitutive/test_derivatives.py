"""Stress = d energy / dF and unprojected tangent = d stress / dF, by central differences.

Step h = 1e-6 on O(1) entries: truncation error ~ h^2 |third derivative| and rounding error
~ 1e-16 |value| / h are both ~ 1e-10 relative for the well separated singular values used here,
so the 1e-5 relative tolerance has a wide margin while any missing term (they are O(1)) fails.
"""

import numpy as np
import pytest
from constitutive_helpers import (
    C1_REGION_SIGMAS,
    C2_SIGMAS,
    DIMS,
    ENERGY_EXTENSION_NAMES,
    EPS_C1,
    EPS_C2,
    LAM,
    MODEL_NAMES,
    MU,
    assert_rel_close,
    fd_jacobian,
    fd_stress,
    fd_tangent,
    jdet,
    jitter,
    make_material,
    matrices_with_sigma,
    random_sigma,
    sigma_cases,
    signed_svd,
    sym_norm_rel,
)

H = 1e-6
RTOL = 1e-5
STRESS_SCALE = MU
TANGENT_SCALE = MU + LAM
EXTENSIONS = ENERGY_EXTENSION_NAMES


def label(model, ext, d):
    return f"{model}+{ext} {d}D"


def check_stress(m, F, what):
    assert_rel_close(m.stress(F), fd_stress(m.energy, F, H), RTOL, STRESS_SCALE, what + " P")


def check_tangent(m, F, what):
    T = m.tangent(F, project=False)
    assert_rel_close(T, fd_tangent(m.stress, F, H), RTOL, TANGENT_SCALE, what + " dP/dF")


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSIONS)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_stress_is_energy_gradient(rng, model, ext, d):
    m = make_material(model, ext)
    F = matrices_with_sigma(rng, sigma_cases(rng, model, ext, d))
    check_stress(m, F, label(model, ext, d))


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSIONS)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_tangent_is_stress_derivative(rng, model, ext, d):
    m = make_material(model, ext)
    F = matrices_with_sigma(rng, sigma_cases(rng, model, ext, d))
    check_tangent(m, F, label(model, ext, d))


def c1_cases():
    return [(d, i) for d in DIMS for i in range(len(C1_REGION_SIGMAS[d]))]


@pytest.mark.parametrize("d,case", c1_cases())
@pytest.mark.parametrize("model", MODEL_NAMES)
@pytest.mark.extensions("C1")
def test_c1_every_region(rng, model, d, case):
    """0, 1, 2 (and 3) singular values below eps, with and without a negative one."""
    base = np.array(C1_REGION_SIGMAS[d][case])
    sig = jitter(rng, base, 4, 0.01)
    F = matrices_with_sigma(rng, sig)
    # the test's own premise: the region is the intended one for every sample
    _, s_ref, _ = signed_svd(F)
    assert np.all((s_ref < EPS_C1).sum(axis=1) == (base < EPS_C1).sum())
    m = make_material(model, "C1")
    what = f"{label(model, 'C1', d)} sigma~{base}"
    check_stress(m, F, what)
    check_tangent(m, F, what)


def c2_cases():
    return [(d, i) for d in DIMS for i in range(len(C2_SIGMAS[d]))]


@pytest.mark.parametrize("d,case", c2_cases())
@pytest.mark.parametrize("model", MODEL_NAMES)
@pytest.mark.extensions("C2")
def test_c2_both_sides_of_threshold(rng, model, d, case):
    """Points with J above and below eps = 0.9, down to strongly inverted ones."""
    base = np.array(C2_SIGMAS[d][case])
    sig = jitter(rng, base, 4, 0.003)
    assert np.all((jdet(sig) < EPS_C2) == (jdet(base) < EPS_C2))
    assert np.all(np.abs(jdet(sig) - EPS_C2) > 0.02)
    F = matrices_with_sigma(rng, sig)
    m = make_material(model, "C2")
    what = f"{label(model, 'C2', d)} sigma~{base} J~{jdet(base):.3f}"
    check_stress(m, F, what)
    check_tangent(m, F, what)


# ---------------------------------------------------------------------------------------------
# IFE: no energy; above the threshold it is the plain model
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", MODEL_NAMES)
@pytest.mark.extensions("IFE", None)
def test_ife_is_model_above_threshold(rng, model, d):
    sig = random_sigma(rng, 20, d, 0.6, 1.8, keep=lambda s: np.prod(s) > EPS_C2 + 1e-3)
    F = matrices_with_sigma(rng, sig)
    ife, plain = make_material(model, "IFE"), make_material(model)
    what = label(model, "IFE", d)
    assert_rel_close(ife.stress(F), plain.stress(F), 1e-12, STRESS_SCALE, what + " P")
    for project in (False, True):
        assert_rel_close(
            ife.tangent(F, project=project),
            plain.tangent(F, project=project),
            1e-12,
            TANGENT_SCALE,
            f"{what} tangent(project={project})",
        )


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", MODEL_NAMES)
@pytest.mark.extensions("IFE")
def test_ife_projected_tangent(rng, model, d):
    F = matrices_with_sigma(rng, sigma_cases(rng, model, "IFE", d))
    T = make_material(model, "IFE").tangent(F, project=True)
    assert np.all(np.isfinite(T))
    assert np.all(sym_norm_rel(T) <= 1e-12)
    norms = np.linalg.norm(T, axis=(1, 2))
    assert np.all(np.linalg.eigvalsh(T)[:, 0] >= -1e-12 * norms)


# ---------------------------------------------------------------------------------------------
# Diagonal space
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSIONS)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_stress_sigma_is_energy_sigma_gradient(rng, model, ext, d):
    m = make_material(model, ext)
    sig = sigma_cases(rng, model, ext, d)
    g_fd = fd_jacobian(m.energy_sigma, sig, H)
    assert_rel_close(m.stress_sigma(sig), g_fd, RTOL, STRESS_SCALE, label(model, ext, d))


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSIONS)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_hessian_sigma_is_stress_sigma_jacobian(rng, model, ext, d):
    m = make_material(model, ext)
    sig = sigma_cases(rng, model, ext, d)
    H_fd = np.swapaxes(fd_jacobian(m.stress_sigma, sig, H), 1, 2)
    Hs = m.hessian_sigma(sig)
    assert_rel_close(Hs, H_fd, RTOL, TANGENT_SCALE, label(model, ext, d))
    assert np.all(sym_norm_rel(Hs) <= 1e-12)


def same_deformation_variants(sig):
    """Other signed sigma of the same F: reversed order, and a pair of signs flipped."""
    d = sig.shape[1]
    flip01 = sig.copy()
    flip01[:, :2] *= -1.0
    flip_ends = sig[:, ::-1].copy()
    flip_ends[:, [0, d - 1]] *= -1.0
    return {"reversed": sig[:, ::-1].copy(), "flip01": flip01, "reversed_flip_ends": flip_ends}


@pytest.mark.parametrize("variant", ["reversed", "flip01", "reversed_flip_ends"])
@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSIONS)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_sigma_derivatives_for_any_signed_input(rng, model, ext, d, variant):
    """The diagonal-space functions take any signed singular values, not only the polar-SVD
    convention (sorted, negative last); whatever they do with them, stress_sigma and
    hessian_sigma must still be the derivatives of energy_sigma and stress_sigma."""
    m = make_material(model, ext)
    sig = same_deformation_variants(sigma_cases(rng, model, ext, d))[variant]
    what = f"{label(model, ext, d)} {variant}"
    g_fd = fd_jacobian(m.energy_sigma, sig, H)
    assert_rel_close(m.stress_sigma(sig), g_fd, RTOL, STRESS_SCALE, what + " gradient")
    H_fd = np.swapaxes(fd_jacobian(m.stress_sigma, sig, H), 1, 2)
    assert_rel_close(m.hessian_sigma(sig), H_fd, RTOL, TANGENT_SCALE, what + " Hessian")


# (sigma with the gap delta to be added to the second entry of the pair, which pair)
NEAR_REPEATED = {
    2: [(1.2, 1.2), (0.8, 0.8)],
    3: [(1.3, 1.3, 0.8), (1.1, 0.7, 0.7), (1.2, 1.2, 1.2)],
}
NEAR_REPEATED_C1 = {2: [(0.3, 0.3)], 3: [(1.1, 0.3, 0.3), (0.3, 0.3, 0.3)]}


@pytest.mark.parametrize("delta", [0.0, 1e-12, 1e-9, 1e-7, 1e-5])
@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSIONS)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_tangent_near_repeated_singular_values(rng, model, ext, d, delta):
    """a_ij = (g_i - g_j) / (sigma_i - sigma_j) must not lose digits when sigma_i ~ sigma_j.

    P is a smooth function of F there (the energy is symmetric in sigma), so central differences
    across the nearly repeated values are as accurate as anywhere else.
    """
    table = NEAR_REPEATED_C1 if ext == "C1" else NEAR_REPEATED
    base = np.array(table[d], dtype=float)
    base[:, 1] += delta
    if d == 3:
        base[-1, 2] -= delta  # the triple case: three distinct but close values
    sig = np.repeat(base, 4, axis=0)
    F = matrices_with_sigma(rng, sig)
    m = make_material(model, ext)
    check_tangent(m, F, f"{label(model, ext, d)} gap {delta:g}")
