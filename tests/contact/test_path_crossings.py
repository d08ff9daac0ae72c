"""Continuous collision detection: the crossing of a straight path with every shape is exact
(the gap vanishes there and stays positive before), for static and moving obstacles, in 2D and
3D; closed-form crossings for head-on motions; the collision-free step. No DOLFINx.
"""

import math

import numpy as np
import pytest
from contact_helpers import random_points, shapes

from dolfinx_invertible.contact import (
    Cone,
    Cylinder,
    HalfSpace,
    Obstacles,
    RigidMotion,
    Sphere,
)

CASES = [
    (dimension, moving, index)
    for dimension in (2, 3)
    for moving in (False, True)
    for index in range(len(shapes(dimension)))
]
IDS = [f"{d}D-{'moving' if m else 'static'}-{shapes(d)[i][0]}" for d, m, i in CASES]
TIME = 0.6


@pytest.mark.parametrize("dimension, moving, index", CASES, ids=IDS)
def test_crossing_is_exact_for_straight_paths(dimension, moving, index):
    _, obstacle = shapes(dimension, moving)[index]
    x = random_points(dimension, 200, seed=dimension + 5)
    x = x[obstacle.gap(x, TIME) > 1e-3]
    p = np.random.default_rng(2).normal(size=x.shape)
    alpha = obstacle.path_crossing(x, p, TIME)
    hits = np.isfinite(alpha)
    assert hits.sum() >= 10 and (~hits).sum() >= 1 or hits.all()
    end = x[hits] + alpha[hits, None] * p[hits]
    np.testing.assert_allclose(obstacle.gap(end, TIME), 0.0, atol=1e-12)
    # The gap stays positive before the crossing (and everywhere along a path that misses).
    fractions = np.linspace(0.0, 1.0, 2001)[1:-1]
    limits = np.where(hits, alpha, 20.0)
    for point, direction, limit in zip(x, p, limits):
        path = point + (fractions * limit)[:, None] * direction
        assert np.all(obstacle.gap(path, TIME) > 0.0)


def test_closed_form_crossings():
    # Plane: gap d, approach speed n·p.
    ground = HalfSpace((0.0, 0.0, 1.0), -0.5)
    x = np.array([[0.3, 0.1, 0.25]])
    assert ground.path_crossing(x, np.array([[1.0, 2.0, -3.0]]))[0] == pytest.approx(0.25)
    assert ground.path_crossing(x, np.array([[1.0, 2.0, 3.0]]))[0] == math.inf
    # Ball, head-on: gap / speed.
    ball = Sphere((1.0, 0.0, 0.0), 0.5)
    x = np.array([[3.0, 0.0, 0.0]])
    assert ball.path_crossing(x, np.array([[-2.0, 0.0, 0.0]]))[0] == pytest.approx(0.75)
    # Bowl, from the centre outwards: radius / speed, in any direction.
    bowl = Sphere((0.0, 0.0, 0.0), 2.0, inside=True)
    p = np.array([[0.0, 0.6, 0.8], [4.0, 0.0, 0.0]])
    np.testing.assert_allclose(bowl.path_crossing(np.zeros((2, 3)), p), [2.0, 0.5])
    # Roller, tangent to the axis the path never comes closer: no crossing; radially: gap/speed.
    roller = Cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1.0)
    x = np.array([[3.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    p = np.array([[0.0, 0.0, 5.0], [-1.0, 0.0, 7.0]])
    np.testing.assert_allclose(roller.path_crossing(x, p), [math.inf, 2.0])
    # Tube, from its axis: radius / radial speed, whatever the axial speed.
    tube = Cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1.0, inside=True)
    assert tube.path_crossing(np.zeros((1, 3)), np.array([[0.0, 0.5, 9.0]]))[0] == (
        pytest.approx(2.0)
    )
    # Cone narrowing from radius 1 at z = 0 to 0 at z = 1: along the axis to the apex.
    cone = Cone.between((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1.0, 1e-300)
    assert cone.path_crossing(np.array([[0.0, 0.0, 0.5]]), np.array([[0.0, 0.0, 2.0]]))[0] == (
        pytest.approx(0.25)
    )
    # A point moving with the obstacle never reaches it; one at rest meets the approaching wall.
    plate = HalfSpace(
        (0.0, 0.0, -1.0), -1.0, motion=RigidMotion(3, translation=lambda t: (0.0, 0.0, -t))
    )
    x = np.array([[0.0, 0.0, 0.0]])
    assert plate.gap(x, 0.4)[0] == pytest.approx(0.6)
    assert plate.path_crossing(x, np.array([[0.0, 0.0, 0.3]]), 0.4)[0] == pytest.approx(2.0)


def test_points_not_outside_cross_at_once():
    ball = Sphere((0.0, 0.0), 1.0)
    x = np.array([[0.5, 0.0], [1.0, 0.0], [2.0, 0.0]])
    p = np.array([[1.0, 0.0], [1.0, 0.0], [1.0, 0.0]])
    np.testing.assert_array_equal(ball.path_crossing(x, p), [0.0, 0.0, math.inf])


def test_collision_free_step_is_a_fraction_of_the_first_crossing_capped_at_one():
    obstacles = Obstacles([HalfSpace((0.0, 1.0), -1.0), Sphere((5.0, 0.0), 1.0)])
    x = np.array([[0.0, 1.0], [3.0, 0.0]])
    towards = np.array([[0.0, -1.0], [0.0, 0.0]])  # reaches the plane y = −1 at α = 2
    assert obstacles.collision_free_step(x, towards, 0.0, fraction=0.9) == pytest.approx(1.0)
    towards[0, 1] = -8.0  # α = 0.25
    assert obstacles.collision_free_step(x, towards, 0.0, fraction=0.9) == pytest.approx(0.225)
    towards[1] = (2.0, 0.0)  # the second point reaches the ball (x = 4) at α = 0.5
    towards[0, 1] = -1.0
    assert obstacles.collision_free_step(x, towards, 0.0, fraction=0.8) == pytest.approx(0.4)
    np.testing.assert_allclose(obstacles.path_crossing(x, towards), [2.0, 0.5])
    assert obstacles.collision_free_step(x[:0], towards[:0], 0.0) == 1.0
    inside = np.array([[5.0, 0.5]])
    assert obstacles.collision_free_step(inside, np.zeros((1, 2)), 0.0) == 0.0
    with pytest.raises(ValueError, match="fraction"):
        obstacles.collision_free_step(x, towards, 0.0, fraction=1.0)
