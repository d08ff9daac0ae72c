"""Variable-step BDF2: second order, A-stable; its first step is a backward Euler step.

With the step ratio ω = hₙ/hₙ₋₁ (variable steps, so that step control keeps working),
α = ((1 + 2ω)/(1 + ω), −(1 + ω), ω²/(1 + ω))/hₙ, which for ω = 1 is (3/2, −2, 1/2)/h
(x̂ = x̄ + ⅔h v̄ with x̄ = (4xₙ − xₙ₋₁)/3, v̄ = (4vₙ − vₙ₋₁)/3).
"""

from __future__ import annotations

from dolfinx_invertible.solvers.integrators.backward_euler import BackwardEuler
from dolfinx_invertible.solvers.integrators.base import MultistepIntegrator

__all__ = ["BDF2"]


class BDF2(MultistepIntegrator):
    """Second order, A-stable, variable step; a backward Euler step where history is missing."""

    name = "bdf2"
    order = 2
    history = 2

    @staticmethod
    def coefficients(step: float, previous_step: float | None) -> tuple[float, float, float]:
        """Return (α₀, α₁, α₂) for ``step`` after a step of ``previous_step`` (None: first)."""
        if previous_step is None:
            return BackwardEuler.coefficients(step, None)
        ratio = step / previous_step
        return (
            (1.0 + 2.0 * ratio) / ((1.0 + ratio) * step),
            -(1.0 + ratio) / step,
            ratio * ratio / ((1.0 + ratio) * step),
        )
