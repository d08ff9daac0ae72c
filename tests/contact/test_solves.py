"""Contact in solves: a block resting on the ground carries its weight (quasi-static, every
material and extension, P1 and P2, 2D and 3D), a dropped cube never penetrates the ground at any
Newton iterate, moving obstacles press and push, and the distributed solves equal the serial
ones.
"""

import math

from mpi4py import MPI

import dolfinx
import numpy as np
import pytest
import ufl
from contact_meshes import box, displacement, symmetry_conditions
from dolfinx_helpers import values_at_points

import dolfinx_invertible as di
from dolfinx_invertible.contact import ContactTerm, HalfSpace, RigidMotion, Sphere

COMM = MPI.COMM_WORLD
DENSITY = 1000.0
GRAVITY = 9.81
MU, LAM = di.lame(E=1.0e5, nu=0.3)
EXTENSIONS = {"none": None, "C1": di.C1(eps=0.4), "C2": di.C2(eps=0.9), "IFE": di.IFE()}


def material(model="NeoHookean", extension="C2"):
    model = getattr(di, model)(mu=MU, lam=LAM)
    return di.Material(model, extension=EXTENSIONS[extension])


def resting_block(
    comm, body, degree=1, dimension=3, cell="tetrahedron", floor_gap=0.01, quadrature_degree=None
):
    """A block of height 0.5 on the floor z = 0 (y = 0 in 2D), released at ``floor_gap``.

    Symmetry conditions on the mid-planes x = 0 (and y = 0) remove the horizontal rigid modes
    without carrying any vertical load.
    """
    if dimension == 3:
        mesh = box(comm, [-0.5, -0.5, floor_gap], [0.5, 0.5, 0.5 + floor_gap], [4, 4, 2], cell)
        planes = [(0, 0.0), (1, 0.0)]
    else:
        mesh = box(comm, [-0.5, floor_gap], [0.5, 0.5 + floor_gap], [6, 3], cell)
        planes = [(0, 0.0)]
    u = displacement(mesh, degree)
    up = np.eye(dimension)[-1]
    term = ContactTerm(u, HalfSpace(up, 0.0), body)
    gravity = dolfinx.fem.Constant(mesh, -GRAVITY * up)
    problem = di.HyperelasticProblem(
        u,
        body,
        symmetry_conditions(u.function_space, planes),
        external_energy=-DENSITY * ufl.dot(gravity, u) * ufl.dx,
        terms=[term],
        step_limits=[term.step_limit()],
        petsc_options={"snes_rtol": 1e-11},
        quadrature_degree=quadrature_degree,
    )
    return problem, term, u


def check_resting(problem, term, dimension):
    result = problem.solve()
    assert result.converged, result.describe()
    weight = DENSITY * GRAVITY * 0.5 * 1.0 ** (dimension - 1)
    force = term.contact_force()
    assert force[-1] == pytest.approx(weight, rel=1e-6)
    np.testing.assert_allclose(force[:-1], 0.0, atol=1e-9 * weight)
    gaps = np.concatenate(term.comm.allgather(term.gaps()[0]))
    bottom = np.concatenate(term.comm.allgather(term.positions()[:, -1] < 0.1))
    assert np.all(gaps > 0.0)
    assert np.all(gaps[bottom] < term.barrier.distance)
    assert term.penetrations() == 0
    return result


@pytest.mark.mpi
def test_block_resting_on_the_ground_carries_its_weight():
    problem, term, _ = resting_block(COMM, material())
    result = check_resting(problem, term, 3)
    assert result.newton_iterations > 2  # contact had to be found, not given
    # The 5 × 5 vertices of the bottom face of the 4 × 4 × 2 block, each within d̂ of the floor
    # (check_resting); the next layer of vertices is 0.25 higher.
    assert term.active_vertices() == 25


@pytest.mark.parametrize(
    "model, extension",
    [
        ("NeoHookean", "none"),
        ("NeoHookean", "C1"),
        ("NeoHookean", "IFE"),
        ("FixedCorotated", "C2"),
        ("StableNeoHookean", "none"),
        ("StVK", "C2"),
    ],
)
def test_every_material_rests_on_the_ground(model, extension):
    problem, term, _ = resting_block(COMM, material(model, extension))
    check_resting(problem, term, 3)


