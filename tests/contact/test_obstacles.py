"""Obstacles: gap derivatives by central differences (static and moving), the gap as a signed
distance to a densely sampled surface, the rigid motion against an explicit construction.

Central differences with step 1e-6 on O(1) coordinates: truncation ~ 1e-12 times the third
derivative (curvatures ~ 1/r³ with r ≥ 0.5) and rounding ~ 1e-10, so 1e-7 fails on any wrong
term. Points within 0.1 of an axis or centre, where the derivatives are singular, are skipped.
No DOLFINx.
"""

import math
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from contact_helpers import random_points, shapes

from dolfinx_invertible.contact import Cone, Cylinder, HalfSpace, Obstacles, RigidMotion, Sphere
from dolfinx_invertible.contact.motion import rotation_matrix

H = 1e-6
CASES = [
    (dimension, moving, index)
    for dimension in (2, 3)
    for moving in (False, True)
    for index in range(len(shapes(dimension)))
]
IDS = [f"{d}D-{'moving' if m else 'static'}-{shapes(d)[i][0]}" for d, m, i in CASES]
TIME = 0.8


def regular_points(obstacle, dimension, t):
    """Random points, none within 0.1 of where the gap is not twice differentiable."""
    x = random_points(dimension, 60, seed=dimension)
    y, _ = obstacle._to_body(x, t)
    if isinstance(obstacle, Sphere):
        keep = np.linalg.norm(y - obstacle.center, axis=1) > 0.1
    elif isinstance(obstacle, (Cylinder, Cone)):
        keep = np.linalg.norm((y - obstacle.point) @ obstacle._projector, axis=1) > 0.1
    else:
        keep = np.ones(len(x), dtype=bool)
    return x[keep]


@pytest.mark.parametrize("dimension, moving, index", CASES, ids=IDS)
def test_gap_derivatives_by_central_differences(dimension, moving, index):
    _, obstacle = shapes(dimension, moving)[index]
    x = regular_points(obstacle, dimension, TIME)
    gap, gradient, hessian = obstacle.gap_derivatives(x, TIME)
    np.testing.assert_allclose(gap, obstacle.gap(x, TIME), rtol=0, atol=1e-15)
    for k in range(dimension):
        step = np.zeros(dimension)
        step[k] = H
        fd_gradient = (obstacle.gap(x + step, TIME) - obstacle.gap(x - step, TIME)) / (2 * H)
        np.testing.assert_allclose(gradient[:, k], fd_gradient, rtol=0, atol=1e-7)
        forward = obstacle.gap_derivatives(x + step, TIME)[1]
        backward = obstacle.gap_derivatives(x - step, TIME)[1]
        np.testing.assert_allclose(hessian[:, :, k], (forward - backward) / (2 * H), atol=1e-7)
    np.testing.assert_allclose(hessian, np.swapaxes(hessian, 1, 2), atol=1e-14)
    # Every gap is a distance near its surface: a unit gradient.
    np.testing.assert_allclose(np.linalg.norm(gradient, axis=1), 1.0, rtol=1e-12)


