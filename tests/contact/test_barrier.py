"""The IPC barrier b(d) and its parameter rules, against finite differences and their definitions.

Central differences with step 1e-7 d̂ on gaps well inside (0, d̂): truncation ~ h² b‴ and
rounding ~ 1e-16 b / h are both below 1e-7 relative there, so the 1e-6 tolerance fails on any
wrong term. No DOLFINx.
"""

import math

import numpy as np
import pytest

from dolfinx_invertible.contact import (
    DEFAULT_DISTANCE_FRACTION,
    HALF_DISTANCE_CURVATURE,
    Barrier,
    barrier_distance,
    barrier_stiffness,
)

DISTANCE = 0.03
STIFFNESS = 7.0e4
GAPS = DISTANCE * np.array([1e-4, 0.01, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99])


def test_value_is_the_formula():
    barrier = Barrier(DISTANCE, STIFFNESS)
    d = GAPS
    expected = -STIFFNESS * (d - DISTANCE) ** 2 * np.log(d / DISTANCE)
    np.testing.assert_allclose(barrier.value(d), expected, rtol=1e-14)


@pytest.mark.parametrize("order", [1, 2])
def test_derivatives_by_central_differences(order):
    barrier = Barrier(DISTANCE, STIFFNESS)
    lower, upper = (
        (barrier.value, barrier.derivative)
        if order == 1
        else (barrier.derivative, barrier.second_derivative)
    )
    h = 1e-7 * GAPS
    fd = (lower(GAPS + h) - lower(GAPS - h)) / (2.0 * h)
    np.testing.assert_allclose(upper(GAPS), fd, rtol=1e-6)


def test_c2_at_the_barrier_distance_and_zero_beyond():
    barrier = Barrier(DISTANCE, STIFFNESS)
    beyond = DISTANCE * np.array([1.0, 1.5, 10.0])
    for function in (barrier.value, barrier.derivative, barrier.second_derivative):
        assert np.all(function(beyond) == 0.0)
    # Approaching d̂ from below, b, b′ and b″ tend to 0 like (d̂ − d)³, (d̂ − d)², (d̂ − d).
    below = DISTANCE * (1.0 - np.array([1e-2, 1e-3, 1e-4]))
    scale = STIFFNESS * DISTANCE**2
    assert np.all(np.abs(barrier.value(below)) < 10 * scale * 1e-6)
    assert np.all(np.diff(np.abs(barrier.second_derivative(below))) < 0.0)
    assert abs(barrier.second_derivative(below[-1])) < 1e-3 * STIFFNESS


def test_infinite_at_and_below_contact():
    barrier = Barrier(DISTANCE, STIFFNESS)
    touching = np.array([0.0, -1e-9, -1.0])
    assert np.all(barrier.value(touching) == math.inf)
    assert np.all(barrier.derivative(touching) == -math.inf)
    assert np.all(barrier.second_derivative(touching) == math.inf)
    tiny = DISTANCE * np.array([1e-3, 1e-6, 1e-9])
    assert np.all(np.diff(barrier.value(tiny)) > 0.0)  # grows without bound as d → 0
    assert np.all(barrier.derivative(GAPS) < 0.0)
    assert np.all(barrier.second_derivative(GAPS) > 0.0)


def test_curvature_at_half_distance_is_the_rule_constant():
    barrier = Barrier(DISTANCE, STIFFNESS)
    assert barrier.second_derivative(0.5 * DISTANCE) == pytest.approx(
        HALF_DISTANCE_CURVATURE * STIFFNESS, rel=1e-14
    )
    assert HALF_DISTANCE_CURVATURE == pytest.approx(5.0 + 2.0 * math.log(2.0))


@pytest.mark.parametrize("dimension", [2, 3])
def test_stiffness_rule_matches_material_stiffness_per_vertex(dimension):
    # A vertex of spacing h carries w = h^(D−1) of the boundary; the rule makes its barrier
    # stiffness at d̂/2 equal E h^(D−2), whatever d̂.
    youngs_modulus, spacing = 3.0e5, 0.04
    kappa = barrier_stiffness(youngs_modulus, spacing)
    for fraction in (0.05, 0.1, 0.5):
        barrier = Barrier(barrier_distance(spacing, fraction), kappa)
        weight = spacing ** (dimension - 1)
        vertex_stiffness = weight * barrier.second_derivative(0.5 * barrier.distance)
        assert vertex_stiffness == pytest.approx(youngs_modulus * spacing ** (dimension - 2))


def test_distance_rule():
    assert barrier_distance(0.2) == pytest.approx(DEFAULT_DISTANCE_FRACTION * 0.2)
    assert barrier_distance(0.2, 0.25) == pytest.approx(0.05)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: Barrier(0.0, 1.0), "distance"),
        (lambda: Barrier(1.0, -1.0), "stiffness"),
        (lambda: Barrier(math.nan, 1.0), "distance"),
        (lambda: barrier_distance(-0.1), "spacing"),
        (lambda: barrier_distance(0.1, 0.0), "fraction"),
        (lambda: barrier_stiffness(0.0, 0.1), "youngs_modulus"),
        (lambda: barrier_stiffness(1.0, math.inf), "spacing"),
    ],
)
def test_bad_parameters_are_refused(call, name):
    with pytest.raises(ValueError, match=name):
        call()
