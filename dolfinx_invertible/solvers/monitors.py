"""What the solvers report to observers: one record per Newton iteration, step cap and attempt.

The minimiser (:class:`~dolfinx_invertible.solvers.minimizer.EnergyMinimizer`) calls its
iteration monitors after every Newton iteration (and once for the initial guess) with a
:class:`NewtonIteration`, and its step-cap monitors with a :class:`StepCap` whenever a step
limit has capped a direction. The steppers (load steps, time steps) call their attempt monitors
with a :class:`StepAttempt` after every attempt of a step, accepted or not. Register them with
``add_monitor`` on the minimiser, on
:class:`~dolfinx_invertible.solvers.hyperelastic.HyperelasticProblem` or on
:class:`~dolfinx_invertible.solvers.dynamics.ImplicitDynamics`, or through a
:class:`~dolfinx_invertible.scenes.RunObserver` when running a scene.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

from petsc4py import PETSc

from dolfinx_invertible.solvers.results import SolveResult, ksp_reason_name

__all__ = [
    "DIRECTION_KINDS",
    "IterationMonitors",
    "MonitorList",
    "NewtonIteration",
    "StepAttempt",
    "StepCap",
]

#: Where a Newton direction came from: the problem's own tangent, the SPD-projected tangent
#: that replaced it, a positive definite blend of the two, or the exact tangent's direction cut
#: at a trust region's boundary.
DIRECTION_KINDS = ("exact", "projected", "blended", "bounded")


@dataclasses.dataclass(frozen=True)
class NewtonIteration:
    """One Newton iteration as the minimiser saw it.

    During the call the problem's ``u`` holds the iterate (owned values and ghosts), so
    anything evaluated on ``u`` sees it.

    Attributes
    ----------
    solve
        How many solves this minimiser has started, this one included.
    iteration
        0 for the initial guess, then the iteration that reached ``iterate``.
    iterate
        The iterate, a PETSc vector owned by the solver: valid during the call only (copy it
        to keep it).
    residual_norm
        Euclidean norm of the residual at the iterate (Dirichlet rows included).
    energy
        Π at the iterate where the line search evaluated it, else ``None``.
    direction
        Where the direction of the step came from (one of :data:`DIRECTION_KINDS`); ``None``
        for the initial guess.
    step_length
        The fraction of that Newton direction taken (1 for a full step, 0 when the step failed
        and the solve stops); ``None`` for the initial guess.
    step_cap
        The smallest cap the step limits put on that direction (1 when nothing capped it).
    linear_iterations
        Krylov iterations spent on that direction, replacements included.
    linear_reason
        PETSc KSP converged reason of the last linear solve of the iteration, e.g.
        ``"CONVERGED_RTOL"``; ``None`` for the initial guess.
    """

    solve: int
    iteration: int
    iterate: PETSc.Vec
    residual_norm: float
    energy: float | None = None
    direction: str | None = None
    step_length: float | None = None
    step_cap: float | None = None
    linear_iterations: int = 0
    linear_reason: str | None = None


@dataclasses.dataclass(frozen=True)
class StepCap:
    """A step limit's cap on a Newton direction.

    Attributes
    ----------
    limit
        The :class:`~dolfinx_invertible.solvers.step_limit.StepLimit` that was asked.
    cap
        The largest fraction of the direction it allows, in [0, 1].
    iteration
        The Newton iteration whose direction was capped.
    """

    limit: Any
    cap: float
    iteration: int


@dataclasses.dataclass(frozen=True)
class StepAttempt:
    """One attempt of a load step or time step.

    Attributes
    ----------
    start, end
        The (pseudo-)times the attempt went from and to.
    result
        The solve's :class:`~dolfinx_invertible.SolveResult`.
    accepted
        Whether the step was accepted; otherwise the state is restored to ``start`` and the step
        cut (or the stepping gives up).
    rejection
        Why a converged attempt was rejected (a step check), else ``None``.
    """

    start: float
    end: float
    result: SolveResult
    accepted: bool
    rejection: str | None = None


class MonitorList:
    """Callbacks of one kind, added and removed by the objects that report to them."""

    def __init__(self) -> None:
        self._callbacks: list[Callable[[Any], None]] = []

    def add(self, callback: Callable[[Any], None]) -> Callable[[], None]:
        """Add ``callback``; return a function that removes it again."""
        if not callable(callback):
            raise TypeError(f"a monitor must be callable, got {callback!r}")
        self._callbacks.append(callback)

        def remove() -> None:
            if callback in self._callbacks:
                self._callbacks.remove(callback)

        return remove

    def __bool__(self) -> bool:
        return bool(self._callbacks)

    def __call__(self, record: Any) -> None:
        """Call every callback with ``record``, in the order they were added."""
        for callback in list(self._callbacks):
            callback(record)


class IterationMonitors:
    """A minimiser's monitors, and what it tells them about the iteration under way."""

    def __init__(self) -> None:
        self.on_iteration = MonitorList()
        self.on_step_cap = MonitorList()
        self.solves = 0
        self._linear_seen = 0
        self.start_direction()

    def add(
        self,
        on_iteration: Callable[[NewtonIteration], None] | None,
        on_step_cap: Callable[[StepCap], None] | None,
    ) -> Callable[[], None]:
        """Add monitors of either kind; return a function that removes them again."""
        removers = [
            monitors.add(callback)
            for monitors, callback in (
                (self.on_iteration, on_iteration),
                (self.on_step_cap, on_step_cap),
            )
            if callback is not None
        ]

        def remove() -> None:
            for remover in removers:
                remover()

        return remove

    def start_solve(self) -> None:
        """Begin a solve."""
        self.solves += 1
        self._linear_seen = 0
        self.start_direction()

    def start_direction(self) -> None:
        """Begin judging a Newton direction: not capped, taken in full so far."""
        self._caps: list[float] = []
        self.step_length = 1.0

    def capped(self, limit: Any, cap: float, iteration: int) -> None:
        """Record (and report) a step limit's cap on the current direction."""
        self._caps.append(float(cap))
        if self.on_step_cap:
            self.on_step_cap(StepCap(limit, float(cap), iteration))

    def iteration_done(
        self,
        snes: PETSc.SNES,
        iteration: int,
        norm: float,
        *,
        problem,
        energy: Callable[[PETSc.Vec], float | None],
        direction: str,
        replacement_linear_iterations: int,
    ) -> None:
        """Report an iteration (SNES's monitor): ``u`` holds the iterate during the reports."""
        first = iteration == 0
        total = int(snes.getLinearSolveIterations())
        linear = total - self._linear_seen + replacement_linear_iterations
        self._linear_seen = 0 if first else total
        if not self.on_iteration:
            return
        iterate = snes.getSolution()
        problem.update_solution(iterate)
        reason = snes.getKSP().getConvergedReason()
        self.on_iteration(
            NewtonIteration(
                solve=self.solves,
                iteration=int(iteration),
                iterate=iterate,
                residual_norm=float(norm),
                energy=energy(iterate),
                direction=None if first else direction,
                step_length=None if first else self.step_length,
                step_cap=None if first else min(self._caps, default=1.0),
                linear_iterations=0 if first else linear,
                linear_reason=None if first else ksp_reason_name(reason),
            )
        )