def surface_map(name, obstacle):
    """The surface of a static 3D obstacle as a map of two parameters and their ranges."""
    if name in ("ball", "bowl"):

        def sphere(theta, phi):
            direction = np.stack(
                [np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1
            )
            return obstacle.center + obstacle.radius * direction

        return sphere, (0.0, math.pi), (-math.pi, 3.0 * math.pi)
    if name == "half-space":
        n = obstacle.normal
        a = np.cross(n, (1.0, 0.0, 0.0))
        a /= np.linalg.norm(a)
        b = np.cross(n, a)

        def plane(s, r):
            return obstacle.offset * n + s[..., None] * a + r[..., None] * b

        return plane, (-4.0, 4.0), (-4.0, 4.0)
    axis = obstacle.axis
    a = np.cross(axis, (1.0, 0.0, 0.0))
    a /= np.linalg.norm(a)
    b = np.cross(axis, a)
    slope = obstacle.slope if name == "cone" else 0.0

    def tube(s, phi):
        radius = obstacle.radius + slope * s
        ring = np.cos(phi)[..., None] * a + np.sin(phi)[..., None] * b
        return obstacle.point + s[..., None] * axis + radius[..., None] * ring

    return tube, (-3.0, 3.0), (-math.pi, 3.0 * math.pi)


def distance_to_surface(point, surface, first, second, samples=120, levels=4):
    """Distance from a point to a parametrised surface by nested grid searches."""
    lower = np.array([first[0], second[0]])
    upper = np.array([first[1], second[1]])
    for _ in range(levels):
        u, v = np.meshgrid(*(np.linspace(lower[k], upper[k], samples) for k in range(2)))
        distances = np.linalg.norm(surface(u, v) - point, axis=-1)
        row, column = np.unravel_index(np.argmin(distances), distances.shape)
        best = np.array([u[row, column], v[row, column]])
        width = 2.0 * (upper - lower) / (samples - 1)
        lower, upper = best - width, best + width
    return float(np.min(distances))


@pytest.mark.parametrize("index", range(6), ids=[name for name, _ in shapes(3)])
def test_gap_is_the_signed_distance_to_the_surface(index):
    name, obstacle = shapes(3)[index]
    surface, first, second = surface_map(name, obstacle)
    # Points near the surface; the cone's apex is 3.6 along its axis, farther than these.
    x = random_points(3, 400, seed=7, scale=1.2)
    gap = obstacle.gap(x)
    x = x[np.abs(gap) < 0.15][:25]
    assert len(x) >= 10
    distance = np.array([distance_to_surface(point, surface, first, second) for point in x])
    np.testing.assert_allclose(np.abs(obstacle.gap(x)), distance, rtol=0, atol=1e-6)


def test_gap_signs():
    ball = Sphere((0.0, 0.0, 0.0), 1.0)
    bowl = Sphere((0.0, 0.0, 0.0), 1.0, inside=True)
    points = np.array([[0.0, 0.0, 0.5], [0.0, 2.0, 0.0]])
    np.testing.assert_allclose(ball.gap(points), [-0.5, 1.0])
    np.testing.assert_allclose(bowl.gap(points), [0.5, -1.0])
    roller = Cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 3.0), 1.0)
    tube = Cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 3.0), 1.0, inside=True)
    points = np.array([[0.5, 0.0, 7.0], [0.0, -3.0, -2.0]])
    np.testing.assert_allclose(roller.gap(points), [-0.5, 2.0])
    np.testing.assert_allclose(tube.gap(points), [0.5, -2.0])
    ground = HalfSpace((0.0, 0.0, 2.0), 1.0)  # z = 0.5 after normalisation
    np.testing.assert_allclose(ground.gap(np.array([[3.0, 1.0, 1.5], [0.0, 0.0, 0.0]])), [1, -0.5])
    # Radius 1 at z = 0 narrowing to 0.5 at z = 1 (slope −1/2): L = √(1 + 1/4).
    cone = Cone.between((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1.0, 0.5)
    assert cone.slope == pytest.approx(-0.5)
    np.testing.assert_allclose(
        cone.gap(np.array([[0.0, 0.0, 1.0], [0.0, 0.8, 1.0], [0.0, 0.0, 2.5]])),
        np.array([0.5, -0.3, -0.25]) / math.sqrt(1.25),
    )


def rotation_about_z(angle, v):
    c, s = math.cos(angle), math.sin(angle)
    return np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]], axis=1)


@pytest.mark.parametrize("index", range(6), ids=[name for name, _ in shapes(3)])
def test_moving_obstacle_carries_its_level_sets(index):
    # Points at gap δ from the static shape, moved by the rigid motion (written out about the
    # z axis), are at gap δ from the moving shape at that time.
    _, static = shapes(3)[index]
    pivot = np.array([0.3, -0.2, 0.1])
    translation = np.array([0.5, -0.1, 0.2])

    def angle(t):
        return 1.3 * t

    motion = RigidMotion(
        3, translation=lambda t: translation * t, angle=angle, axis=(0, 0, 5), pivot=pivot
    )
    moving = type(static).__new__(type(static))
    moving.__dict__.update(static.__dict__)
    moving.motion = motion
    x = random_points(3, 50, seed=3)
    t = 0.6
    moved = rotation_about_z(angle(t), x - pivot) + pivot + translation * t
    np.testing.assert_allclose(moving.gap(moved, t), static.gap(x), atol=1e-13)
    np.testing.assert_allclose(moving.gap(x, 0.0), static.gap(x), atol=1e-15)


