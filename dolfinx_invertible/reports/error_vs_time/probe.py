"""What a case records beyond the run's summary: its stepping time and the sampled solution."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from dolfinx_invertible.fem import PointValues
from dolfinx_invertible.scenes import RunObserver

__all__ = ["Probe"]


class Probe(RunObserver):
    """Times the stepping and samples the final state at ``points`` (none: no samples).

    Attributes
    ----------
    values
        ``stepping_time_s`` (from the first step to the end, setup excluded) and ``samples``
        (the displacement at the points, one row each), once the run has ended.
    """

    def __init__(self, points: np.ndarray | None):
        self.points = points
        self.values: dict[str, Any] = {}
        self._started = 0.0

    def start(self, run) -> None:
        """Note when the stepping starts."""
        self._started = time.perf_counter()

    def end(self, run) -> None:
        """Keep the stepping time and the samples of the final state (collective)."""
        self.values["stepping_time_s"] = time.perf_counter() - self._started
        if self.points is not None:
            self.values["samples"] = PointValues(run.u, self.points)().tolist()
