"""The barrier potential Σ wᵢ Σₒ b(dₒ(xᵢ)): gradient and exact Hessian by central differences for
every shape (static and moving, 2D and 3D) and a set of two; the projected Hessian is positive
semidefinite and equals the exact one where that already is; infeasible points. No DOLFINx.

Gaps ≥ 0.05 with d̂ = 0.3 and a step of 1e-6: the barrier's derivatives vary on the scale of the
gap, so central differences are good to ~1e-9 relative there; the tolerance is 1e-6.
"""

import math

import numpy as np
import pytest
from contact_helpers import random_points, shapes

from dolfinx_invertible.contact import (
    Barrier,
    BarrierPotential,
    HalfSpace,
    Obstacles,
    Sphere,
    project_blocks,
)

H = 1e-6
TIME = 0.7
BARRIER = Barrier(0.3, 2.0e3)
CASES = [
    (dimension, moving, index)
    for dimension in (2, 3)
    for moving in (False, True)
    for index in range(len(shapes(dimension)))
]
IDS = [f"{d}D-{'moving' if m else 'static'}-{shapes(d)[i][0]}" for d, m, i in CASES]


def near_points(obstacles, dimension, count=40, seed=0):
    """Points with every gap in [0.05, ∞) and most within d̂ of an obstacle, and weights."""
    x = random_points(dimension, 4000, seed=seed)
    gaps = obstacles.gaps(x, TIME)
    feasible = np.all(gaps > 0.05, axis=0)
    near = np.any(gaps < BARRIER.distance, axis=0)
    chosen = np.concatenate(
        [np.flatnonzero(feasible & near)[:count], np.flatnonzero(feasible & ~near)[:3]]
    )
    assert np.count_nonzero(near[chosen]) >= min(count, 20)
    weights = np.random.default_rng(seed).uniform(0.5, 2.0, len(chosen))
    return x[chosen], weights


def obstacle_sets():
    for dimension, moving, index in CASES:
        yield Obstacles(shapes(dimension, moving)[index][1]), dimension
    # Two obstacles acting on the same points: a floor inside a bowl.
    yield (
        Obstacles([HalfSpace((0.0, 0.0, 1.0), -0.6), Sphere((0.0, 0.0, 0.0), 1.0, inside=True)]),
        3,
    )


OBSTACLE_SETS = list(obstacle_sets())
OBSTACLE_SET_IDS = [*IDS, "floor-in-bowl"]


def energy_of_points(potential, x, weights):
    return np.array(
        [potential.energy(point[None], weight[None], TIME) for point, weight in zip(x, weights)]
    )


@pytest.mark.parametrize("obstacles, dimension", OBSTACLE_SETS, ids=OBSTACLE_SET_IDS)
def test_gradient_and_exact_hessian_by_central_differences(obstacles, dimension):
    potential = BarrierPotential(obstacles, BARRIER)
    x, weights = near_points(obstacles, dimension)
    gradient = potential.gradient(x, weights, TIME)
    points, blocks = potential.hessians(x, weights, TIME, project=False)
    full = np.zeros((len(x), dimension, dimension))
    full[points] = blocks
    # Each point's energy depends on that point only: differentiate point by point.
    scale = np.max(np.abs(gradient))
    for k in range(dimension):
        step = np.zeros(dimension)
        step[k] = H
        fd = (
            energy_of_points(potential, x + step, weights)
            - energy_of_points(potential, x - step, weights)
        ) / (2 * H)
        np.testing.assert_allclose(gradient[:, k], fd, rtol=0, atol=1e-6 * scale)
        fd_block = (
            potential.gradient(x + step, weights, TIME)
            - potential.gradient(x - step, weights, TIME)
        ) / (2 * H)
        np.testing.assert_allclose(
            full[:, :, k], fd_block, rtol=0, atol=1e-6 * np.max(np.abs(full))
        )
    assert potential.energy(x, weights, TIME) == pytest.approx(
        np.sum(energy_of_points(potential, x, weights))
    )
    # Points beyond d̂ of every obstacle contribute nothing.
    far = np.all(obstacles.gaps(x, TIME) >= BARRIER.distance, axis=0)
    assert (
        far.any()
        and np.all(gradient[far] == 0.0)
        and not np.isin(np.flatnonzero(far), points).any()
    )


@pytest.mark.parametrize("obstacles, dimension", OBSTACLE_SETS, ids=OBSTACLE_SET_IDS)
def test_projected_hessian_is_positive_semidefinite(obstacles, dimension):
    potential = BarrierPotential(obstacles, BARRIER)
    x, weights = near_points(obstacles, dimension, seed=4)
    points, exact = potential.hessians(x, weights, TIME, project=False)
    same, projected = potential.hessians(x, weights, TIME)
    np.testing.assert_array_equal(points, same)
    np.testing.assert_allclose(
        projected, np.swapaxes(projected, 1, 2), atol=1e-12 * np.max(np.abs(projected))
    )
    eigenvalues = np.linalg.eigvalsh(projected)
    assert np.all(eigenvalues >= -1e-12 * np.max(np.abs(projected)))
    # Along the gap's gradient the barrier is always stiff: b″ |∇d|² w > 0 there.
    assert np.all(eigenvalues[:, -1] > 0.0)
    exact_eigenvalues = np.linalg.eigvalsh(exact)
    definite = np.all(exact_eigenvalues >= 0.0, axis=1)
    np.testing.assert_allclose(
        projected[definite], exact[definite], atol=1e-10 * np.max(np.abs(exact))
    )
    if isinstance(obstacles[0], Sphere) and not obstacles[0].inside:
        # A ball curves towards the body: b′∇²d is negative, the projection must act.
        assert not definite.all()


def test_project_blocks_keeps_the_positive_part():
    rng = np.random.default_rng(3)
    vectors, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    values = np.array([-2.0, 0.5, 3.0])
    block = vectors @ np.diag(values) @ vectors.T
    expected = vectors @ np.diag([0.0, 0.5, 3.0]) @ vectors.T
    np.testing.assert_allclose(project_blocks(block[None])[0], expected, atol=1e-14)


def test_points_on_or_inside_an_obstacle_are_infeasible():
    potential = BarrierPotential(HalfSpace((0.0, 1.0), 0.0), BARRIER)
    x = np.array([[0.0, 0.1], [0.0, 0.0], [0.0, -0.2], [0.0, 5.0]])
    weights = np.ones(4)
    assert potential.energy(x, weights) == math.inf
    gradient = potential.gradient(x, weights)
    assert np.all(np.isfinite(gradient[[0, 3]])) and np.all(np.isnan(gradient[[1, 2]]))
    points, _ = potential.hessians(x, weights)
    np.testing.assert_array_equal(points, [0])
    assert math.isfinite(potential.energy(x[[0, 3]], weights[:2]))


def test_bad_input_is_refused():
    potential = BarrierPotential(HalfSpace((0.0, 1.0), 0.0), BARRIER)
    with pytest.raises(ValueError, match="positions"):
        potential.energy(np.zeros((2, 3)), np.ones(2))
    with pytest.raises(ValueError, match="weights"):
        potential.energy(np.ones((2, 2)), np.ones(3))
    with pytest.raises(ValueError, match="Barrier"):
        BarrierPotential(HalfSpace((0.0, 1.0), 0.0), 0.1)