def test_rotation_matrix_is_the_rotation_about_its_axis():
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    angle = 0.83
    R = rotation_matrix(angle, axis, 3)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R @ axis, axis, atol=1e-15)
    v = np.cross(axis, (0.0, 0.0, 1.0))
    v /= np.linalg.norm(v)
    w = R @ v
    assert v @ w == pytest.approx(math.cos(angle))
    assert np.cross(v, w) @ axis == pytest.approx(math.sin(angle))


def test_obstacles_evaluate_every_obstacle():
    obstacles = [obstacle for _, obstacle in shapes(3, moving=True)]
    together = Obstacles(obstacles)
    x = random_points(3, 20)
    gaps = together.gaps(x, TIME)
    assert gaps.shape == (len(obstacles), 20)
    for index, obstacle in enumerate(obstacles):
        np.testing.assert_array_equal(gaps[index], obstacle.gap(x, TIME))
    assert len(Obstacles(together)) == len(obstacles)
    assert Obstacles(obstacles[0]).obstacles == [obstacles[0]]


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: Sphere((0.0, 0.0, 0.0), 0.0), "radius"),
        (lambda: Sphere((0.0, 0.0, 0.0, 1.0), 1.0), "center"),
        (lambda: Sphere((0.0, 0.0), 1.0, inside="yes"), "inside"),
        (lambda: HalfSpace((0.0, 0.0, 0.0)), "normal"),
        (lambda: HalfSpace((0.0, 1.0), math.nan), "offset"),
        (lambda: Cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1.0), "axis"),
        (lambda: Cylinder((0.0, 0.0, 0.0), (0.0, 1.0), 1.0), "axis"),
        (lambda: Cone((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1.0, math.inf), "slope"),
        (lambda: Cone.between((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1.0, 0.5), "different"),
        (lambda: RigidMotion(2, axis=(0.0, 0.0, 1.0)), "axis"),
        (lambda: RigidMotion(4), "dimension"),
        (lambda: RigidMotion(3, translation=(1.0, 0.0, 0.0)), "translation"),
        (lambda: Sphere((0.0, 0.0), 1.0, motion=RigidMotion(3)), "3D"),
        (lambda: Obstacles([]), "at least one"),
        (lambda: Obstacles([Sphere((0.0, 0.0), 1.0), Sphere((0.0, 0.0, 0.0), 1.0)]), "dimensions"),
        (lambda: Obstacles([Sphere((0.0, 0.0), 1.0), "wall"]), "not an Obstacle"),
        (lambda: Sphere((0.0, 0.0), 1.0).gap(np.zeros((3, 3))), r"\(n, 2\)"),
        (
            lambda: Sphere((0.0, 0.0), 1.0, motion=RigidMotion(2, translation=lambda t: (t,))).gap(
                np.zeros((1, 2)), 1.0
            ),
            "translation",
        ),
    ],
)
def test_bad_input_is_refused(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_numpy_layer_does_not_load_dolfinx():
    # In a fresh interpreter: this one has DOLFINx loaded by the test configuration.
    root = pathlib.Path(__file__).resolve().parents[2]
    code = (
        "import sys\n"
        "from dolfinx_invertible import contact\n"
        "shapes = [contact.HalfSpace((0, 1), 0), contact.Cone((0, 0), (1, 0), 1, 0)]\n"
        "obstacles = contact.Obstacles(shapes)\n"
        "contact.BarrierPotential(obstacles, contact.Barrier(0.1, 1.0))\n"
        "names = ('dolfinx', 'petsc4py', 'ufl', 'basix')\n"
        "loaded = [name for name in names if name in sys.modules]\n"
        "assert not loaded, loaded\n"
    )
    environment = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")])
    )
    completed = subprocess.run(
        [sys.executable, "-c", code], env=environment, capture_output=True, text=True, timeout=120
    )
    assert completed.returncode == 0, completed.stderr
