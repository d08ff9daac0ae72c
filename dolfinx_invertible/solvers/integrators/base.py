"""What every time integrator provides, and the multistep integrators' shared formula.

A multistep integrator approximates the velocity from positions at the new and earlier steps,

    v_{n+1} = α₀ x_{n+1} + α₁ xₙ + α₂ xₙ₋₁,        a_{n+1} = α₀ v_{n+1} + α₁ vₙ + α₂ vₙ₋₁,

so that M a_{n+1} = −∇Π(x_{n+1}) is the stationarity condition of

    E(x) = ½ α₀² ‖x − x̂‖²_M + Π(x),    x̂ = −(α₁ xₙ + α₂ xₙ₋₁)/α₀ − (α₁ vₙ + α₂ vₙ₋₁)/α₀².

Mass-proportional damping c M v adds ½ c α₀ ‖x − x̃‖²_M with x̃ = −(α₁ xₙ + α₂ xₙ₋₁)/α₀, which
merges with the inertia term into one quadratic of weight α₀² + c α₀.
"""

from __future__ import annotations

from typing import Any, ClassVar

import dolfinx.fem
import numpy as np

__all__ = ["Integrator", "MultistepIntegrator"]


class Integrator:
    """The history of an implicit integrator and the inertia term of its next step.

    Parameters
    ----------
    space
        The displacement's function space.
    displacement
        The displacement at the initial time (the local array, ghosts included).
    velocity
        The initial velocity (a local array like ``displacement``); ``None`` for rest.

    Attributes
    ----------
    displacement, velocity
        The state at the start of the next step (Functions on ``space``).
    """

    #: The ``scheme`` name (:data:`dolfinx_invertible.choices.SCHEMES`).
    name: ClassVar[str] = ""
    #: Order of accuracy.
    order: ClassVar[int] = 1

    def __init__(self, space, displacement: np.ndarray, velocity: np.ndarray | None) -> None:
        self.displacement = dolfinx.fem.Function(space)
        self.displacement.x.array[:] = displacement
        self.velocity = dolfinx.fem.Function(space)
        if velocity is not None:
            self.velocity.x.array[:] = velocity

    def start(self, dynamics) -> None:
        """Complete the initial state once the dynamics' problem is built (collective)."""

    def inertia(self, step: float, damping: float) -> tuple[float, np.ndarray]:
        """Return W and x̃ of the step's inertia term ½ W ‖x − x̃‖²_M (damping c included)."""
        raise NotImplementedError

    def commit(self, x: np.ndarray, step: float) -> None:
        """Advance the history to the accepted displacement ``x`` after a step of ``step``."""
        raise NotImplementedError

    def fields(self) -> dict[str, dolfinx.fem.Function]:
        """Return the Functions a continued run needs, by name (for a checkpoint)."""
        return {"displacement": self.displacement, "velocity": self.velocity}

    def state(self) -> dict[str, Any]:
        """Return the scalar state besides :meth:`fields`, as JSON values."""
        return {}

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`state` (the :meth:`fields` hold their values already)."""


class MultistepIntegrator(Integrator):
    """An integrator whose velocity combines the positions at the new and the last steps.

    Subclasses give :meth:`coefficients`; ``history`` says how many earlier steps it reads
    (2: the step ratio of a variable-step formula).
    """

    #: Earlier steps the formula reads.
    history: ClassVar[int] = 1

    def __init__(self, space, displacement: np.ndarray, velocity: np.ndarray | None) -> None:
        super().__init__(space, displacement, velocity)
        self.older = dolfinx.fem.Function(space)
        self.older_velocity = dolfinx.fem.Function(space)
        self.last_step: float | None = None

    @staticmethod
    def coefficients(step: float, previous_step: float | None) -> tuple[float, float, float]:
        """Return (α₀, α₁, α₂) for ``step`` after a step of ``previous_step`` (None: first)."""
        raise NotImplementedError

    def _coefficients(self, step: float) -> tuple[float, float, float]:
        return self.coefficients(step, self.last_step if self.history > 1 else None)

    def inertia(self, step: float, damping: float) -> tuple[float, np.ndarray]:
        """Return W = α₀² (+ c α₀) and x̂ (merged with x̃ under damping); see the module."""
        a0, a1, a2 = self._coefficients(step)
        positions = a1 * self.displacement.x.array + a2 * self.older.x.array
        velocities = a1 * self.velocity.x.array + a2 * self.older_velocity.x.array
        prediction = -positions / a0 - velocities / a0**2
        weight = a0 * a0
        if damping > 0.0:
            damped = -positions / a0
            weight = a0 * a0 + damping * a0
            prediction = (a0 * a0 * prediction + damping * a0 * damped) / weight
        return weight, prediction

    def commit(self, x: np.ndarray, step: float) -> None:
        """Shift the history by one step: v_{n+1} from the velocity formula."""
        a0, a1, a2 = self._coefficients(step)
        new_velocity = a0 * x + a1 * self.displacement.x.array + a2 * self.older.x.array
        self.older.x.array[:] = self.displacement.x.array
        self.older_velocity.x.array[:] = self.velocity.x.array
        self.displacement.x.array[:] = x
        self.velocity.x.array[:] = new_velocity
        self.last_step = step

    def fields(self) -> dict[str, dolfinx.fem.Function]:
        """Return the state and the one before it (BDF2 reads both)."""
        return {
            **super().fields(),
            "older_displacement": self.older,
            "older_velocity": self.older_velocity,
        }

    def state(self) -> dict[str, Any]:
        """Return the last step's size (the step ratio of a variable-step formula)."""
        return {"last_step": self.last_step}

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`state`."""
        last = state.get("last_step")
        self.last_step = None if last is None else float(last)
