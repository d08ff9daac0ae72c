"""Implicit time integrators written as incremental potentials: backward Euler and BDF2.

Both approximate the velocity from positions at the new and earlier steps,

    v_{n+1} = α₀ x_{n+1} + α₁ xₙ + α₂ xₙ₋₁,        a_{n+1} = α₀ v_{n+1} + α₁ vₙ + α₂ vₙ₋₁,

so that M a_{n+1} = −∇Π(x_{n+1}) is the stationarity condition of

    E(x) = ½ α₀² ‖x − x̂‖²_M + Π(x),    x̂ = −(α₁ xₙ + α₂ xₙ₋₁)/α₀ − (α₁ vₙ + α₂ vₙ₋₁)/α₀²:

a minimisation, so the energy line search applies unchanged. Backward Euler has
α = (1, −1, 0)/h. BDF2 with the step ratio ω = hₙ/hₙ₋₁ (variable steps, so that step control
keeps working) has α = ((1 + 2ω)/(1 + ω), −(1 + ω), ω²/(1 + ω))/hₙ, which for ω = 1 is
(3/2, −2, 1/2)/h (x̂ = x̄ + ⅔h v̄ with x̄ = (4xₙ − xₙ₋₁)/3, v̄ = (4vₙ − vₙ₋₁)/3); its first step,
without history, is a backward Euler step. Mass-proportional damping c M v adds
½ c α₀ ‖x − x̃‖²_M with x̃ = −(α₁ xₙ + α₂ xₙ₋₁)/α₀, which merges with the inertia term into one
quadratic of weight α₀² + c α₀.
"""

from __future__ import annotations

__all__ = ["INTEGRATORS", "BackwardEuler", "BDF2"]


class BackwardEuler:
    """First order, L-stable; damps oscillations strongly at large steps."""

    name = "backward-euler"
    order = 1
    history = 1  # earlier steps its formula uses

    @staticmethod
    def coefficients(step: float, previous_step: float | None) -> tuple[float, float, float]:
        """Return (α₀, α₁, α₂) of the velocity formula for a step of size ``step``."""
        return 1.0 / step, -1.0 / step, 0.0


class BDF2:
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


#: Integrators by name.
INTEGRATORS = {integrator.name: integrator for integrator in (BackwardEuler, BDF2)}
