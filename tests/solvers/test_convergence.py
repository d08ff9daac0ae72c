"""The minimiser's convergence test on its own: the order of its decisions and their reasons."""

from __future__ import annotations

import math

import pytest
from petsc4py import PETSc

from dolfinx_invertible import _compat
from dolfinx_invertible.solvers.convergence import STALL_WINDOW, ConvergenceTest

REASONS = PETSc.SNES.ConvergedReason


class _FixedTolerance:
    """Stands in for the scaled tolerances: an absolute tolerance, and how often it was asked."""

    def __init__(self, value: float):
        self.value = value
        self.asked = 0

    def absolute_tolerance(self) -> float:
        self.asked += 1
        return self.value


def _snes(rtol: float, max_it: int):
    solver = PETSc.SNES().create(comm=PETSc.COMM_SELF)
    solver.setTolerances(rtol=rtol, max_it=max_it)
    yield solver
    solver.destroy()


@pytest.fixture
def snes():
    yield from _snes(1e-6, 5)


def _never(*_):
    return False


def test_absolute_then_relative_then_cap(snes):
    tolerances = _FixedTolerance(1e-8)
    test = ConvergenceTest(tolerances)
    assert test.check(0, 1.0, snes, _never) == REASONS.ITERATING
    assert tolerances.asked == 1 and test.tolerance == 1e-8  # taken once, at the start
    assert test.check(1, 1e-3, snes, _never) == REASONS.ITERATING
    assert test.check(2, 5e-7, snes, _never) == REASONS.CONVERGED_FNORM_RELATIVE  # ≤ 1e-6 · 1
    test.start_solve()
    assert test.check(0, 1e-9, snes, _never) == REASONS.CONVERGED_FNORM_ABS  # no work to do
    test.start_solve()
    test.check(0, 1.0, snes, _never)
    assert test.check(5, 0.5, snes, _never) == REASONS.DIVERGED_MAX_IT
    assert test.failure[1] == "iteration cap" and "after 5 iterations" in test.failure[2]


def test_declared_outcomes_win_and_a_veto_holds_convergence(snes):
    test = ConvergenceTest(_FixedTolerance(1e-8))
    test.check(0, 1.0, snes, _never)
    assert test.check(1, 1e-12, snes, lambda: True) == REASONS.ITERATING  # vetoed
    test.converge("at round-off")
    assert test.check(2, 1.0, snes, _never) == REASONS.CONVERGED_SNORM_RELATIVE
    test.start_solve()
    test.fail(REASONS.DIVERGED_LINE_SEARCH, "line search", "no decrease")
    assert test.check(0, 1e-12, snes, _never) == REASONS.DIVERGED_LINE_SEARCH
    test.start_solve()
    assert test.check(0, math.nan, snes, _never) == _compat.SNES_DIVERGED_NOT_FINITE
    assert test.failure[1] == "NaN"


@pytest.fixture
def patient_snes():
    yield from _snes(1e-12, 1000)


def _run(test, snes, norms, energies, rounding=0.0):
    """Feed the test a solve's history; return the iteration it stopped at and its reason."""
    for iteration, (norm, energy) in enumerate(zip(norms, energies, strict=True)):
        reason = test.check(iteration, norm, snes, _never, energy=energy, rounding=rounding)
        if reason != REASONS.ITERATING:
            return iteration, reason
    return None, REASONS.ITERATING


def test_a_solve_without_progress_stops_after_the_window(patient_snes):
    window = STALL_WINDOW
    test = ConvergenceTest(_FixedTolerance(1e-8))
    flat = [1.0 + 0.01 * (i % 2) for i in range(200)]  # residual oscillates, never halves
    stopped, reason = _run(test, patient_snes, flat, [5.0] * 200)
    assert (stopped, reason) == (window, REASONS.DIVERGED_MAX_IT)
    assert test.failure[1] == "stalled" and f"last {window} iterations" in test.failure[2]
    # An energy that falls by less than its rounding error is no progress either.
    test.start_solve()
    energies = [-1.0e-9 * i for i in range(200)]
    stopped, _ = _run(test, patient_snes, flat, energies, rounding=1.0e-6)
    assert stopped == window and test.failure[1] == "stalled"


def test_a_solve_that_descends_or_converges_slowly_goes_on(patient_snes):
    test = ConvergenceTest(_FixedTolerance(1e-30))
    count = 5 * STALL_WINDOW
    flat = [1.0] * count
    # The residual is flat but the energy keeps falling (a crawl through a non-convex energy).
    descending = [100.0 - 1.0e-4 * i for i in range(count)]
    assert _run(test, patient_snes, flat, descending) == (None, REASONS.ITERATING)
    # The energy is flat but the residual halves once a window (linear convergence).
    test.start_solve()
    slow = [0.5 ** (i / (STALL_WINDOW - 1)) for i in range(count)]
    assert _run(test, patient_snes, slow, [5.0] * count) == (None, REASONS.ITERATING)
    # No energy known (a watchdog's tentative iterates): the progress test does not judge.
    test.start_solve()
    assert _run(test, patient_snes, flat, [None] * count) == (None, REASONS.ITERATING)


def test_the_progress_test_can_be_turned_off(patient_snes):
    test = ConvergenceTest(_FixedTolerance(1e-8))
    test.window = None
    patient_snes.setTolerances(max_it=3 * STALL_WINDOW)
    count = 4 * STALL_WINDOW
    stopped, reason = _run(test, patient_snes, [1.0] * count, [5.0] * count)
    assert (stopped, reason) == (3 * STALL_WINDOW, REASONS.DIVERGED_MAX_IT)
    assert test.failure[1] == "iteration cap"
