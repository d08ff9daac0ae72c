"""Order of the time integrators (backward Euler, variable-step BDF2) in ImplicitDynamics.

References are independent of solvers/integrators.py: the analytic solution of a linear
oscillator, closed forms of the discrete free-fall trajectories, a recurrence built from the
derivative of the Lagrange interpolant (what variable-step BDF2 is by definition), and a run at a
much finer time step. A step cut is forced through the real cut-and-retry path: an energy term
that poisons the residual with NaN in the first attempt past a given time.
"""

from __future__ import annotations

import math

from mpi4py import MPI

import dolfinx
import numpy as np
import pytest
import ufl

from dolfinx_invertible import C2, Material, NeoHookean, _compat, lame
from dolfinx_invertible.solvers import ImplicitDynamics
from dolfinx_invertible.solvers.stepping import StepController

MU, LAM = lame(400.0, 0.3)
DENSITY = 2.0
GRAVITY = np.array([0.0, 0.0, -9.81])
INITIAL_VELOCITY = np.array([0.3, 0.0, 0.1])


def _material(mu: float = MU, lam: float = LAM):
    return Material(NeoHookean(mu=mu, lam=lam), C2())


def _space(cells: int, comm=MPI.COMM_WORLD):
    mesh = dolfinx.mesh.create_unit_cube(comm, cells, cells, cells)
    return _compat.vector_function_space(mesh, 1)


def _uniform(space, vector) -> dolfinx.fem.Function:
    function = dolfinx.fem.Function(space)
    function.interpolate(lambda x: np.outer(vector, np.ones(x.shape[1])))
    return function


class FailOnce:
    """An energy term whose residual is NaN in the first solve attempt that ends after ``time``.

    Its ``boundary_update`` is the dynamics' hook, called with the end time of every attempt, so
    the dynamics cuts that step and retries it through its own failure path.
    """

    def __init__(self, time: float):
        self.time = time
        self.armed = False
        self.fired = False

    def boundary_update(self, t: float) -> None:
        self.armed = not self.fired and t > self.time * (1.0 + 1e-12)

    def energy(self) -> float:
        return 0.0

    def add_residual(self, residual: np.ndarray) -> None:
        if self.armed and len(residual):
            residual[0] = math.nan
        self.fired = self.fired or self.armed

    def add_tangent(self, matrix, constrained) -> None:
        pass


class VaryingSteps(StepController):
    """Steps of ``nominal`` times PATTERN in turn, the last one clipped to land on the end."""

    PATTERN = (1.0, 0.5, 0.8, 0.6, 1.0, 0.7)

    def size(self, remaining: float = math.inf) -> float:
        step = self.nominal * self.PATTERN[len(self.accepted) % len(self.PATTERN)]
        return remaining if remaining - step <= 1e-9 * self.nominal else step


def _slope(steps, errors) -> float:
    return float(np.polyfit(np.log(steps), np.log(errors), 1)[0])


# --- a linear oscillator: the translation mode of a body on a distributed spring ----------------

OMEGA = 2.0 * math.pi
OSCILLATOR_TIME = 0.25
AMPLITUDE_VELOCITY = np.array([1.0, 0.5, -0.3])


def _oscillator(
    scheme: str,
    dt: float,
    *,
    fail_after: float | None = None,
    controller=None,
    end: float = OSCILLATOR_TIME,
    energies: list | None = None,
):
    """Return the displacement error at ``end`` and the accepted steps.

    A spring ½ρω²∫|u|² dX acts on a free body at rest shape with uniform velocity: the elastic
    force of a translation is zero (F = I), and mass and spring share ∫u·w dX, so the motion
    stays a uniform translation u(t) = v₀ sin(ωt)/ω whatever the material.
    """
    space = _space(1, MPI.COMM_SELF)
    u = dolfinx.fem.Function(space)
    spring = 0.5 * DENSITY * OMEGA**2 * ufl.dot(u, u) * ufl.dx
    options = {}
    if fail_after is not None:
        failing = FailOnce(fail_after)
        options = {"terms": [failing], "boundary_update": failing.boundary_update}
    if controller is not None:
        options["controller"] = controller
    dynamics = ImplicitDynamics(
        u, _material(), density=DENSITY, dt=dt, velocity=_uniform(space, AMPLITUDE_VELOCITY),
        external_energy=spring, scheme=scheme, **options,
    )  # fmt: skip

    def energy(t: float, result) -> None:
        # Kinetic and spring energy per unit mass of the uniform translation.
        displacement, velocity = u.x.array[:3], dynamics.velocity.x.array[:3]
        energies.append(0.5 * (velocity @ velocity + OMEGA**2 * displacement @ displacement))

    dynamics.advance(end, on_step=None if energies is None else energy)
    assert dynamics.time == pytest.approx(end, rel=1e-12)
    exact = AMPLITUDE_VELOCITY * math.sin(OMEGA * end) / OMEGA
    values = u.x.array.reshape(-1, 3)
    return float(np.abs(values - exact).max()), list(dynamics.controller.accepted)


