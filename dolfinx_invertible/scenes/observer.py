"""Watching a scene run: the hooks :func:`~dolfinx_invertible.scenes.run_scene` calls.

Subclass :class:`RunObserver`, override the hooks you need and pass an instance to
``run_scene(..., observers=[...])``. Every hook gets the :class:`~.run.Run` (the scene, the
mesh, ``u``, the stepper, the step's record and the run's statistics so far) and is called on
every rank, so collective work (assembling, reducing) is allowed inside, except in
:meth:`RunObserver.close`. The solver-level records are those of
:mod:`dolfinx_invertible.solvers.monitors`. The run's own outputs (the XDMF and VTX files, the
step log, the checkpoints, the progress bar: :mod:`dolfinx_invertible.scenes.outputs`) are
observers too, attached before the caller's.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # importing the scenes must not load DOLFINx
    from dolfinx_invertible.scenes.run import Run
    from dolfinx_invertible.solvers.monitors import NewtonIteration, StepAttempt, StepCap

__all__ = ["RunObserver"]


class RunObserver:
    """Hooks of a scene run; each does nothing unless overridden.

    The order: :meth:`start` once the problem is built and the initial state recorded (a
    continued run: restored); for every attempt of a step :meth:`iteration` after each Newton
    iteration (with ``u`` holding the iterate) and :meth:`step_cap` for each cap of a step
    limit, then :meth:`attempt`; after an accepted step :meth:`step`; at the end :meth:`end`,
    also after a failed step (not after an interrupt), before the scene's own quantities are
    evaluated; last :meth:`close`, always.
    """

    def start(self, run: Run) -> None:
        """Before the first step."""

    def iteration(self, run: Run, iteration: NewtonIteration) -> None:
        """After every Newton iteration (and for the initial guess) of every attempt."""

    def step_cap(self, run: Run, cap: StepCap) -> None:
        """Whenever a step limit has capped a Newton direction."""

    def attempt(self, run: Run, attempt: StepAttempt) -> None:
        """After every attempt of a step, accepted or not (before a failed one is undone)."""

    def step(self, run: Run) -> None:
        """After every accepted step, once it is recorded (``run.record``)."""

    def end(self, run: Run) -> None:
        """After the stepping ended, completed or failed (``run.completed``, ``run.failure``)."""

    def close(self, run: Run) -> None:
        """Last, also after an interrupt: release files; no collective work here."""
