"""Isotropy and frame indifference: Psi(R F Q) = Psi(F), P(R F) = R P(F), P(F Q) = P(F) Q.

Both sides go through a different SVD, so only rounding separates them: 1e-10 relative leaves
room for the conditioning of the singular vectors of random matrices (gaps ~1e-3 cost ~1e3 ulp).
"""

import numpy as np
import pytest
from constitutive_helpers import (
    DIMS,
    EXTENSION_NAMES,
    MODEL_NAMES,
    MU,
    assert_rel_close,
    make_material,
    random_rotations,
)

RTOL = 1e-10
N = 40


def random_F(rng, model, ext, d):
    """Random matrices, about half of them inverted (only J > 0 for plain Neo-Hookean)."""
    F = np.concatenate(
        [np.eye(d) + 0.4 * rng.standard_normal((N // 2, d, d)), rng.standard_normal((N, d, d))]
    )
    if model == "NeoHookean" and ext is None:
        F = F[np.linalg.det(F) > 1e-3]
    else:
        assert np.sum(np.linalg.det(F) < 0) >= N // 4
    return F


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("ext", EXTENSION_NAMES)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_invariance(rng, model, ext, d):
    m = make_material(model, ext)
    F = random_F(rng, model, ext, d)
    n = F.shape[0]
    R, Q = random_rotations(rng, n, d), random_rotations(rng, n, d)
    what = f"{model}+{ext} {d}D"

    P = m.stress(F)
    assert_rel_close(m.stress(R @ F), R @ P, RTOL, MU, what + " P(RF) = R P(F)")
    assert_rel_close(m.stress(F @ Q), P @ Q, RTOL, MU, what + " P(FQ) = P(F) Q")
    assert_rel_close(m.stress(R @ F @ Q), R @ P @ Q, RTOL, MU, what + " P(RFQ) = R P(F) Q")
    if ext != "IFE":
        e = m.energy(F)
        assert_rel_close(m.energy(R @ F @ Q), e, RTOL, MU, what + " Psi(RFQ) = Psi(F)")