@pytest.mark.parametrize(("scheme", "order"), [("backward-euler", 1), ("bdf2", 2)])
def test_oscillator_converges_at_the_scheme_order(scheme, order):
    steps = [OSCILLATOR_TIME / n for n in (20, 40, 80, 160)]
    errors = [_oscillator(scheme, dt)[0] for dt in steps]
    assert all(np.diff(np.log(errors)) < 0)
    assert _slope(steps, errors) == pytest.approx(order, abs=0.1)
    # Each halving divides the error by about 2^order.
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    np.testing.assert_allclose(ratios, 2.0**order, rtol=0.15)


def test_newmark_oscillator_converges_at_order_two_and_keeps_its_energy():
    """The average-acceleration rule: second order, and no numerical damping at all.

    On a linear oscillator it conserves ½(v² + ω²u²) exactly (backward Euler and BDF2 lose
    it); the error is measured off the peak at t = 0.3 s, where the rule's phase error shows
    at its order (at the peak of sin it would show squared).
    """
    steps = [0.3 / n for n in (24, 48, 96, 192)]
    errors = [_oscillator("newmark", dt, end=0.3)[0] for dt in steps]
    assert _slope(steps, errors) == pytest.approx(2.0, abs=0.1)
    initial = 0.5 * AMPLITUDE_VELOCITY @ AMPLITUDE_VELOCITY
    for scheme, kept in (("newmark", True), ("bdf2", False)):
        energies: list[float] = []
        _oscillator(scheme, 0.02, end=1.0, energies=energies)
        drift = np.abs(np.array(energies) / initial - 1.0).max()
        assert (drift < 1e-9) if kept else (drift > 1e-3), (scheme, drift)


def test_bdf2_with_a_step_cut_in_the_middle_still_converges_at_order_two():
    steps = [OSCILLATOR_TIME / n for n in (20, 40, 80, 160)]
    errors = []
    for dt in steps:
        error, accepted = _oscillator("bdf2", dt, fail_after=0.5 * OSCILLATOR_TIME)
        errors.append(error)
        # The cut happened: one step of dt/2 after the failure; the step grew back to dt, and
        # the last step is the half step left to land on the end time.
        sizes = np.array(accepted) / dt
        assert np.count_nonzero(np.isclose(sizes, 0.5)) == 2
        assert np.count_nonzero(np.isclose(sizes, 1.0)) == len(sizes) - 2
        half = int(np.flatnonzero(np.isclose(sizes, 0.5))[0])
        assert 0.3 * len(sizes) < half < 0.7 * len(sizes) and np.isclose(sizes[-1], 0.5)
    assert _slope(steps, errors) == pytest.approx(2.0, abs=0.1)
    # The cut costs accuracy of the order of one step, not an order.
    uncut = [_oscillator("bdf2", dt)[0] for dt in steps]
    assert np.all(np.array(errors) < 3.0 * np.array(uncut))


def test_bdf2_with_a_different_step_every_time_converges_at_order_two():
    """Step ratios between 0.5 and 2 at every step: the variable-step coefficients at work.

    (The constant-step coefficients (3/2, −2, 1/2)/h lose an order here; after a single cut
    they would not, so the test above alone could not tell them apart.)
    """
    steps = [OSCILLATOR_TIME / n for n in (20, 40, 80, 160)]
    errors = []
    for dt in steps:
        error, accepted = _oscillator("bdf2", dt, controller=VaryingSteps(dt))
        assert len(set(np.round(np.array(accepted[:-1]) / dt, 9))) == len(VaryingSteps.PATTERN) - 1
        errors.append(error)
    assert _slope(steps, errors) == pytest.approx(2.0, abs=0.1)


