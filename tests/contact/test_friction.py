"""Lagged Coulomb friction against obstacles: the closed form of a block on an inclined plane,
derivatives by finite differences, and the drag of a moving obstacle's surface.
"""

import math

from mpi4py import MPI

import dolfinx
import numpy as np
import pytest

import dolfinx_invertible as di
from dolfinx_invertible.contact import Barrier, Cylinder, HalfSpace, Obstacles, RigidMotion
from dolfinx_invertible.contact.friction import ObstacleFriction, mollifier

THETA = math.radians(30.0)
SIDE = 0.1
DENSITY = 1000.0
G = 9.81


def resting_gap(comm, youngs_modulus):
    """The gap at which the barrier carries the block's weight normal to the plane (bisection)."""
    probe = dolfinx.mesh.create_box(comm, [[0, 0, 0], [SIDE] * 3], [2, 2, 2])
    u = dolfinx.fem.Function(di.vector_function_space(probe, 1))
    term = di.contact.ContactTerm(u, [HalfSpace((0, 0, 1), 0.0)], youngs_modulus=youngs_modulus)
    bottom = term.boundary.reference[:, 2] < 1e-12
    area = comm.allreduce(float(term.boundary.weights[bottom].sum()), op=MPI.SUM)
    weight = DENSITY * SIDE**3 * G * math.cos(THETA)
    low, high = 0.0, term.barrier.distance
    for _ in range(100):
        middle = 0.5 * (low + high)
        if -area * term.barrier.derivative(middle) > weight:
            low = middle
        else:
            high = middle
    return 0.5 * (low + high)


def slide(comm, ratio, t_end=0.5, dt=0.01):
    """A block released at rest on a plane tilted by θ (gravity tilted), μ = ratio · tan θ.

    Returns the times and the block's mean displacement along the slope.
    """
    youngs_modulus = 1e6
    gap = resting_gap(comm, youngs_modulus)
    mesh = dolfinx.mesh.create_box(comm, [[0, 0, gap], [SIDE, SIDE, SIDE + gap]], [2, 2, 2])
    u = dolfinx.fem.Function(di.vector_function_space(mesh, 1))
    material = di.Material(di.NeoHookean(*di.lame(youngs_modulus, 0.3)))
    term = di.contact.ContactTerm(
        u, [HalfSpace((0, 0, 1), 0.0)], material, friction=ratio * math.tan(THETA)
    )
    gravity = (G * math.sin(THETA), 0.0, -G * math.cos(THETA))
    dynamics = di.ImplicitDynamics(
        u, material, density=DENSITY, dt=dt, gravity=gravity, terms=[term],
        step_limits=[term.step_limit()], boundary_update=term.set_time,
    )  # fmt: skip
    owned = u.function_space.dofmap.index_map.size_local
    times, positions = [0.0], [0.0]

    def record(t, result):
        local = u.x.array[: 3 * owned : 3]
        total = comm.allreduce((float(local.sum()), len(local)), op=MPI.SUM)
        times.append(t)
        positions.append(total[0] / total[1])

    dynamics.advance(t_end, on_step=record)
    return np.array(times), np.array(positions)


@pytest.mark.mpi
def test_block_slides_down_an_incline_as_coulomb_says():
    """μ = 0.9 tan θ: it slides with a = g (sin θ − μ cos θ) (backward Euler has it exactly)."""
    ratio = 0.9
    times, x = slide(MPI.COMM_WORLD, ratio)
    expected = G * (math.sin(THETA) - ratio * math.tan(THETA) * math.cos(THETA))
    later = times >= 0.1
    acceleration = 2 * np.polyfit(times[later], x[later], 2)[0]
    assert acceleration == pytest.approx(expected, rel=0.01)
    assert x[-1] > 0.5 * 0.5 * expected * 0.4**2


@pytest.mark.mpi
def test_block_sticks_on_an_incline_as_coulomb_says():
    """μ = 1.1 tan θ: it stays, creeping no faster than the friction velocity ε_v."""
    times, x = slide(MPI.COMM_WORLD, 1.1)
    frictionless = 0.5 * G * math.sin(THETA) * times[-1] ** 2
    assert abs(x[-1]) < 2e-3 * times[-1]  # ε_v = 1e-3 m/s: creep, not sliding
    assert abs(x[-1]) < 0.01 * frictionless  # μ = 0.9 tan θ slides a tenth of it


def test_mollifier_is_c1_and_its_derivatives_match():
    threshold = 0.3
    y = np.linspace(0.0, 1.0, 1001)
    value, slope_over_y, curvature = mollifier(y, threshold)
    step = y[1] - y[0]
    slope = slope_over_y * y
    np.testing.assert_allclose(np.gradient(value, step)[1:-1], slope[1:-1], atol=2e-3)
    np.testing.assert_allclose(np.gradient(slope, step)[1:-1], curvature[1:-1], atol=2e-2)
    assert value[0] == pytest.approx(threshold / 3) and slope_over_y[0] == pytest.approx(2 / 0.3)
    assert np.all(y[y >= threshold] == value[y >= threshold])


def test_friction_gradient_and_hessian_match_finite_differences():
    rng = np.random.default_rng(3)
    normal = np.array([0.2, 0.1, 1.0]) / np.linalg.norm([0.2, 0.1, 1.0])
    in_plane = rng.random((40, 3))
    in_plane -= np.outer(in_plane @ normal, normal)
    points = in_plane + np.outer(0.002 + 0.006 * rng.random(40), normal)
    plane = Obstacles([HalfSpace(tuple(normal), 0.0)])
    friction = ObstacleFriction(0.4, velocity=1.0)
    friction.lag(points, np.full(40, 0.01), plane, Barrier(0.01, 5.0), 0.0, 0.01)
    assert friction.active > 0
    # Some points slide past the threshold ε = 0.01, some stay below it.
    moved = points + 0.02 * rng.standard_normal(points.shape)
    direction = rng.standard_normal(points.shape)
    h = 1e-7
    gradient = friction.gradient(moved)
    slope = (friction.energy(moved + h * direction) - friction.energy(moved - h * direction)) / (
        2 * h
    )
    assert slope == pytest.approx(np.sum(gradient * direction), rel=1e-6)
    indices, blocks = friction.hessians(moved)
    product = np.zeros_like(points)
    np.add.at(product, indices, np.einsum("kij,kj->ki", blocks, direction[indices]))
    difference = (
        friction.gradient(moved + h * direction) - friction.gradient(moved - h * direction)
    ) / (2 * h)
    np.testing.assert_allclose(product, difference, atol=1e-5 * np.abs(difference).max())
    assert np.all(np.linalg.eigvalsh(blocks) > -1e-12)


def test_a_turning_roller_drags_the_surface_under_a_vertex():
    """The lagged slip is relative to the obstacle's surface, which a turning roller moves."""
    speed, radius = 2.0, 0.5
    turning = RigidMotion(3, angle=lambda t: speed / radius * t, axis=(0, 1, 0))
    roller = Cylinder((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), radius, motion=turning)
    point = np.array([[0.0, 0.0, radius + 1e-3]])
    friction = ObstacleFriction(1.0)
    friction.lag(point, np.ones(1), Obstacles([roller]), Barrier(0.01, 1.0), 0.0, 1e-3)
    # A vertex that stays put slides relative to the surface by the surface's motion, which
    # the friction force opposes: it pulls the vertex along the surface, along +x here.
    force = -friction.gradient(point)[0]
    assert force[0] > 0 and abs(force[1]) < 1e-12 and abs(force[2]) < 1e-9 * abs(force[0])
