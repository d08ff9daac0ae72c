"""The state of a scene run as its hooks and observers see it (:class:`Run`)."""

from __future__ import annotations

import dataclasses
import math
from time import perf_counter
from typing import Any

from dolfinx_invertible.scenes.parameters import Parameters
from dolfinx_invertible.scenes.scene import Scene
from dolfinx_invertible.solvers.dynamics import ImplicitDynamics
from dolfinx_invertible.solvers.hyperelastic import HyperelasticProblem
from dolfinx_invertible.solvers.results import SolveResult
from dolfinx_invertible.solvers.stepping import StepController

__all__ = ["Run"]


@dataclasses.dataclass
class Run:
    """The state of a scene run, as the scene's hooks see it after every step.

    Attributes
    ----------
    scene, parameters, material, mesh, u
        What runs.
    time
        Time (dynamic) or pseudo-time (quasi-static) of the last completed step.
    result
        The last step's :class:`~dolfinx_invertible.SolveResult` (None at t = 0).
    diagnostics
        Global counts of the last completed step (:func:`~dolfinx_invertible.summary`).
    dynamics, problem
        The stepping object (one of them is None).
    controller
        The step controller (of the dynamics, or of the load steps).
    body_contact
        The :class:`~dolfinx_invertible.contact.BodyContactTerm` between the surfaces of the
        bodies (``--self-contact``, several bodies), or None.
    min_distance, intersections
        With ``body_contact``: the smallest distance between surface primitives and the
        crossing surface facet pairs summed over the stored steps.
    """

    scene: Scene
    parameters: Parameters
    material: Any
    mesh: Any
    u: Any
    time: float = 0.0
    result: SolveResult | None = None
    diagnostics: dict[str, Any] = dataclasses.field(default_factory=dict)
    dynamics: ImplicitDynamics | None = None
    problem: HyperelasticProblem | None = None
    controller: StepController | None = None
    body_contact: Any = None
    steps: int = 0
    newton_total: int = 0
    newton_max: int = 0
    linear_total: int = 0
    max_inverted: int = 0
    min_J: float = math.inf  # noqa: N815 (the notation: J = det F)
    nan_encountered: bool = False
    min_distance: float = math.inf
    intersections: int = 0
    svd_points: dict[str, list[float]] = dataclasses.field(default_factory=dict)
    started: float = dataclasses.field(default_factory=perf_counter)

    @property
    def minimizer(self):
        """The :class:`~dolfinx_invertible.EnergyMinimizer` that solves every step."""
        stepper = self.dynamics.problem if self.dynamics is not None else self.problem
        return stepper.solver

    @property
    def kinetic_energy(self) -> float | None:
        """Kinetic energy of the current state (dynamic scenes, collective)."""
        return None if self.dynamics is None else self.dynamics.kinetic_energy
