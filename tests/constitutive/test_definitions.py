"""The energies are the ones the contract defines.

Plain models are compared with closed-form formulas; the C1, C2 and IFE extensions are rebuilt from
their definitions (docs/design.md) on top of the plain model's sigma-space value, gradient and
Hessian, which the first tests pin down independently.
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
    c2_root,
    jdet,
    jitter,
    make_material,
    matrices_with_sigma,
    random_sigma,
    reference_energy,
    sigma_cases,
    signed_svd,
    subsets,
)

# Closed forms evaluated two ways differ by rounding only.
RTOL = 1e-11
K_C1 = 5.0


def plain_sigma(rng, model, d):
    pos = random_sigma(rng, 20, d, 0.3, 2.0, min_gap=1e-3)
    if model == "NeoHookean":
        return pos
    return np.concatenate([pos, random_sigma(rng, 20, d, 0.1, 2.0, inverted=True, min_gap=1e-3)])


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", MODEL_NAMES)
@pytest.mark.extensions(None)
def test_plain_energy_formula(rng, model, d):
    m = make_material(model)
    sig = plain_sigma(rng, model, d)
    what = f"{model} {d}D"
    assert_rel_close(m.energy_sigma(sig), reference_energy(model, sig), RTOL, MU, what)
    F = matrices_with_sigma(rng, sig)
    _, s_ref, _ = signed_svd(F)
    # through the SVD: the signed singular values of F decide the energy
    assert_rel_close(m.energy(F), reference_energy(model, s_ref), 1e-10, MU, what + " energy(F)")


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", ENERGY_EXTENSION_NAMES)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_stress_is_rotated_sigma_gradient(rng, model, ext, d):
    """P = U diag(g) V^T with g = stress_sigma(sigma); energy(F) = energy_sigma(sigma)."""
    m = make_material(model, ext)
    F = matrices_with_sigma(rng, sigma_cases(rng, model, ext, d))
    U, s, V = signed_svd(F)
    P_ref = np.einsum("nij,nj,nkj->nik", U, m.stress_sigma(s), V)
    what = f"{model}+{ext} {d}D"
    assert_rel_close(m.stress(F), P_ref, 1e-10, MU, what + " P")
    assert_rel_close(m.energy(F), m.energy_sigma(s), 1e-10, MU, what + " energy")


# ---------------------------------------------------------------------------------------------
# C1
# ---------------------------------------------------------------------------------------------
def third_mixed_partial(plain, q, i, j, k, h=1e-5):
    """d^3 Psi / d i d j d k at q: central difference of the (exact) Hessian. Error ~1e-9."""
    e = np.zeros_like(q)
    e[k] = h
    Hp, Hm = plain.hessian_sigma(np.array([q + e, q - e]))
    return (Hp[i, j] - Hm[i, j]) / (2 * h)


def c1_reference(plain, s, eps, k):
    S = [i for i in range(s.size) if s[i] < eps]
    q = s.copy()
    q[S] = eps
    value = plain.energy_sigma(q[None])[0]
    g = plain.stress_sigma(q[None])[0]
    H = plain.hessian_sigma(q[None])[0]
    for T in subsets(S):
        if not T:
            continue
        if len(T) == 1:
            dT = g[T[0]]
        elif len(T) == 2:
            dT = H[T[0], T[1]]
        else:
            dT = third_mixed_partial(plain, q, *T)
        value += dT * np.prod(s[list(T)] - eps)
    return value + k / 2 * np.sum((s[S] - eps) ** 2)


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", MODEL_NAMES)
@pytest.mark.extensions("C1", None)
def test_c1_energy_definition(rng, model, d):
    plain = make_material(model)
    m = make_material(model, "C1", k=K_C1)
    sig = np.concatenate(
        [jitter(rng, C1_REGION_SIGMAS[d], 2, 0.01), random_sigma(rng, 10, d, 0.02, 1.5)]
    )
    ref = np.array([c1_reference(plain, s, EPS_C1, K_C1) for s in sig])
    # the finite-difference third partial is good to ~1e-9 and enters times prod(sigma - eps)
    assert_rel_close(m.energy_sigma(sig), ref, 1e-8, MU, f"{model}+C1 {d}D")


# ---------------------------------------------------------------------------------------------
# C2 and IFE: second / first order Taylor expansion at the point q on J = eps
# ---------------------------------------------------------------------------------------------
def c2_point(s, eps):
    t = c2_root(s, eps)
    q = 1.0 + t * (s - 1.0)
    assert abs(np.prod(q) - eps) < 1e-12
    return q


def c2_samples(rng, d):
    return np.concatenate(
        [jitter(rng, C2_SIGMAS[d], 2, 0.003), random_sigma(rng, 10, d, 0.05, 1.6, inverted=True)]
    )


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", MODEL_NAMES)
@pytest.mark.extensions("C2", None)
def test_c2_energy_definition(rng, model, d):
    plain = make_material(model)
    m = make_material(model, "C2")
    sig = c2_samples(rng, d)
    ref = np.empty(len(sig))
    for n, s in enumerate(sig):
        if np.prod(s) >= EPS_C2:
            ref[n] = plain.energy_sigma(s[None])[0]
            continue
        q = c2_point(s, EPS_C2)
        dq = s - q
        e, g, H = (
            f(q[None])[0] for f in (plain.energy_sigma, plain.stress_sigma, plain.hessian_sigma)
        )
        ref[n] = e + g @ dq + 0.5 * dq @ H @ dq
    assert_rel_close(m.energy_sigma(sig), ref, 1e-10, MU, f"{model}+C2 {d}D")


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", MODEL_NAMES)
@pytest.mark.extensions("IFE", None)
def test_ife_stress_definition(rng, model, d):
    plain = make_material(model)
    m = make_material(model, "IFE")
    sig = c2_samples(rng, d)
    F = matrices_with_sigma(rng, sig)
    U, s_ref, V = signed_svd(F)
    g_ref = np.empty_like(s_ref)
    for n, s in enumerate(s_ref):
        q = s if np.prod(s) >= EPS_C2 else c2_point(s, EPS_C2)
        g_ref[n] = plain.stress_sigma(q[None])[0] + plain.hessian_sigma(q[None])[0] @ (s - q)
    P_ref = np.einsum("nij,nj,nkj->nik", U, g_ref, V)
    assert np.any(jdet(s_ref) < 0)
    assert_rel_close(m.stress(F), P_ref, 1e-10, MU + LAM, f"{model}+IFE {d}D")
