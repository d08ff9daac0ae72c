"""Backward Euler: α = (1, −1, 0)/h, first order, L-stable."""

from __future__ import annotations

from dolfinx_invertible.solvers.integrators.base import MultistepIntegrator

__all__ = ["BackwardEuler"]


class BackwardEuler(MultistepIntegrator):
    """First order, L-stable; damps oscillations strongly at large steps."""

    name = "backward-euler"
    order = 1
    history = 1

    @staticmethod
    def coefficients(step: float, previous_step: float | None) -> tuple[float, float, float]:
        """Return (α₀, α₁, α₂) of the velocity formula for a step of size ``step``."""
        return 1.0 / step, -1.0 / step, 0.0
