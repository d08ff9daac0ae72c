"""What a cell tracks beyond the runner's summary: a SNES monitor and the step limits' caps.

The recorder reaches into the scene run's solver (its minimiser, SNES and step limits) and
subclasses the scene class at run time to get the ``record`` hook.
"""

from __future__ import annotations

__all__ = ["Recorder"]


class Recorder:
    """What a cell tracks beyond the runner's summary, through the scene's ``record`` hook.

    At t = 0 it puts a SNES monitor on the step's minimiser, which keeps the latest Newton
    iterate and residual norms of the current solve (after a failed step: of its last attempt),
    and wraps the step limits so that their caps are kept too.
    """

    def __init__(self):
        self.run = None
        self.kinetic_max = 0.0
        self.projected = 0
        self.last_inverted_time = None
        self.iterate = None
        self.norms: list[float] = []
        self.caps: list[float] = []

    def scene(self, scene_class):
        """Return a subclass of ``scene_class`` whose ``record`` hook reports to this recorder."""
        recorder = self

        class Observed(scene_class):
            def record(self, run) -> None:
                recorder.observe(run)
                super().record(run)

        Observed.__name__ = scene_class.__name__
        return Observed

    def observe(self, run) -> None:
        """Record the state after a step (and at t = 0)."""
        if self.run is None and run.dynamics is not None:
            minimizer = run.dynamics.problem.solver
            self.iterate = minimizer.problem.create_vector()
            minimizer.snes.setMonitor(self._monitor)
            minimizer.step_limits = [_CapRecorder(limit, self) for limit in minimizer.step_limits]
        self.run = run
        kinetic = run.kinetic_energy
        if kinetic is not None:
            self.kinetic_max = max(self.kinetic_max, kinetic)
        if run.result is not None:
            self.projected += run.result.projected_iterations
        if run.diagnostics.get("inverted_cells", 0) > 0:
            self.last_inverted_time = run.time

    def _monitor(self, snes, iteration: int, norm: float) -> None:
        if iteration == 0:
            self.norms = []
            self.caps = []
        snes.getSolution().copy(self.iterate)
        self.norms.append(float(norm))


class _CapRecorder:
    """A step limit wrapped so that the caps it returns are kept."""

    def __init__(self, limit, recorder: Recorder):
        self.limit = limit
        self.recorder = recorder

    def largest_step(self, direction, sign: float = 1.0) -> float:
        """Return the wrapped limit's cap, keeping it."""
        cap = self.limit.largest_step(direction, sign)
        self.recorder.caps.append(float(cap))
        return cap
