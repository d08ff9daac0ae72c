"""Continuity across the extension boundaries.

Points are placed 1e-9 on either side of a boundary. A continuous quantity with derivative of size
D changes by ~2e-9 D there; the 1e-6 relative tolerance allows D up to ~500 (k = 20 E ~ 43 here),
while a missing term produces an O(1e-2 .. 1) jump.
"""

import numpy as np
import pytest
from constitutive_helpers import (
    C2_SIGMAS,
    DIMS,
    EPS_C1,
    EPS_C2,
    LAM,
    MODEL_NAMES,
    MU,
    assert_rel_close,
    c2_root,
    compose,
    jdet,
    make_material,
    random_rotations,
)

DELTA = 1e-9
RTOL = 1e-6
N_ROT = 5

# (sigma with None at the position that crosses eps, description). Values below eps stay >= 0.05
# away from it, the crossing one passes from eps + delta to eps - delta.
C1_CROSSINGS = {
    2: [(1.2, None), (None, 0.2), (None, -0.2)],
    3: [
        (1.2, 0.9, None),
        (1.2, None, 0.2),
        (1.2, None, -0.2),
        (None, 0.25, 0.1),
        (None, 0.25, -0.1),
        (None, 0.3, -0.2),
    ],
}


def pair(sig_plus, sig_minus, rng):
    """The same random rotations applied to both sides."""
    sig = np.array([sig_plus, sig_minus])
    n, d = N_ROT, sig.shape[1]
    R1, R2 = random_rotations(rng, n, d), random_rotations(rng, n, d)
    Fp = compose(np.tile(sig[0], (n, 1)), R1, R2)
    Fm = compose(np.tile(sig[1], (n, 1)), R1, R2)
    return sig, Fp, Fm


def check_continuous(m, sig, Fp, Fm, what, tangent):
    e = m.energy_sigma(sig)
    assert_rel_close(e[:1], e[1:], RTOL, MU, what + " energy_sigma")
    g = m.stress_sigma(sig)
    assert_rel_close(g[:1], g[1:], RTOL, MU, what + " stress_sigma")
    assert_rel_close(m.energy(Fp), m.energy(Fm), RTOL, MU, what + " energy")
    assert_rel_close(m.stress(Fp), m.stress(Fm), RTOL, MU, what + " P")
    if tangent:
        h = m.hessian_sigma(sig)
        assert_rel_close(h[:1], h[1:], RTOL, MU + LAM, what + " hessian_sigma")
        Tp, Tm = m.tangent(Fp, project=False), m.tangent(Fm, project=False)
        assert_rel_close(Tp, Tm, RTOL, MU + LAM, what + " dP/dF")


def c1_crossings():
    return [(d, i) for d in DIMS for i in range(len(C1_CROSSINGS[d]))]


@pytest.mark.parametrize("d,case", c1_crossings())
@pytest.mark.parametrize("model", MODEL_NAMES)
@pytest.mark.extensions("C1")
def test_c1_region_boundaries(rng, model, d, case):
    template = C1_CROSSINGS[d][case]
    side = [[EPS_C1 + s * DELTA if v is None else v for v in template] for s in (1, -1)]
    sig, Fp, Fm = pair(side[0], side[1], rng)
    m = make_material(model, "C1")
    # P is continuous; dP/dF jumps across C1 region boundaries by design.
    check_continuous(m, sig, Fp, Fm, f"{model}+C1 crossing {template}", tangent=False)


def c2_crossings():
    return [(d, i) for d in DIMS for i, s in enumerate(C2_SIGMAS[d]) if np.prod(s) < EPS_C2]


@pytest.mark.parametrize("d,case", c2_crossings())
@pytest.mark.parametrize("model", MODEL_NAMES)
@pytest.mark.extensions("C2")
def test_c2_threshold(rng, model, d, case):
    """Along the ray from (1,..,1) towards a point below the threshold, cross J = eps."""
    target = np.array(C2_SIGMAS[d][case])
    a = target - 1.0
    s_star = c2_root(target, EPS_C2)
    sig_plus = 1.0 + s_star * (1.0 - DELTA) * a
    sig_minus = 1.0 + s_star * (1.0 + DELTA) * a
    sig, Fp, Fm = pair(sig_plus, sig_minus, rng)
    J = jdet(sig)
    assert J[0] > EPS_C2 > J[1] and np.all(np.abs(J - EPS_C2) < 1e-7)
    m = make_material(model, "C2")
    what = f"{model}+C2 crossing towards {target}"
    check_continuous(m, sig, Fp, Fm, what, tangent=True)


@pytest.mark.parametrize("d,case", c2_crossings())
@pytest.mark.parametrize("model", MODEL_NAMES)
@pytest.mark.extensions("C2", None)
def test_c2_equals_model_on_threshold(rng, model, d, case):
    """Value, gradient and Hessian of the extension match the model at J = eps (from above the
    two are the same function, so this checks the extension's limit from below)."""
    target = np.array(C2_SIGMAS[d][case])
    s_star = c2_root(target, EPS_C2)
    sig = (1.0 + s_star * (1.0 + DELTA) * (target - 1.0))[None]
    assert jdet(sig)[0] < EPS_C2
    ext, plain = make_material(model, "C2"), make_material(model)
    what = f"{model}+C2 at J=eps towards {target}"
    assert_rel_close(ext.energy_sigma(sig), plain.energy_sigma(sig), RTOL, MU, what + " energy")
    assert_rel_close(ext.stress_sigma(sig), plain.stress_sigma(sig), RTOL, MU, what + " grad")
    assert_rel_close(
        ext.hessian_sigma(sig), plain.hessian_sigma(sig), RTOL, MU + LAM, what + " Hessian"
    )
