"""What a cell tracks beyond the runner's summary: the last Newton attempt and the step caps.

A :class:`~dolfinx_invertible.scenes.RunObserver` on the cell's run: it keeps the latest Newton
iterate and residual norms of the current solve (after a failed step: of its last attempt) and
the caps the step limits put on its directions, besides a few figures of every stored step.
"""

from __future__ import annotations

from dolfinx_invertible.scenes.observer import RunObserver

__all__ = ["Recorder"]


class Recorder(RunObserver):
    """Observes a cell's run: the stored states and the Newton iterates of the last attempt.

    Attributes
    ----------
    run
        The run, once started.
    kinetic_max
        The largest kinetic energy of a stored state.
    projected
        Newton iterations of the accepted steps whose direction came from the projected tangent.
    last_inverted_time
        The time of the last stored state with an inverted cell.
    iterate, norms, caps
        The latest Newton iterate of the current (or last) attempt, the residual norms of its
        iterations, and the step limits' caps on its directions.
    on_step
        Called with the run after every stored step (the worker reports progress with it, so
        that a cell stopped by its timeout still says how far it got); ``None`` by default.
    """

    def __init__(self, on_step=None):
        self.on_step = on_step
        self.run = None
        self.kinetic_max = 0.0
        self.projected = 0
        self.last_inverted_time = None
        self.iterate = None
        self.norms: list[float] = []
        self.caps: list[float] = []

    def start(self, run) -> None:
        """Record the initial state."""
        self._observe(run)

    def step(self, run) -> None:
        """Record a stored state."""
        self._observe(run)
        if self.on_step is not None:
            self.on_step(run)

    def iteration(self, run, iteration) -> None:
        """Keep the iterate and its residual norm (a new attempt starts at iteration 0)."""
        if iteration.iteration == 0:
            self.norms = []
            self.caps = []
        if self.iterate is None:
            self.iterate = iteration.iterate.duplicate()
        iteration.iterate.copy(self.iterate)
        self.norms.append(iteration.residual_norm)

    def step_cap(self, run, cap) -> None:
        """Keep a step limit's cap."""
        self.caps.append(cap.cap)

    def _observe(self, run) -> None:
        self.run = run
        kinetic = run.kinetic_energy
        if kinetic is not None:
            self.kinetic_max = max(self.kinetic_max, kinetic)
        if run.result is not None:
            self.projected += run.result.projected_iterations
        if run.diagnostics.get("inverted_cells", 0) > 0:
            self.last_inverted_time = run.time
