"""What a scene run counts over its steps, defined once: the summary's keys and the checkpoint's."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

__all__ = ["RunStatistics"]


@dataclasses.dataclass
class RunStatistics:
    """The counts of a run; each field is the ``summary.json`` key of the same name.

    Attributes
    ----------
    steps
        Accepted steps.
    newton_iterations
        ``{"total": ..., "max": ...}`` over the accepted steps.
    linear_iterations
        Krylov iterations of the accepted steps.
    max_inverted
        The most inverted cells at one stored state.
    min_J_reached
        The smallest det F at any stored state.
    nan_encountered
        Whether a step's energy was not finite, or a step failed on a NaN.
    svd_points
        Per kernel kind, the share of points that went through the SVD, one entry per step (the
        summary's ``svd_share`` is their mean).
    failed_attempts
        Attempts of a step that failed (each then cut and retried, or ending the run).
    failed_attempts_wall_time
        The seconds those attempts took (their solves'), part of the run's wall time.
    """

    steps: int = 0
    newton_iterations: dict[str, int] = dataclasses.field(
        default_factory=lambda: {"total": 0, "max": 0}
    )
    linear_iterations: int = 0
    max_inverted: int = 0
    min_J_reached: float = math.inf  # noqa: N815 (the notation: J = det F)
    nan_encountered: bool = False
    svd_points: dict[str, list[float]] = dataclasses.field(default_factory=dict)
    failed_attempts: int = 0
    failed_attempts_wall_time: float = 0.0

    def add_state(self, diagnostics: dict[str, Any]) -> None:
        """Count a stored state's global diagnostics (inverted cells, smallest J)."""
        self.max_inverted = max(self.max_inverted, diagnostics["inverted_cells"])
        self.min_J_reached = min(self.min_J_reached, diagnostics["min_J"])

    def add_step(self, result) -> None:
        """Count an accepted step's :class:`~dolfinx_invertible.SolveResult`."""
        self.steps += 1
        self.newton_iterations["total"] += result.newton_iterations
        self.newton_iterations["max"] = max(self.newton_iterations["max"], result.newton_iterations)
        self.linear_iterations += result.linear_iterations
        for kind, share in result.svd_share.items():
            if share is not None:
                self.svd_points.setdefault(kind, []).append(share)
        if result.energy is not None and not math.isfinite(result.energy):
            self.nan_encountered = True

    def add_failed_attempt(self, result) -> None:
        """Count a failed attempt's :class:`~dolfinx_invertible.SolveResult`."""
        self.failed_attempts += 1
        self.failed_attempts_wall_time += result.wall_time

    def summary(self) -> dict[str, Any]:
        """Return the counts under their summary keys (``svd_share`` the mean of the points)."""
        values = dataclasses.asdict(self)
        points = values.pop("svd_points")
        values["svd_share"] = {kind: float(np.mean(shares)) for kind, shares in points.items()}
        return values

    def state(self) -> dict[str, Any]:
        """Return every field, as JSON values (for a checkpoint)."""
        values = dataclasses.asdict(self)
        if math.isinf(values["min_J_reached"]):
            values["min_J_reached"] = None
        return values

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> RunStatistics:
        """Return the statistics of a :meth:`state`."""
        values = dict(state)
        if values.get("min_J_reached") is None:
            values["min_J_reached"] = math.inf
        return cls(**values)
