"""The one protocol of load stepping and time stepping: a :class:`Stepper` advances a problem.

A stepper holds a state at a (pseudo-)time, and :meth:`Stepper.advance` takes accepted steps to
an end time under a :class:`~dolfinx_invertible.solvers.stepping.StepController`: each step is
attempted, cut and retried when its solve fails, and grows back after easy steps. Its siblings
differ only in what a step is:

- :class:`~dolfinx_invertible.solvers.quasi_static.QuasiStatic`: load steps over a pseudo-time
  in [0, 1], each an equilibrium of the loads at its end;
- :class:`~dolfinx_invertible.solvers.dynamics.ImplicitDynamics`: time steps of an implicit
  integrator, each the minimiser of an incremental potential.

Both are watched the same way (:meth:`Stepper.add_monitor`) and continue from a checkpoint the
same way (:meth:`Stepper.checkpoint_fields`, :meth:`Stepper.checkpoint_state`,
:meth:`Stepper.restore`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from dolfinx_invertible.solvers.monitors import MonitorList, NewtonIteration, StepAttempt, StepCap
from dolfinx_invertible.solvers.results import SolveResult
from dolfinx_invertible.solvers.stepping import StepController, take_step

__all__ = ["Stepper"]


class Stepper:
    """Advance a state step by step under a step controller (base class).

    Parameters
    ----------
    problem
        What solves a step: a :class:`~dolfinx_invertible.HyperelasticProblem` or any
        :class:`~dolfinx_invertible.solvers.stepping.Solvable` (an object with ``u`` and
        ``solve()``; ``add_monitor`` and ``escalate`` are used where it has them).
    controller
        The step policy.
    update
        ``update(t)`` sets what depends on the (pseudo-)time (loads, Dirichlet values, moving
        obstacles) for time ``t``; called before every attempt with its end time, when ``u``
        holds the attempt's initial guess, which it may adjust, and with the step's start after
        a failed attempt.

    Attributes
    ----------
    problem, controller
        As given.
    u
        The problem's unknown.
    time
        (Pseudo-)time of the current state.
    steps
        Accepted steps so far.
    """

    #: What a step is called in messages ("time step", "load step").
    step_name = "step"

    def __init__(
        self,
        problem,
        controller: StepController,
        update: Callable[[float], None] | None = None,
    ) -> None:
        self.problem = problem
        self.u = problem.u
        self.controller = controller
        self.update = update
        self.time = 0.0
        self.steps = 0
        self._on_attempt = MonitorList()

    # -- what a sibling defines ---------------------------------------------------------------
    def _attempt(self, start: float, end: float) -> SolveResult:
        """Set up the step from ``start`` to ``end`` (initial guess, loads) and solve it."""
        raise NotImplementedError

    def _restore(self, start: float) -> None:
        """Put back the state and the loads of ``start`` after a failed attempt."""
        raise NotImplementedError

    def _commit(self, size: float) -> None:
        """Make the converged attempt of ``size`` the new state."""
        raise NotImplementedError

    def _check(self) -> Callable[[SolveResult], str | None] | None:
        """Return a test of a converged attempt (a reason to reject it), or None."""
        return None

    def checkpoint_fields(self) -> dict[str, Any]:
        """Return the Functions of the state a continued run needs, by name."""
        raise NotImplementedError

    # -- shared -------------------------------------------------------------------------------
    @property
    def solver(self):
        """The :class:`~dolfinx_invertible.EnergyMinimizer` that solves every step."""
        return getattr(self.problem, "solver", self.problem)

    @property
    def kinetic_energy(self) -> float | None:
        """Kinetic energy of the current state; ``None`` where there is no mass."""
        return None

    def add_monitor(
        self,
        *,
        on_iteration: Callable[[NewtonIteration], None] | None = None,
        on_step_cap: Callable[[StepCap], None] | None = None,
        on_attempt: Callable[[StepAttempt], None] | None = None,
    ) -> Callable[[], None]:
        """Observe Newton iterations, step caps and every attempt of a step.

        ``on_iteration`` and ``on_step_cap`` see the minimiser of every step (see
        :meth:`~dolfinx_invertible.solvers.minimizer.EnergyMinimizer.add_monitor`);
        ``on_attempt`` gets a :class:`~dolfinx_invertible.solvers.monitors.StepAttempt` after
        every attempt, accepted or not. Returns a function that removes them again.
        """
        removers = []
        if on_iteration is not None or on_step_cap is not None:
            removers.append(
                self.problem.add_monitor(on_iteration=on_iteration, on_step_cap=on_step_cap)
            )
        if on_attempt is not None:
            removers.append(self._on_attempt.add(on_attempt))

        def remove() -> None:
            for remover in removers:
                remover()

        return remove

    def escalate(self) -> bool:
        """Switch the solver to its more robust mode; ``False`` if it has none or is in it."""
        escalate = getattr(self.problem, "escalate", None)
        return escalate is not None and escalate()

    def _set_time(self, t: float) -> None:
        if self.update is not None:
            self.update(t)

    def _failure(self, start: float, end: float, result: SolveResult) -> str:
        return (
            f"{self.step_name} {self.steps + 1} from t = {start:.6g} failed "
            f"{self.controller.consecutive_cuts} times (last step {end - start:.3g}): "
            f"{result.describe()}"
        )

    def step(self, remaining: float = math.inf) -> SolveResult:
        """Take one step (at most ``remaining``), cutting and retrying it on failure.

        Raises
        ------
        SolverError
            The cuts ran out; the state and the time are those of the last accepted step.
        """
        try:
            size, result = take_step(
                self.controller,
                self.time,
                remaining,
                self._attempt,
                self._restore,
                self._failure,
                self._check(),
                escalate=self.escalate,
                on_attempt=self._on_attempt if self._on_attempt else None,
            )
        except Exception as error:
            if hasattr(error, "step_index"):
                error.step_index = self.steps + 1
            raise
        self._commit(size)
        self.steps += 1
        return result

    def advance(
        self, end: float, on_step: Callable[[float, SolveResult], None] | None = None
    ) -> list[SolveResult]:
        """Step until ``end``, the last step landing on it.

        ``on_step(t, result)`` is called after every accepted step, so output written there
        survives a later failure.
        """
        results = []
        while self.time < end - 1e-12 * max(1.0, abs(end)):
            result = self.step(end - self.time)
            results.append(result)
            if on_step is not None:
                on_step(self.time, result)
        return results

    def checkpoint_state(self) -> dict[str, Any]:
        """Return the time, the step count, the step controller and the solver's mode (JSON)."""
        solver = self.solver
        return {
            "time": self.time,
            "steps": self.steps,
            "controller": self.controller.state(),
            "escalated": getattr(solver, "blend_after", None) == 0,
        }

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from a checkpoint: :meth:`checkpoint_fields` hold its Functions already."""
        self.time = float(state["time"])
        self.steps = int(state["steps"])
        self.controller.restore(state["controller"])
        if state["escalated"]:
            self.escalate()
