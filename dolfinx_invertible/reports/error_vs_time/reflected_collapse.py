"""The collapse scene started from a reflection: the error-vs-time study's inverted start."""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.reports.error_vs_time.study import REFLECTION
from dolfinx_invertible.scenes.collapse import Collapse

__all__ = ["ReflectedCollapse"]


class ReflectedCollapse(Collapse):
    """The collapse cube, every cell inverted by F = :data:`REFLECTION` about its centre."""

    def initial_displacement(self):
        """Return u₀ = (REFLECTION − I)(x − centre)."""
        centre = 0.5 * self.parameters.size

        def displacement(x):
            return (REFLECTION - np.eye(3)) @ (x - centre)

        return displacement
