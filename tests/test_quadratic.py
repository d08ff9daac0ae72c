"""The first positive root of quadratics: the smallest positive root, also for tiny c₀."""

import math

import numpy as np
import pytest

from dolfinx_invertible.quadratic import first_positive_root_quadratic


def test_first_positive_root_quadratic_is_the_smallest_positive_root():
    rng = np.random.default_rng(1)
    c0 = rng.uniform(0.01, 2.0, 400)
    c1 = rng.normal(size=400)
    c2 = rng.normal(size=400)
    c2[:50] = 0.0  # linear
    c1[50:60] = 0.0
    alpha = first_positive_root_quadratic(c0, c1, c2)
    for a, b, c, found in zip(c0, c1, c2, alpha):
        roots = np.roots([c, b, a]) if c != 0.0 else np.roots([b, a]) if b != 0.0 else []
        positive = [r.real for r in np.atleast_1d(roots) if abs(r.imag) < 1e-12 and r.real > 0]
        if positive:
            assert found == pytest.approx(min(positive), rel=1e-10)
        else:
            assert found == math.inf


def test_first_positive_root_quadratic_keeps_accuracy_for_tiny_gaps():
    # c0 = 1e-14 with a slope of −1: the root 1e-14 must not be lost to cancellation.
    assert first_positive_root_quadratic(1e-14, -1.0, 1.0)[0] == pytest.approx(1e-14, rel=1e-12)
    assert first_positive_root_quadratic(1e-14, -1.0, -1.0)[0] == pytest.approx(1e-14, rel=1e-12)
