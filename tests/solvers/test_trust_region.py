"""The trust region's radius update (Conn, Gould and Toint's rules, with a line search)."""

from __future__ import annotations

import math

import pytest

from dolfinx_invertible.solvers.trust_region import TrustRegion


def _step(region: TrustRegion, **given) -> float:
    values = dict(fraction=1.0, step_norm=2.0, boundary=True, actual=1.0, predicted=1.0)
    values.update(given)
    region.update(rounding=1e-12, **values)
    return region.radius


def test_a_solve_starts_unbounded_and_its_first_good_step_sets_twice_its_length():
    region = TrustRegion()
    assert region.radius == math.inf
    assert _step(region, boundary=False, step_norm=3.0) == 6.0
    region.start_solve()
    assert region.radius == math.inf and math.isnan(region.ratio)


@pytest.mark.parametrize(
    ("actual", "boundary", "expected"),
    [
        (0.9, True, 8.0),  # ρ = 0.9 on the boundary: doubles
        (0.9, False, 4.0),  # inside the region the radius was not what bound the step
        (0.5, True, 4.0),  # a fair model: kept
        (0.1, True, 2.0),  # a poor one: half the step
        (-0.2, True, 2.0),  # the energy rose (a step the line search cannot have passed)
    ],
)
def test_the_radius_follows_the_models_agreement(actual, boundary, expected):
    region = TrustRegion()
    region.radius = 4.0
    assert _step(region, step_norm=4.0 if boundary else 3.0, boundary=boundary,
                 actual=actual) == pytest.approx(expected)  # fmt: skip
    assert region.ratio == pytest.approx(actual)


def test_a_shortened_step_sets_the_radius_to_the_length_taken():
    region = TrustRegion()
    region.radius = 4.0
    assert _step(region, fraction=0.25, step_norm=4.0, actual=0.5) == 1.0
    assert _step(region, fraction=0.25, step_norm=4.0, actual=0.1) == 0.5


def test_a_step_limits_cap_leaves_the_radius():
    # Collision detection stopping a step short says nothing of how far the model holds.
    region = TrustRegion()
    assert _step(region, fraction=0.05, cap=0.05, step_norm=4.0, boundary=False) == 4.0
    assert _step(region, fraction=0.1, cap=0.1, step_norm=4.0) == 4.0
    # Shortened by the line search after the cap: as far as the model held.
    assert _step(region, fraction=0.05, cap=0.1, step_norm=4.0, actual=0.5) == 0.2


def test_decreases_below_rounding_count_as_agreement():
    region = TrustRegion()
    region.radius = 4.0
    region.update(
        fraction=1.0, step_norm=4.0, boundary=True, actual=-1e-15, predicted=2e-15, rounding=1e-12
    )
    assert region.ratio == 1.0 and region.radius == 8.0


@pytest.mark.parametrize("step_norm", [math.nan, 0.0])
def test_an_unknown_step_length_leaves_the_radius(step_norm):
    region = TrustRegion()
    region.radius = 4.0
    assert _step(region, step_norm=step_norm, actual=-5.0) == 4.0
