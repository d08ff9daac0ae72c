"""The minimiser's convergence test on its own: the order of its decisions and their reasons."""

from __future__ import annotations

import math

import pytest
from petsc4py import PETSc

from dolfinx_invertible import _compat
from dolfinx_invertible.solvers.convergence import ConvergenceTest

REASONS = PETSc.SNES.ConvergedReason


class _FixedTolerance:
    """Stands in for the scaled tolerances: an absolute tolerance, and how often it was asked."""

    def __init__(self, value: float):
        self.value = value
        self.asked = 0

    def absolute_tolerance(self) -> float:
        self.asked += 1
        return self.value


@pytest.fixture
def snes():
    solver = PETSc.SNES().create(comm=PETSc.COMM_SELF)
    solver.setTolerances(rtol=1e-6, max_it=5)
    yield solver
    solver.destroy()


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