# --- free fall: the discrete trajectories in closed form ----------------------------------------


def _free_fall(scheme: str, dt: float, steps: int, *, fail_after: float | None = None):
    space = _space(2)
    u = dolfinx.fem.Function(space)
    options = {}
    if fail_after is not None:
        failing = FailOnce(fail_after)
        options = {"terms": [failing], "boundary_update": failing.boundary_update}
    dynamics = ImplicitDynamics(
        u, _material(), density=DENSITY, dt=dt, gravity=GRAVITY, scheme=scheme,
        velocity=_uniform(space, INITIAL_VELOCITY), **options,
    )  # fmt: skip
    history = []
    for _ in range(steps):
        dynamics.step()
        history.append(
            (dynamics.time, u.x.array.reshape(-1, 3).copy(), dynamics.velocity.x.array.copy())
        )
    return dynamics, history


@pytest.mark.mpi
def test_free_fall_matches_discrete_bdf2_exactly():
    """uₙ = v₀nh + g h²(n²/2 + ¾(1 − 3⁻ⁿ)) and vₙ = v₀ + g n h at every node.

    The first step is backward Euler, u₁ = h v₀ + h² g, v₁ = v₀ + h g. The velocities are linear
    in n, on which BDF2 is exact. uₙ minus the exact fall v₀t + g t²/2 solves the homogeneous
    recurrence 3dₙ₊₁ − 4dₙ + dₙ₋₁ = 0 (roots 1 and 1/3) with d₀ = 0, d₁ = g h²/2.
    """
    dt = 0.05
    _, history = _free_fall("bdf2", dt, 6)
    for n, (time, values, velocity) in enumerate(history, start=1):
        assert time == pytest.approx(n * dt, rel=1e-12)
        expected = INITIAL_VELOCITY * n * dt + GRAVITY * dt**2 * (n**2 / 2 + 0.75 * (1 - 3.0**-n))
        np.testing.assert_allclose(values, np.broadcast_to(expected, values.shape), atol=1e-12)
        expected_velocity = INITIAL_VELOCITY + GRAVITY * n * dt
        np.testing.assert_allclose(
            velocity.reshape(-1, 3), np.broadcast_to(expected_velocity, values.shape), atol=1e-11
        )
    # Not the backward-Euler trajectory, nor the exact fall: the test tells them apart.
    n = len(history)
    backward_euler = INITIAL_VELOCITY * n * dt + GRAVITY * dt**2 * n * (n + 1) / 2
    exact = INITIAL_VELOCITY * n * dt + GRAVITY * (n * dt) ** 2 / 2
    final = history[-1][1][0]
    assert np.abs(final - backward_euler).max() > 1e-3
    assert np.abs(final - exact).max() > 1e-3


@pytest.mark.mpi
def test_newmark_free_fall_is_exact_from_the_balanced_initial_acceleration():
    """The trapezoidal rule integrates a constant acceleration exactly: uₙ = v₀t + g t²/2.

    Only if the rule starts from the acceleration the forces give (a₀ = g for a free body at
    rest shape): started from a₀ = 0, every step would carry an error of g h²/4.
    """
    dt = 0.05
    _, history = _free_fall("newmark", dt, 6)
    for n, (time, values, velocity) in enumerate(history, start=1):
        assert time == pytest.approx(n * dt, rel=1e-12)
        t = n * dt
        expected = INITIAL_VELOCITY * t + 0.5 * GRAVITY * t * t
        np.testing.assert_allclose(values, np.broadcast_to(expected, values.shape), atol=1e-10)
        np.testing.assert_allclose(
            velocity.reshape(-1, 3),
            np.broadcast_to(INITIAL_VELOCITY + GRAVITY * t, values.shape),
            atol=1e-9,
        )
    # A start from rest acceleration would lag by g h²/4 per step: far above the tolerance.
    assert np.abs(GRAVITY).max() * dt**2 / 4 > 1e-4


def _interpolant_derivative(times: np.ndarray) -> np.ndarray:
    """Weights w with Σ wⱼ yⱼ = p'(times[-1]) for the polynomial p through (times, y)."""
    weights = []
    for j in range(len(times)):
        unit = np.zeros(len(times))
        unit[j] = 1.0
        weights.append(np.polyval(np.polyder(np.polyfit(times, unit, len(times) - 1)), times[-1]))
    return np.array(weights)


