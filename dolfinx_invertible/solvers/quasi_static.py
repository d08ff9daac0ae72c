"""Quasi-static load stepping: equilibria of a load ramped over a pseudo-time t from 0 to 1.

:class:`QuasiStatic` is the :class:`~dolfinx_invertible.solvers.stepper.Stepper` of a problem
without mass: each step sets the loads of its end (``update_load(t)``) and solves for
equilibrium from the previous solution; a failed step restores the last converged solution and
load and is cut; easy steps grow back, never past the largest spacing of the targets nor past
the next target, so every target is hit exactly. :func:`solve_load_steps` is the one-call form.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import dolfinx.fem
import numpy as np

from dolfinx_invertible.solvers.monitors import StepAttempt
from dolfinx_invertible.solvers.results import SolverError, SolveResult
from dolfinx_invertible.solvers.stepper import Stepper
from dolfinx_invertible.solvers.stepping import Solvable, StepController

__all__ = ["QuasiStatic", "load_targets", "solve_load_steps"]


def load_targets(steps: int | Sequence[float]) -> list[float]:
    """Return the target pseudo-times of ``steps``: a count of equal steps, or the targets.

    ``ValueError`` unless ``steps`` is an int ≥ 1 or strictly increasing pseudo-times in
    (0, 1] ending with 1.
    """
    if isinstance(steps, (int, np.integer)) and not isinstance(steps, bool):
        if steps < 1:
            raise ValueError(f"steps: need at least 1 load step, got {steps}")
        return [(index + 1) / int(steps) for index in range(int(steps))]
    try:
        if isinstance(steps, (bool, str, bytes)):
            raise TypeError
        targets = [float(value) for value in steps]
    except TypeError:
        raise ValueError(
            f"steps: expected an int or a sequence of pseudo-times, got {steps!r}"
        ) from None
    if not targets:
        raise ValueError("steps: the sequence of pseudo-times is empty")
    if any(not (0.0 < value <= 1.0) for value in targets):
        raise ValueError(f"steps: pseudo-times must lie in (0, 1], got {targets}")
    if any(later <= earlier for earlier, later in zip(targets[:-1], targets[1:], strict=True)):
        raise ValueError(f"steps: pseudo-times must increase strictly, got {targets}")
    if targets[-1] != 1.0:
        raise ValueError(f"steps: the last pseudo-time must be 1, got {targets[-1]}")
    return targets


class QuasiStatic(Stepper):
    """Load steps of a problem over a pseudo-time t in [0, 1], cutting steps on failure.

    Parameters
    ----------
    problem
        A :class:`~dolfinx_invertible.HyperelasticProblem` or an
        :class:`~dolfinx_invertible.EnergyMinimizer` (any
        :class:`~dolfinx_invertible.solvers.stepping.Solvable`); its ``u`` holds the state at
        t = 0.
    update_load
        Sets the loads and boundary values for a pseudo-time in [0, 1] (e.g. Constants scaled
        by t).
    steps
        Number of equal steps, or increasing target pseudo-times in (0, 1] ending with 1.
    max_cuts
        Largest number of consecutive cuts before giving up (when no ``controller`` is given).
    controller
        The step policy; by default a :class:`~dolfinx_invertible.StepController` whose
        nominal step is the largest spacing of the targets.

    Attributes
    ----------
    targets
        The pseudo-times every run of the steps lands on.
    previous
        The last converged solution (the state), a Function on the space of ``u``.
    """

    step_name = "load step"

    def __init__(
        self,
        problem: Solvable,
        update_load: Callable[[float], None],
        steps: int | Sequence[float],
        *,
        max_cuts: int = 6,
        controller: StepController | None = None,
    ) -> None:
        self.targets = load_targets(steps)
        if controller is None:
            spacing = max(np.diff([0.0, *self.targets]))
            controller = StepController(spacing, max_cuts=max_cuts)
        super().__init__(problem, controller, update_load)
        self.previous = dolfinx.fem.Function(self.u.function_space)
        self.previous.x.array[:] = self.u.x.array
        self._target = self.targets[0]

    def _index(self) -> int:
        """Return the 1-based index of the target the next step heads for."""
        return next(
            (index for index, target in enumerate(self.targets, 1) if target > self.time),
            len(self.targets),
        )

    def step(self, remaining: float = math.inf) -> SolveResult:
        """Take one step towards the next target (at most ``remaining``), cutting on failure.

        Raises
        ------
        SolverError
            The cuts ran out; the solution and the load are those of the last converged
            pseudo-time.
        """
        index = self._index()
        self._target = self.targets[index - 1]
        try:
            return super().step(min(remaining, self._target - self.time))
        except SolverError as error:
            error.step_index = index
            raise

    def _attempt(self, start: float, end: float) -> SolveResult:
        self._set_time(end)
        return self.problem.solve()

    def _restore(self, start: float) -> None:
        self.u.x.array[:] = self.previous.x.array
        self.u.x.scatter_forward()
        self._set_time(start)

    def _commit(self, size: float) -> None:
        self.time = self._target if size == self._target - self.time else self.time + size
        self.previous.x.array[:] = self.u.x.array

    def _failure(self, start: float, end: float, result: SolveResult) -> str:
        return (
            f"load step {self._index()} of {len(self.targets)} failed "
            f"{self.controller.consecutive_cuts} times in a row, the step cut each time, last at "
            f"pseudo-time {end:.6g}: {result.describe()}; last converged pseudo-time "
            f"{start:.6g}, to which the solution and the load are restored"
        )

    def checkpoint_fields(self) -> dict[str, Any]:
        """Return the last converged solution."""
        return {"displacement": self.previous}

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from a checkpoint: :meth:`checkpoint_fields` hold its Functions already."""
        super().restore(state)
        self.u.x.array[:] = self.previous.x.array
        self._set_time(self.time)