# Hexahedra and P2 quadrilaterals need full integration (2 and 4): the default degrees (1, 2)
# leave hourglass modes that no Dirichlet condition here removes.
@pytest.mark.parametrize(
    "degree, dimension, cell, quadrature_degree",
    [
        (2, 3, "tetrahedron", None),
        (1, 3, "hexahedron", 2),
        (1, 2, "triangle", None),
        (2, 2, "triangle", None),
        (2, 2, "quadrilateral", 4),
    ],
)
def test_resting_with_other_elements_and_in_2d(degree, dimension, cell, quadrature_degree):
    problem, term, _ = resting_block(
        COMM, material(), degree, dimension, cell, quadrature_degree=quadrature_degree
    )
    check_resting(problem, term, dimension)


@pytest.mark.mpi
def test_resting_block_distributed_equals_serial():
    solutions = []
    for comm in (COMM, MPI.COMM_SELF):
        problem, term, u = resting_block(comm, material())
        check_resting(problem, term, 3)
        probes = np.array([[0.3, 0.2, 0.011], [-0.5, 0.5, 0.26], [0.1, -0.4, 0.51]])
        solutions.append((values_at_points(u, probes), term.minimum_gap()))
    (distributed, gap), (serial, serial_gap) = solutions
    np.testing.assert_allclose(distributed, serial, rtol=0, atol=1e-8 * np.abs(serial).max())
    assert gap == pytest.approx(serial_gap, rel=1e-7)


def drop(comm, steps=30, on_iterate=None):
    """A cube of side 0.4 falling from 0.1 above the ground, backward Euler, dt = 0.01."""
    mesh = box(comm, [-0.2, -0.2, 0.1], [0.2, 0.2, 0.5], [3, 3, 3])
    u = displacement(mesh)
    body = material()
    term = ContactTerm(u, HalfSpace((0.0, 0.0, 1.0), 0.0), body)
    dynamics = di.ImplicitDynamics(
        u,
        body,
        density=DENSITY,
        dt=0.01,
        gravity=(0.0, 0.0, -GRAVITY),
        terms=[term],
        step_limits=[term.step_limit()],
        boundary_update=term.set_time,
    )
    if on_iterate is not None:
        dynamics.add_monitor(on_iteration=lambda record: on_iterate(term, record))
    history = []
    for _ in range(steps):
        dynamics.step()
        history.append((term.minimum_gap(), term.contact_force()[2]))
    return np.array(history), dynamics, term


@pytest.mark.mpi
def test_dropped_cube_never_penetrates_at_any_newton_iterate():
    seen = {"iterates": 0, "penetrations": 0, "smallest": math.inf}

    def check(term, record):
        # u holds the iterate during the call.
        seen["iterates"] += 1
        seen["penetrations"] += term.penetrations()
        seen["smallest"] = min(seen["smallest"], term.minimum_gap())

    history, dynamics, term = drop(COMM, on_iterate=check)
    assert seen["penetrations"] == 0
    assert seen["smallest"] > 0.0
    # 30 steps, each monitored at its start and after at least one Newton iteration (the cube
    # moves: no step starts at its solution), give 60; the impact takes more. Regression pin:
    # observed 109 on 2026-12-04 (a5eadce) with
    # pytest tests/contact/test_solves.py -k dropped_cube_never_penetrates
    assert seen["iterates"] > 60
    # It hit (t ≈ 0.14 s at 1.4 m/s: more than its weight) and was stopped.
    weight = DENSITY * 0.4**3 * GRAVITY
    assert history[:, 1].max() > 2.0 * weight
    assert np.all(history[:, 0] > 0.0)
    assert history[:, 0].min() < term.barrier.distance
    # regression pin: observed 0 on 2026-12-04 (a5eadce) with
    # pytest tests/contact/test_solves.py -k dropped_cube_never_penetrates
    assert dynamics.controller.cuts == 0


@pytest.mark.mpi
def test_dropped_cube_distributed_equals_serial():
    distributed, _, _ = drop(COMM, steps=20)
    serial, _, _ = drop(MPI.COMM_SELF, steps=20)
    np.testing.assert_allclose(distributed[:, 0], serial[:, 0], rtol=1e-6)
    np.testing.assert_allclose(
        distributed[:, 1], serial[:, 1], rtol=1e-6, atol=1e-6 * serial[:, 1].max()
    )
    assert serial[:, 1].max() > 0.0