@pytest.mark.mpi
def test_free_fall_with_a_cut_step_matches_the_variable_step_recurrence():
    """With a step cut, every node follows variable-step BDF2 built from Lagrange interpolation."""
    dt = 0.05
    dynamics, history = _free_fall("bdf2", dt, 7, fail_after=2.5 * dt)
    accepted = dynamics.controller.accepted
    assert dynamics.controller.cuts == 1  # FailOnce fails one attempt; its retry succeeds
    assert not np.allclose(accepted, dt)
    times = np.concatenate([[0.0], np.cumsum(accepted)])
    positions = [np.zeros(3)]
    velocities = [INITIAL_VELOCITY.copy()]
    # First step: backward Euler.
    h = accepted[0]
    positions.append(h * INITIAL_VELOCITY + h * h * GRAVITY)
    velocities.append(INITIAL_VELOCITY + h * GRAVITY)
    for n in range(1, len(accepted)):
        c_older, c_previous, c_new = _interpolant_derivative(times[n - 1 : n + 2])
        # v = c_new x + c_previous xₙ + c_older xₙ₋₁ and g = c_new v + c_previous vₙ + c_older vₙ₋₁.
        known_velocity = c_previous * positions[n] + c_older * positions[n - 1]
        new = (
            GRAVITY - c_previous * velocities[n] - c_older * velocities[n - 1]
        ) / c_new**2 - known_velocity / c_new
        positions.append(new)
        velocities.append(c_new * new + known_velocity)
    for n, (time, values, velocity) in enumerate(history, start=1):
        assert time == pytest.approx(times[n], rel=1e-12)
        np.testing.assert_allclose(values, np.broadcast_to(positions[n], values.shape), atol=1e-12)
        np.testing.assert_allclose(
            velocity.reshape(-1, 3), np.broadcast_to(velocities[n], values.shape), atol=1e-10
        )
    # BDF2 is exact on the linear velocities whatever the steps.
    np.testing.assert_allclose(velocities[-1], INITIAL_VELOCITY + GRAVITY * times[-1], atol=1e-12)


# --- a free-flying spinning body: nonlinear in the displacement -----------------------------------

SPIN = np.array([0.0, 0.0, 2.0 * math.pi])
SPIN_TIME = 0.25
# Soft: the centrifugal load stretches the body by about 20 %, and its vibrations are slow
# enough for the steps below to resolve them (the asymptotic range of the orders).
SPIN_MU, SPIN_LAM = lame(100.0, 0.3)


def _spinning(scheme: str, dt: float) -> np.ndarray:
    """Return the nodal displacements at SPIN_TIME of a cube spinning about its axis.

    The velocity is a rigid rotation plus a translation: no supports, so the body turns by a
    quarter turn (rotations are nonlinear in the displacement) while the centrifugal load
    stretches it and sets it vibrating.
    """
    space = _space(1, MPI.COMM_SELF)
    u = dolfinx.fem.Function(space)
    velocity = dolfinx.fem.Function(space)

    def spin(x):
        arm = x - 0.5
        return np.cross(SPIN, arm.T).T + INITIAL_VELOCITY[:, None]

    velocity.interpolate(spin)
    dynamics = ImplicitDynamics(
        u, _material(SPIN_MU, SPIN_LAM), density=DENSITY, dt=dt, velocity=velocity, scheme=scheme
    )
    dynamics.advance(SPIN_TIME)
    return u.x.array.copy()


@pytest.fixture(scope="module")
def spinning_reference():
    return _spinning("bdf2", SPIN_TIME / 1024)


@pytest.mark.parametrize(
    ("scheme", "order", "counts"),
    [
        ("backward-euler", 1, (16, 32, 64, 128)),
        ("bdf2", 2, (32, 64, 128, 256)),
        ("newmark", 2, (16, 32, 64, 128)),
    ],
)
def test_spinning_body_converges_at_the_scheme_order(scheme, order, counts, spinning_reference):
    steps = [SPIN_TIME / n for n in counts]
    errors = [np.linalg.norm(_spinning(scheme, dt) - spinning_reference) for dt in steps]
    # A quarter turn: corners move by about the size of the body, far above the errors.
    assert np.abs(spinning_reference).max() > 0.5
    assert all(np.diff(np.log(errors)) < 0)
    assert _slope(steps, errors) == pytest.approx(order, abs=0.1)