def solve_load_steps(
    solver: Solvable,
    update_load: Callable[[float], None],
    steps: int | Sequence[float],
    *,
    max_cuts: int = 6,
    on_step: Callable[[float, SolveResult], None] | None = None,
    controller: StepController | None = None,
    on_attempt: Callable[[StepAttempt], None] | None = None,
) -> list[SolveResult]:
    """Quasi-static load stepping over a pseudo-time t from 0 to 1 (:class:`QuasiStatic`).

    Parameters
    ----------
    solver
        An :class:`~dolfinx_invertible.solvers.minimizer.EnergyMinimizer` or a
        :class:`~dolfinx_invertible.solvers.hyperelastic.HyperelasticProblem`
        (any :class:`~dolfinx_invertible.solvers.stepping.Solvable`); its ``u`` holds the
        state at t = 0 on entry.
    update_load
        Sets the load for a pseudo-time in [0, 1].
    steps
        Number of equal steps, or increasing target pseudo-times in (0, 1] ending with 1.
    max_cuts
        Largest number of consecutive cuts before giving up (when no ``controller`` is given).
    on_step
        Called as ``on_step(t, result)`` after every converged (sub)step, e.g. to write output
        that survives a later failure.
    controller
        The step policy; by default a :class:`~dolfinx_invertible.StepController` whose
        nominal step is the largest spacing of the targets.
    on_attempt
        Called after every attempt of a step, accepted or not (see
        :func:`~dolfinx_invertible.solvers.stepping.take_step`).

    Returns
    -------
    list of SolveResult
        One per converged (sub)step, in order.

    Raises
    ------
    SolverError
        Newton still failed after ``max_cuts`` consecutive cuts. The state and load are those of
        the last converged pseudo-time.
    ValueError
        Invalid ``steps`` or ``max_cuts``.
    """
    stepper = QuasiStatic(solver, update_load, steps, max_cuts=max_cuts, controller=controller)
    if on_attempt is not None:
        stepper.add_monitor(on_attempt=on_attempt)
    return stepper.advance(1.0, on_step=on_step)
