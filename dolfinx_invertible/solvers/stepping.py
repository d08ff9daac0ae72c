"""Step control shared by quasi-static load stepping and implicit time stepping.

:class:`StepController` is the one cut-and-retry policy: a failed step is cut, a step that was
easy (few Newton iterations) lets the next one grow, never beyond the nominal step the user
asked for; after too many consecutive cuts the stepping gives up with a
:class:`~dolfinx_invertible.solvers.results.SolverError` that names the step, the time and the
solver stage that failed. :func:`take_step` applies it to one step; the steppers
(:class:`~dolfinx_invertible.solvers.stepper.Stepper`: load steps and time steps) take every
step with it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any, Protocol

import dolfinx.fem
import numpy as np

from dolfinx_invertible.solvers.monitors import StepAttempt
from dolfinx_invertible.solvers.results import SolverError, SolveResult

__all__ = ["Solvable", "StepController", "take_step"]

# Steps are sums of cuts of the nominal step; a remainder this small (relative to the nominal
# step) is rounding, and the step goes to the target exactly.
_SNAP = 1.0e-9


class Solvable(Protocol):
    """What a stepping loop drives: a solve from the current state of ``u``.

    :class:`~dolfinx_invertible.solvers.minimizer.EnergyMinimizer` and
    :class:`~dolfinx_invertible.solvers.hyperelastic.HyperelasticProblem` are both; an
    ``escalate()`` method, if the solver has one, is what the stepping calls when a step's cuts
    run out (see :func:`take_step`).
    """

    u: dolfinx.fem.Function

    def solve(self) -> SolveResult:
        """Solve from the current ``u``; on failure ``u`` keeps its value."""
        ...


class StepController:
    """Chooses step sizes: cut after a failure, grow after an easy step, never above nominal.

    Parameters
    ----------
    nominal
        The largest step: the user's time step or load increment.
    max_cuts
        Consecutive cuts of a step before the stepping gives up.
    cut
        Factor applied to a step that failed, in (0, 1).
    growth
        Factor applied to the step after an easy one (≥ 1), up to ``nominal``.
    easy_iterations
        A converged step with at most this many Newton iterations counts as easy.
    minimum
        The smallest step worth trying; a step cut below it gives up too. Default
        ``nominal · cut ** (2 · max_cuts)``: alternating successes and failures (a solution that
        Newton cannot reach, such as an energy minimum on a kink) cannot creep on for ever.

    Notes
    -----
    The controller remembers the last size that failed (its ceiling). Growth reaches the ceiling
    again only after ``hold`` accepted steps below it: one at first, twice as many each time a
    retry at the ceiling fails again, and back to one once a step of that size is accepted
    (exponential backoff). A failure that was transient costs nothing more than before, while
    one that persists (a time scale the step must resolve, which a cut does not change) is
    retried after 1, 2, 4, … steps instead of after every easy one: where each failed attempt
    spends Newton's whole iteration budget, the retries then cost a vanishing share of the run,
    and a run whose ceiling has in fact lifted loses at most a factor of 2 in steps meanwhile.

    An attempt that ran to Newton's iteration cap cost the whole budget (200 iterations by
    default), where a step a cut too small costs a few easy steps more before growth has made
    it up (each easy step doubles it): its retry is cut to ``cut²`` of it at once, two of the
    ``max_cuts``, so that finding the size that passes costs half as many attempts at the cap
    and the cuts still run out (and the solver escalates) at the same smallest size.

    Attributes
    ----------
    step
        The step the next attempt uses (before clipping to a target).
    accepted
        Sizes of the accepted steps, in order.
    cuts
        Total number of cuts (failed attempts).
    escalations
        Times the cuts of a step ran out and the solver switched to a more robust mode
        (:func:`take_step`'s ``escalate``), which then got a fresh budget of cuts.
    """

    def __init__(
        self,
        nominal: float,
        *,
        max_cuts: int = 6,
        cut: float = 0.5,
        growth: float = 2.0,
        easy_iterations: int = 10,
        minimum: float | None = None,
    ):
        if not (math.isfinite(nominal) and nominal > 0.0):
            raise ValueError(f"the nominal step must be a finite number > 0, got {nominal!r}")
        if (
            isinstance(max_cuts, bool)
            or not isinstance(max_cuts, (int, np.integer))
            or max_cuts < 0
        ):
            raise ValueError(f"max_cuts: expected a non-negative int, got {max_cuts!r}")
        if not (0.0 < cut < 1.0):
            raise ValueError(f"cut must lie in (0, 1), got {cut!r}")
        if not growth >= 1.0:
            raise ValueError(f"growth must be at least 1, got {growth!r}")
        self.nominal = float(nominal)
        self.max_cuts = int(max_cuts)
        self.cut = float(cut)
        self.growth = float(growth)
        self.easy_iterations = int(easy_iterations)
        self.minimum = (
            self.nominal * self.cut ** (2 * self.max_cuts) if minimum is None else float(minimum)
        )
        self.step = self.nominal
        self.accepted: list[float] = []
        self.cuts = 0
        self.escalations = 0
        self._consecutive_cuts = 0
        self._budget = self.max_cuts
        self._ceiling = math.inf
        self._hold = 1
        self._held = 0

    def size(self, remaining: float = math.inf) -> float:
        """Return the size of the next attempt: the current step, clipped to ``remaining``."""
        if remaining - self.step <= _SNAP * self.nominal:
            return remaining
        return self.step

    def succeeded(self, size: float, result: SolveResult) -> None:
        """Record an accepted step of ``size``; an easy one lets the next step grow."""
        self.accepted.append(size)
        self._consecutive_cuts = 0
        self._budget = self.max_cuts
        if self._reaches_ceiling(size):
            self._ceiling, self._hold, self._held = math.inf, 1, 0
        else:
            self._held += 1
        if result.newton_iterations <= self.easy_iterations:
            grown = min(self.nominal, max(self.step, size) * self.growth)
            if self._reaches_ceiling(grown) and self._held < self._hold:
                grown = max(self.step, size)
            self.step = grown

    def failed(self, size: float, *, exhausted: bool = False) -> bool:
        """Record a failed attempt of ``size`` and cut; ``False`` once the cuts are used up.

        An ``exhausted`` attempt (one that ran to Newton's iteration cap) is cut twice over, to
        ``size · cut²``, where two of the ``max_cuts`` are left, and that spends both (see the
        class notes): the cuts run out at the same smallest size, only the attempt between is
        skipped.
        """
        self.cuts += 1
        self._consecutive_cuts += 1
        halvings = 2 if exhausted and self._consecutive_cuts < self._budget else 1
        self._budget -= halvings - 1
        if self._reaches_ceiling(size):
            self._hold *= 2
        self._ceiling = min(self._ceiling, size)
        self._held = 0
        self.step = size * self.cut**halvings
        return self._consecutive_cuts <= self._budget and self.step >= self.minimum

    def _reaches_ceiling(self, size: float) -> bool:
        return size >= self._ceiling * (1.0 - _SNAP)

    def set_nominal(self, nominal: float) -> None:
        """Make ``nominal`` the largest step from now on and the next step's size.

        The step's cut budget, its floor and what the controller learnt about failing sizes
        start afresh; the accepted steps and the cuts so far stay counted.
        """
        if not (math.isfinite(nominal) and nominal > 0.0):
            raise ValueError(f"the nominal step must be a finite number > 0, got {nominal!r}")
        self.nominal = self.step = float(nominal)
        self.minimum = self.nominal * self.cut ** (2 * self.max_cuts)
        self._consecutive_cuts = 0
        self._budget = self.max_cuts
        self._ceiling, self._hold, self._held = math.inf, 1, 0

    def restart(self, size: float) -> None:
        """Try ``size`` again with a fresh budget of ``max_cuts`` cuts (after an escalation)."""
        self.escalations += 1
        self._budget = self._consecutive_cuts + self.max_cuts
        self.step = size

    def state(self) -> dict[str, Any]:
        """Return what the next steps depend on, as JSON values (for a checkpoint)."""
        return {
            "step": self.step,
            "accepted": list(self.accepted),
            "cuts": self.cuts,
            "escalations": self.escalations,
            "consecutive_cuts": self._consecutive_cuts,
            "budget": self._budget,
            "max_cuts": self.max_cuts,
            "ceiling": self._ceiling if math.isfinite(self._ceiling) else None,
            "hold": self._hold,
            "held": self._held,
        }

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from a :meth:`state` (same nominal step; ``max_cuts`` may have changed)."""
        self.step = float(state["step"])
        self.accepted = [float(size) for size in state["accepted"]]
        self.cuts = int(state["cuts"])
        self.escalations = int(state["escalations"])
        self._consecutive_cuts = int(state["consecutive_cuts"])
        # The budget left to the step in progress grows or shrinks with a changed max_cuts.
        saved_max_cuts = int(state.get("max_cuts", self.max_cuts))
        self._budget = int(state["budget"]) + self.max_cuts - saved_max_cuts
        ceiling = state.get("ceiling")
        self._ceiling = math.inf if ceiling is None else float(ceiling)
        self._hold = int(state.get("hold", 1))
        self._held = int(state.get("held", 0))

    @property
    def consecutive_cuts(self) -> int:
        """Failed attempts since the last accepted step."""
        return self._consecutive_cuts

    def statistics(self) -> dict[str, float | int | None]:
        """Return accepted steps, cuts and the smallest and largest accepted step."""
        return {
            "steps": len(self.accepted),
            "cuts": self.cuts,
            "escalations": self.escalations,
            "step_min": min(self.accepted) if self.accepted else None,
            "step_max": max(self.accepted) if self.accepted else None,
        }


def take_step(
    controller: StepController,
    start: float,
    remaining: float,
    attempt: Callable[[float, float], SolveResult],
    restore: Callable[[float], None],
    failure: Callable[[float, float, SolveResult], str],
    check: Callable[[SolveResult], str | None] | None = None,
    escalate: Callable[[], bool] | None = None,
    on_attempt: Callable[[StepAttempt], None] | None = None,
) -> tuple[float, SolveResult]:
    """Take one step from ``start``, cutting and retrying until it succeeds or the cuts run out.

    Parameters
    ----------
    controller
        The step policy.
    start
        The (pseudo-)time the state is at.
    remaining
        The step never goes past ``start + remaining`` (and lands on it when within rounding).
    attempt
        ``attempt(start, end)`` sets the loads or boundary values of ``end`` and solves.
    restore
        ``restore(start)`` puts back the state and the loads of ``start`` after a failure.
    failure
        ``failure(start, end, result)`` is the message of the
        :class:`~dolfinx_invertible.solvers.results.SolverError` when the cuts are used up.
    check
        Optional test of a converged attempt: a reason to reject it (cut and retry) or ``None``.
    escalate
        Called once the cuts are used up: ``True`` if it switched the solver to a more robust
        mode (e.g. :meth:`~dolfinx_invertible.solvers.minimizer.EnergyMinimizer.escalate`), and
        the last size is then tried again with a fresh budget of cuts. The mode stays.
    on_attempt
        Called with a :class:`~dolfinx_invertible.solvers.monitors.StepAttempt` after every
        attempt, accepted or not (before a failed one is restored).

    Returns
    -------
    (size, result)
        The accepted step and its solve.
    """
    escalated = False
    while True:
        size = controller.size(remaining)
        result = attempt(start, start + size)
        rejection = check(result) if (check is not None and result.converged) else None
        accepted = result.converged and rejection is None
        if on_attempt is not None:
            on_attempt(StepAttempt(start, start + size, result, accepted, rejection))
        if accepted:
            controller.succeeded(size, result)
            return size, result
        restore(start)
        if rejection is not None:
            result = _rejected(result, rejection)
        if not controller.failed(size, exhausted=result.stage == "iteration cap"):
            if escalate is not None and escalate():
                controller.restart(size)
                escalated = True
                continue
            message = failure(start, start + size, result)
            if escalated:
                message += " (the last attempts with blended tangents)"
            if controller.step < controller.minimum:
                message += f" (the next cut would take the step below {controller.minimum:.3g})"
            raise SolverError(
                message,
                reason_name=result.reason_name,
                stage=result.stage,
                time_reached=start,
                time_tried=start + size,
                result=result,
            )


def _rejected(result: SolveResult, reason: str) -> SolveResult:
    return dataclasses.replace(
        result, converged=False, stage="step check", detail=reason, energy=None
    )