@pytest.mark.mpi
def test_descending_plate_presses_the_block_into_the_ground():
    # The plate moves 0.06 down per pseudo-time unit, four load steps of 0.015 each: more than
    # the gap it leaves, so each step starts with the top layer swept and separated.
    body = material()
    problem, term, u = resting_block(COMM, body)
    floor = term.obstacles[0]
    plate = HalfSpace(
        (0.0, 0.0, -1.0),
        -0.515,
        motion=RigidMotion(3, translation=lambda t: (0.0, 0.0, -0.06 * t)),
    )
    term = ContactTerm(u, [floor, plate], body)
    problem = di.HyperelasticProblem(
        u,
        body,
        problem.energy_problem.bcs,
        external_energy=-DENSITY
        * ufl.dot(dolfinx.fem.Constant(u.function_space.mesh, np.array([0.0, 0.0, -GRAVITY])), u)
        * ufl.dx,
        terms=[term],
        step_limits=[term.step_limit()],
        petsc_options={"snes_rtol": 1e-11},
    )
    moved = []

    def update(t):
        term.set_time(t)
        moved.append(term.separate())

    results = di.solve_load_steps(problem, update, 4)
    assert all(result.converged for result in results)
    assert sum(moved) > 0
    assert term.penetrations() == 0
    weight = DENSITY * GRAVITY * 0.5
    ground, pressing = term.contact_force(0), term.contact_force(1)
    assert -pressing[2] > weight  # the plate pushes down harder than gravity
    assert ground[2] + pressing[2] == pytest.approx(weight, rel=1e-6)


def ball_and_block(top, cells, centre, velocity, project_hessian=None):
    """A block of 0.4 × 0.4 × ``top`` on the ground and a ball of radius 0.2 moving through it.

    Returns the dynamics (dt = 0.01 s, gravity) and the contact term (ground first, ball second),
    whose ``boundary_update`` separates the vertices the ball sweeps over.
    """
    mesh = box(COMM, [-0.2, -0.2, 0.005], [0.2, 0.2, 0.005 + top], cells)
    u = displacement(mesh)
    body = material()
    motion = RigidMotion(3, translation=lambda t: tuple(v * t for v in velocity))
    ball = Sphere(centre, 0.2, motion=motion)
    term = ContactTerm(
        u, [HalfSpace((0.0, 0.0, 1.0), 0.0), ball], body, project_hessian=project_hessian
    )

    def update(t):
        term.set_time(t)
        term.separate()

    dynamics = di.ImplicitDynamics(
        u,
        body,
        density=DENSITY,
        dt=0.01,
        gravity=(0.0, 0.0, -GRAVITY),
        terms=[term],
        step_limits=[term.step_limit()],
        boundary_update=update,
    )
    return dynamics, term


@pytest.mark.mpi
def test_ball_hits_a_resting_block_and_pushes_it():
    # A ball of radius 0.2 at 2 m/s along x, starting 0.02 from the block's side: 2 cm per
    # step, far more than any contact gap; boundary_update separates the swept vertices.
    dynamics, term = ball_and_block(0.4, [3, 3, 3], (-0.42, 0.0, 0.2), (2.0, 0.0, 0.0))
    seen = {"penetrations": 0}

    def check(record):
        # u holds the iterate during the call.
        seen["penetrations"] += term.penetrations()

    dynamics.add_monitor(on_iteration=check)
    pushed = []
    for _ in range(8):
        dynamics.step()
        pushed.append(term.contact_force(1)[0])
    assert seen["penetrations"] == 0
    assert max(pushed) > 0.0
    velocity = values_at_points(dynamics.velocity, np.array([[0.2, 0.0, 0.2]]))[0]
    assert velocity[0] > 0.5  # the block moves along with the ball


def _ball_pressing_a_block(project_hessian, steps=6):
    """Newton iterations per step of a ball (a convex obstacle) descending onto a block."""
    dynamics, term = ball_and_block(
        0.2, [4, 4, 2], (0.05, 0.03, 0.43), (0.0, 0.0, -1.0), project_hessian
    )
    iterations = [dynamics.step().newton_iterations for _ in range(steps)]
    return iterations, term.contact_force(1), term.u


@pytest.mark.mpi
def test_barrier_follows_the_exact_tangent_in_newtons_local_phase():
    # Along the ball's surface the barrier is concave, so its projected Hessian misses curvature
    # and Newton converges only linearly at the end; following the problem's tangent (exact
    # after a full step, projected where the exact direction is no descent) converges
    # quadratically there, to the same solution.
    follows, force, u = _ball_pressing_a_block(None)
    projected, projected_force, projected_u = _ball_pressing_a_block(True)
    assert force[2] < -100.0  # the ball presses the block
    assert all(a <= b for a, b in zip(follows, projected)), (follows, projected)
    assert sum(follows) < sum(projected), (follows, projected)
    np.testing.assert_allclose(force, projected_force, rtol=1e-6)
    points = np.array([[0.05, 0.03, 0.205], [0.2, 0.2, 0.005], [-0.2, 0.0, 0.1]])
    np.testing.assert_allclose(
        values_at_points(u, points), values_at_points(projected_u, points), rtol=1e-6, atol=1e-9
    )
