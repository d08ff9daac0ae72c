"""The state of a scene run as its hooks and observers see it (:class:`Run`)."""

from __future__ import annotations

import dataclasses
from time import perf_counter
from typing import Any

from dolfinx_invertible.scenes.parameters import Parameters
from dolfinx_invertible.scenes.scene import Scene
from dolfinx_invertible.scenes.statistics import RunStatistics
from dolfinx_invertible.solvers.monitors import StepAttempt
from dolfinx_invertible.solvers.results import SolveResult
from dolfinx_invertible.solvers.stepper import Stepper

__all__ = ["Run"]


@dataclasses.dataclass
class Run:
    """The state of a scene run, as the scene's hooks and the observers see it.

    Attributes
    ----------
    scene, parameters, material, mesh, u
        What runs.
    stepper
        The :class:`~dolfinx_invertible.solvers.stepper.Stepper` that advances it: an
        :class:`~dolfinx_invertible.ImplicitDynamics` (dynamic scenes) or a
        :class:`~dolfinx_invertible.solvers.quasi_static.QuasiStatic` (load steps).
    terms
        The scene's :class:`~dolfinx_invertible.solvers.terms.StatefulTerm` energy terms (its
        contact, say), which the run drives.
    statistics
        The :class:`~dolfinx_invertible.scenes.statistics.RunStatistics` so far.
    result
        The last step's :class:`~dolfinx_invertible.SolveResult` (None at t = 0).
    diagnostics
        Global counts of the last stored state (:func:`~dolfinx_invertible.summary`).
    cell_values
        Per-cell diagnostics of the last stored state on this rank's owned cells
        (:func:`~dolfinx_invertible.cell_diagnostics`), as the outputs write them.
    record
        The step-log record of the last stored state: the diagnostics, the step's solver
        counts, the terms' figures, the wall time, and the attempts of the step that failed
        before it (``failed_attempts``: step size, stage, Newton iterations, seconds).
    stored
        States stored so far (the initial one and every accepted step; a continued run counts
        its first run's).
    resumed
        Whether the run continues a stopped one from its checkpoint.
    started
        ``perf_counter()`` when the run started (shifted back by a continued run's time).
    completed, failure
        Whether the stepping reached its end; why it stopped otherwise (``reason``,
        ``failed_stage``, ``failed_time``).
    failed_attempts
        The failed attempts since the last stored state (:meth:`add_attempt`), which the next
        stored state's record takes.
    """

    scene: Scene
    parameters: Parameters
    material: Any
    mesh: Any
    u: Any
    stepper: Stepper
    terms: list = dataclasses.field(default_factory=list)
    statistics: RunStatistics = dataclasses.field(default_factory=RunStatistics)
    result: SolveResult | None = None
    diagnostics: dict[str, Any] = dataclasses.field(default_factory=dict)
    cell_values: dict[str, Any] = dataclasses.field(default_factory=dict)
    record: dict[str, Any] = dataclasses.field(default_factory=dict)
    stored: int = 0
    resumed: bool = False
    started: float = dataclasses.field(default_factory=perf_counter)
    completed: bool = False
    failure: dict[str, Any] = dataclasses.field(default_factory=dict)
    failed_attempts: list[dict[str, Any]] = dataclasses.field(default_factory=list)

    def add_attempt(self, attempt: StepAttempt) -> None:
        """Count an attempt of a step; a failed one goes into the next stored state's record."""
        if attempt.accepted:
            return
        result = attempt.result
        self.statistics.add_failed_attempt(result)
        self.failed_attempts.append(
            {
                "step_size": attempt.end - attempt.start,
                "stage": result.stage or "step check",
                "newton_iterations": result.newton_iterations,
                "wall_time": result.wall_time,
            }
        )

    def store(self, result: SolveResult | None) -> None:
        """Record the current state (collective): diagnostics, statistics, the step's record.

        ``result`` is the accepted step's solve, None for the initial state. The record holds
        the global diagnostics, the step's solver counts and size, the kinetic energy (dynamic
        scenes), each stateful term's figures and the wall time so far.
        """
        from dolfinx_invertible.fem.diagnostics import cell_diagnostics, summary

        self.result = result
        self.cell_values = cell_diagnostics(self.u, self.material)
        self.diagnostics = summary(self.cell_values, self.mesh.comm)
        self.statistics.add_state(self.diagnostics)
        record = dict(self.diagnostics)
        if result is not None:
            self.statistics.add_step(result)
            record.update(
                energy=result.energy,
                newton_iterations=result.newton_iterations,
                linear_iterations=result.linear_iterations,
                tangent=result.tangent,
                svd_share=result.svd_share,
                step_size=self.controller.accepted[-1],
            )
        kinetic = self.kinetic_energy
        if kinetic is not None:
            record["kinetic_energy"] = kinetic
        for term in self.terms:
            record.update(term.step_quantities())
        if self.failed_attempts:
            record["failed_attempts"] = self.failed_attempts
            self.failed_attempts = []
        record["wall_time"] = perf_counter() - self.started
        self.record = record
        self.stored += 1

    @property
    def time(self) -> float:
        """Time (dynamic) or pseudo-time (quasi-static) of the current state."""
        return self.stepper.time

    @property
    def controller(self):
        """The stepper's :class:`~dolfinx_invertible.StepController`."""
        return self.stepper.controller

    @property
    def minimizer(self):
        """The :class:`~dolfinx_invertible.EnergyMinimizer` that solves every step."""
        return self.stepper.solver

    @property
    def kinetic_energy(self) -> float | None:
        """Kinetic energy of the current state (collective); None without mass."""
        return self.stepper.kinetic_energy
