"""The funnel (a wall with a conical hole) against an independent distance computation, its
derivatives by central differences, and its path crossings on sampled paths and in closed form.
No DOLFINx.
"""

import math

import numpy as np
import pytest

from dolfinx_invertible.contact import Funnel

FUNNEL = Funnel((0.3, 0.1, -0.2), (1.0, 0.5, 0.2), 0.2, 0.5)


def meridian(funnel, points):
    """(s, ρ) of the points: position along the axis from the throat, distance to the axis."""
    v = points - funnel.throat
    s = v @ funnel.axis
    return s, np.linalg.norm(v - np.outer(s, funnel.axis), axis=1)


def sampled_gap(funnel, points):
    """Distance to the funnel's surface, sampled in the plane through the axis, signed."""
    along = np.linspace(-4.0, 0.0, 40001)
    wall = np.stack([along, funnel.radius - funnel.slope * along], axis=1)
    up = np.linspace(funnel.radius, 4.0, 40001)
    face = np.stack([np.zeros_like(up), up], axis=1)
    surface = np.concatenate([wall, face])
    s, rho = meridian(funnel, points)
    distance = np.array(
        [np.min(np.hypot(surface[:, 0] - a, surface[:, 1] - b)) for a, b in zip(s, rho)]
    )
    solid = (rho >= funnel.radius - funnel.slope * s) & (s <= 0.0)
    return np.where(solid, -distance, distance)


def test_funnel_gap_is_the_distance_to_its_surface():
    rng = np.random.default_rng(3)
    points = FUNNEL.throat + rng.normal(scale=0.4, size=(300, 3))
    gap, reference = FUNNEL.gap(points), sampled_gap(FUNNEL, points)
    assert np.all(np.sign(gap) == np.sign(reference))
    outside = reference > 0.0
    # Every region is hit: beyond the face, nearest to the rim, inside the cone.
    s, rho = meridian(FUNNEL, points[outside])
    eta = rho - FUNNEL.radius
    assert np.any((s > 0) & (eta > 0))
    assert np.any((eta <= 0) & (s >= FUNNEL.slope * eta)) and np.any(s < FUNNEL.slope * eta)
    np.testing.assert_allclose(gap[outside], reference[outside], atol=1e-4)
    # The same as the cone where the nearest point is on the cone's wall.
    axis_points = FUNNEL.throat + np.outer([-1.0, -0.5], FUNNEL.axis)
    np.testing.assert_allclose(
        FUNNEL.gap(axis_points), (FUNNEL.radius + np.array([0.5, 0.25])) / math.sqrt(1.25)
    )


def test_funnel_derivatives_by_central_differences():
    rng = np.random.default_rng(4)
    points = FUNNEL.throat + rng.normal(scale=0.4, size=(300, 3))
    points = points[FUNNEL.gap(points) > 1e-3]
    gap, gradient, hessian = FUNNEL.gap_derivatives(points)
    np.testing.assert_allclose(gap, FUNNEL.gap(points))
    h = 1e-6
    basis = np.eye(3)
    by_differences = np.stack(
        [(FUNNEL.gap(points + h * e) - FUNNEL.gap(points - h * e)) / (2 * h) for e in basis], 1
    )
    np.testing.assert_allclose(gradient, by_differences, atol=1e-7)
    np.testing.assert_allclose(np.linalg.norm(gradient, axis=1), 1.0)  # a distance
    second = np.stack(
        [
            (FUNNEL.gap_derivatives(points + h * e)[1] - FUNNEL.gap_derivatives(points - h * e)[1])
            / (2 * h)
            for e in basis
        ],
        2,
    )
    # Away from the borders between regions, where the second derivatives jump.
    error = np.max(np.abs(second - hessian), axis=(1, 2))
    assert np.mean(error < 1e-6) > 0.95
    s, rho = meridian(FUNNEL, points)
    rim = (rho <= FUNNEL.radius) & (s >= FUNNEL.slope * (rho - FUNNEL.radius))
    assert np.count_nonzero(rim & (error < 1e-6)) > 5  # the rim's curved distance is checked


def test_funnel_path_crossing_on_sampled_paths():
    rng = np.random.default_rng(5)
    points = FUNNEL.throat + rng.normal(scale=0.4, size=(400, 3))
    points = points[FUNNEL.gap(points) > 0.0]
    directions = rng.normal(size=points.shape)
    crossing = FUNNEL.path_crossing(points, directions)
    alphas = np.linspace(0.0, 4.0, 40001)
    for point, direction, alpha in zip(points, directions, crossing):
        gaps = FUNNEL.gap(point + alphas[:, None] * direction)
        inside = np.flatnonzero(gaps <= 0.0)
        if len(inside) == 0:
            assert alpha > 4.0 - 1e-4
        else:
            assert alpha == pytest.approx(alphas[inside[0]], abs=2e-4)
            assert abs(FUNNEL.gap((point + alpha * direction)[None])[0]) < 1e-9
    assert np.count_nonzero(np.isfinite(crossing)) > 50


def test_funnel_crossings_in_closed_form():
    funnel = Funnel((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 0.5, 1.0)
    starts = np.array([[-2.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, -1.2, 0.0], [-1.0, 0.0, 0.0]])
    directions = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [-1.0, 1.5, 0.0], [0.0, 1.0, 0.0]])
    np.testing.assert_allclose(
        funnel.path_crossing(starts, directions),
        # Along the axis through the hole: never. Onto the face from beyond: 1. Back through
        # the hole (at α = 1, y = 0.3) until y = 0.3 + 1.5β meets the wall's radius 0.5 + β at
        # β = 0.4. Sideways from the axis at s = −1 to the wall of radius 1.5.
        [math.inf, 1.0, 1.4, 1.5],
    )
    # Backwards through the hole parallel to the axis: the cone widens, never met.
    assert funnel.path_crossing(np.array([[1.0, 0.2, 0.0]]), np.array([[-1.0, 0.0, 0.0]]))[0] == (
        math.inf
    )
    assert funnel.path_crossing(np.array([[-1.0, 2.0, 0.0]]), np.ones((1, 3)))[0] == 0.0
    with pytest.raises(ValueError, match="slope"):
        Funnel((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 0.5, -1.0)
