"""Newmark's average-acceleration rule (γ = 1/2, β = 1/4): second order, no numerical damping.

    x_{n+1} = xₙ + h vₙ + h² ((½ − β) aₙ + β a_{n+1}),    v_{n+1} = vₙ + h ((1 − γ) aₙ + γ a_{n+1}).

With x* = xₙ + h vₙ + (½ − β) h² aₙ, a_{n+1} = (x_{n+1} − x*)/(β h²), so M a_{n+1} = −∇Π(x) is the
stationarity condition of ½ W ‖x − x*‖²_M + Π(x) with W = 1/(β h²). Mass-proportional damping
c M v_{n+1}, with v_{n+1} = ṽ + γ h a_{n+1} and ṽ = vₙ + (1 − γ) h aₙ, adds
c M ṽ + c γ h W M (x − x*) to the balance: one quadratic of weight W (1 + c γ h) centred at
x* − c ṽ / (W (1 + c γ h)).

The rule reads the acceleration at the start of each step, so the initial one is made to satisfy
the momentum balance, M a₀ = −∇Π(x₀) (:meth:`~dolfinx_invertible.ImplicitDynamics.
static_acceleration`). For linear elasticity the rule conserves the discrete energy exactly; for
a hyperelastic body the energy stays within O(h²) of its initial value instead of decaying.
"""

from __future__ import annotations

from typing import Any

import dolfinx.fem
import numpy as np

from dolfinx_invertible.solvers.integrators.base import Integrator

__all__ = ["Newmark"]

GAMMA = 0.5
BETA = 0.25


class Newmark(Integrator):
    """Average acceleration (trapezoidal rule): second order, A-stable, energy-conserving."""

    name = "newmark"
    order = 2

    def __init__(self, space, displacement: np.ndarray, velocity: np.ndarray | None) -> None:
        super().__init__(space, displacement, velocity)
        self.acceleration = dolfinx.fem.Function(space)

    def start(self, dynamics) -> None:
        """Set a₀ from the momentum balance at the initial state."""
        self.acceleration.x.array[:] = dynamics.static_acceleration()

    def _prediction(self, step: float) -> tuple[np.ndarray, np.ndarray]:
        """Return x* and ṽ of a step of ``step`` (see the module)."""
        acceleration = self.acceleration.x.array
        predicted = (
            self.displacement.x.array
            + step * self.velocity.x.array
            + (0.5 - BETA) * step * step * acceleration
        )
        return predicted, self.velocity.x.array + (1.0 - GAMMA) * step * acceleration

    def inertia(self, step: float, damping: float) -> tuple[float, np.ndarray]:
        """Return W = 1/(β h²) (times 1 + c γ h) and the centre of the quadratic."""
        predicted, velocity = self._prediction(step)
        weight = 1.0 / (BETA * step * step)
        if damping > 0.0:
            weight *= 1.0 + damping * GAMMA * step
            predicted = predicted - damping * velocity / weight
        return weight, predicted

    def commit(self, x: np.ndarray, step: float) -> None:
        """Advance to a_{n+1} = (x − x*)/(β h²) and v_{n+1} = ṽ + γ h a_{n+1}."""
        predicted, velocity = self._prediction(step)
        acceleration = (x - predicted) / (BETA * step * step)
        self.velocity.x.array[:] = velocity + GAMMA * step * acceleration
        self.acceleration.x.array[:] = acceleration
        self.displacement.x.array[:] = x

    def fields(self) -> dict[str, dolfinx.fem.Function]:
        """Return displacement, velocity and acceleration at the start of the next step."""
        return {**super().fields(), "acceleration": self.acceleration}

    def state(self) -> dict[str, Any]:
        """Nothing besides the fields."""
        return {}
