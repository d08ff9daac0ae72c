"""The contact scenes at a small size: each runs without a boundary vertex ever inside an
obstacle, keeps a positive gap, and shows what it is there for (the cube settles at the bowl's
bottom; the ball inverts cells that recover; the body passes the funnel's throat; the body gets
past the cylinders). The funnel obstacle of the tight-tube scene is checked against an
independent distance computation, finite differences and sampled paths.
"""

from __future__ import annotations

import json
import math

from mpi4py import MPI

import numpy as np
import pytest

from dolfinx_invertible.scenes import Parameters, get_scene, run_scene
from dolfinx_invertible.scenes.tight_tube import Funnel


def run(name, comm=MPI.COMM_WORLD, directory=None, **overrides):
    scene = get_scene(name)
    values = dict(scene.defaults)
    values.update(overrides)
    return run_scene(scene, Parameters(**values), output=directory, comm=comm)


def check_contact(summary):
    assert summary["completed"] and summary["converged"], summary.get("reason")
    assert summary["penetrations"] == 0
    assert summary["min_gap"] > 0.0
    # The body did touch: some step came within the barrier distance.
    assert summary["min_gap"] < summary["barrier_distance"]


# -- the scenes ------------------------------------------------------------------------------
def test_bowl_drop_settles_at_the_bottom(directory):
    summary = run("bowl-drop", directory=directory / "bowl", resolution=2, dt=0.02, t_end=2.0)
    check_contact(summary)
    size = summary["parameters"]["size"]
    centre = np.array(summary["final_centre"])
    # At rest: the centre half a side above the bowl's bottom (z = −1), give or take the
    # sphere's curvature under its bottom face; below where a rigid cube would rest on its
    # bottom corners, as the soft one sags into the bowl.
    assert centre[2] == pytest.approx(-1.0 + 0.5 * size, abs=0.05)
    assert centre[2] < summary["rest_centre_height"]
    np.testing.assert_allclose(centre[:2], 0.0, atol=0.01)
    assert summary["final_kinetic_energy"] < 1e-4 * summary["peak_kinetic_energy"]
    # It started in the middle: the corners √3·size/2 from the centre of the bowl.
    history = np.load(directory / "bowl" / "contact.npy")
    assert history[0, 1] == pytest.approx(1.0 - math.sqrt(3.0) * 0.5 * size)
    assert len(history) == summary["steps"] + 1


def test_ball_hit_inverts_cells_that_recover_after_it_left():
    summary = run("ball-hit", resolution=4, dt=0.004, t_end=0.16)
    check_contact(summary)
    assert summary["max_inverted_during_hit"] > 0
    assert summary["final_inverted"] == 0
    assert summary["time"] > summary["ball_leaves"]


def test_tight_tube_pushes_the_body_past_the_throat():
    summary = run("tight-tube", resolution=2, dt=0.005)
    check_contact(summary)
    # Every node of the body lies beyond the throat, which is a third of its width.
    assert summary["final_low"][0] > summary["throat_x"]
    assert summary["throat_radius"] == pytest.approx(summary["parameters"]["size"] / 6.0)
    assert summary["time"] > summary["push_time"]
    # Squeezed through inversion on the way. (Whether the body then finds its shape again
    # depends on the path at this coarse size, where the throat is less than two cells
    # across; at the default size it does.)
    assert summary["max_inverted"] > 0


def test_gap_squeeze_gets_the_body_past_the_cylinders():
    summary = run("gap-squeeze", resolution=3, dt=0.004, t_end=0.1)
    check_contact(summary)
    # Every node lies below the plane of the cylinders' axes, the nip.
    assert summary["final_high"][2] < 0.0
    assert summary["max_inverted"] > 0 and summary["final_inverted"] == 0


@pytest.mark.mpi
def test_bowl_drop_distributed_equals_serial():
    options = dict(resolution=3, dt=0.02, t_end=0.6)
    distributed = run("bowl-drop", comm=MPI.COMM_WORLD, **options)
    serial = run("bowl-drop", comm=MPI.COMM_SELF, **options)
    assert distributed["ranks"] == MPI.COMM_WORLD.size and serial["ranks"] == 1
    assert distributed["penetrations"] == serial["penetrations"] == 0
    assert distributed["min_gap"] == pytest.approx(serial["min_gap"], rel=1e-6)
    np.testing.assert_allclose(distributed["final_centre"], serial["final_centre"], atol=1e-8)
    assert distributed["steps"] == serial["steps"]


def test_contact_scenes_write_their_record(directory):
    summary = run("gap-squeeze", directory=directory / "gap", resolution=2, dt=0.004, t_end=0.02)
    if MPI.COMM_WORLD.rank == 0:
        written = json.loads((directory / "gap" / "summary.json").read_text())
        assert written["min_gap"] == summary["min_gap"]
        history = np.load(directory / "gap" / "contact.npy")
        assert history.shape == (summary["steps"] + 1, 7)
        assert np.min(history[:, 1]) == pytest.approx(summary["min_gap"])


# -- the funnel ------------------------------------------------------------------------------
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


def test_funnel_first_crossing_on_sampled_paths():
    rng = np.random.default_rng(5)
    points = FUNNEL.throat + rng.normal(scale=0.4, size=(400, 3))
    points = points[FUNNEL.gap(points) > 0.0]
    directions = rng.normal(size=points.shape)
    crossing = FUNNEL.first_crossing(points, directions)
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
        funnel.first_crossing(starts, directions),
        # Along the axis through the hole: never. Onto the face from beyond: 1. Back through
        # the hole (at α = 1, y = 0.3) until y = 0.3 + 1.5β meets the wall's radius 0.5 + β at
        # β = 0.4. Sideways from the axis at s = −1 to the wall of radius 1.5.
        [math.inf, 1.0, 1.4, 1.5],
    )
    # Backwards through the hole parallel to the axis: the cone widens, never met.
    assert funnel.first_crossing(np.array([[1.0, 0.2, 0.0]]), np.array([[-1.0, 0.0, 0.0]]))[0] == (
        math.inf
    )
    assert funnel.first_crossing(np.array([[-1.0, 2.0, 0.0]]), np.ones((1, 3)))[0] == 0.0
    with pytest.raises(ValueError, match="slope"):
        Funnel((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 0.5, -1.0)
