"""Implicit dynamics as minimisation of an incremental potential (backward Euler or BDF2).

Each step minimises over the new displacement u

    E(u) = ρ w/2 ‖u − û‖²_M + ∫Ψ(F(u)) dX − ∫ρ g·u dX + (extra potential),

where the weight w and the target û come from the integrator (see
:mod:`~dolfinx_invertible.solvers.integrators`; backward Euler: w = 1/h², û = uₙ + h vₙ). Its
stationarity condition is the integrator's discrete momentum balance; being a minimisation, the
energy line search and the step limits apply unchanged. The mass matrix is consistent by
default; ``lumped_mass=True`` integrates the inertia term with the vertex rule (P1 only), which
lumps it. Quasi-static problems use
:class:`~dolfinx_invertible.solvers.hyperelastic.HyperelasticProblem` directly and carry no mass
term at all. Steps are controlled by the
:class:`~dolfinx_invertible.solvers.stepping.StepController` that load stepping uses too.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

from mpi4py import MPI

import dolfinx
import numpy as np
import ufl

from dolfinx_invertible import _compat
from dolfinx_invertible.constitutive.material import Material
from dolfinx_invertible.solvers.hyperelastic import HyperelasticProblem
from dolfinx_invertible.solvers.integrators import INTEGRATORS
from dolfinx_invertible.solvers.monitors import MonitorList, NewtonIteration, StepAttempt, StepCap
from dolfinx_invertible.solvers.results import SolveResult
from dolfinx_invertible.solvers.stepping import StepController, take_step

__all__ = ["ImplicitDynamics"]


class ImplicitDynamics:
    """Implicit time stepping of a hyperelastic body: backward Euler or variable-step BDF2.

    Parameters
    ----------
    u
        Displacement at the initial time (also the unknown of every step).
    material
        The :class:`~dolfinx_invertible.Material`.
    density
        Mass density ρ > 0 in the reference configuration.
    dt
        Time step h > 0: the largest step the controller takes.
    bcs
        Dirichlet conditions; for time-dependent data pass ``boundary_update``.
    velocity
        Initial velocity (a Function on the space of ``u``); zero by default.
    gravity
        Body acceleration g (a tuple with one entry per dimension), as the potential −ρ g·u.
    external_energy
        Further UFL potential in ``u`` (tractions, springs, ...).
    boundary_update
        ``boundary_update(t)`` sets the Dirichlet values (and any time-dependent load or
        obstacle) for time ``t``; called before every solve attempt, when ``u`` already holds
        that attempt's initial guess (the previous state), which it may adjust.
    scheme
        ``"backward-euler"`` (default; first order, strongly damping) or ``"bdf2"`` (second
        order, variable step).
    damping
        Mass-proportional damping coefficient c ≥ 0 [1/s]: a force −c ρ v per unit volume.
    lumped_mass
        Lump the mass matrix (vertex quadrature; P1 only).
    max_cuts
        Consecutive step cuts before a step gives up.
    controller
        The step policy; by default a :class:`~dolfinx_invertible.solvers.stepping.StepController`
        with nominal step ``dt`` (cut on failure, grow after easy steps, never above ``dt``).
    max_new_inverted
        If given, a converged step that inverts more than this many further quadrature cells
        (cells with det F ≤ 0 at a point) is cut and retried as if it had failed.
    **problem_options
        Passed to :class:`~dolfinx_invertible.solvers.hyperelastic.HyperelasticProblem`
        (``quadrature_degree``, ``project`` (default ``"auto"``), ``petsc_options``,
        ``options_prefix``, ``linear_solver``, ``pc``, ``inversion_free``, ``step_limits``,
        ``terms``, ``blend_after``, ...).

    Attributes
    ----------
    problem
        The :class:`~dolfinx_invertible.solvers.hyperelastic.HyperelasticProblem` of a step.
    time
        Time of the current state.
    steps
        Completed steps.
    velocity
        Velocity of the current state.
    """

    def __init__(
        self,
        u,
        material: Material,
        *,
        density: float,
        dt: float,
        bcs: Sequence[Any] = (),
        velocity=None,
        gravity: Sequence[float] | None = None,
        external_energy=None,
        boundary_update: Callable[[float], None] | None = None,
        scheme: str = "backward-euler",
        damping: float = 0.0,
        lumped_mass: bool = False,
        max_cuts: int = 6,
        controller: StepController | None = None,
        max_new_inverted: int | None = None,
        **problem_options,
    ):
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be a finite number > 0, got {dt!r}")
        if not (math.isfinite(density) and density > 0.0):
            raise ValueError(f"density must be a finite number > 0, got {density!r}")
        if not (math.isfinite(damping) and damping >= 0.0):
            raise ValueError(f"damping must be a finite number >= 0, got {damping!r}")
        if scheme not in INTEGRATORS:
            raise ValueError(f"scheme must be one of {sorted(INTEGRATORS)}, got {scheme!r}")
        space = u.function_space
        mesh = space.mesh
        d = mesh.geometry.dim
        if lumped_mass and _compat.element_degree(space) != 1:
            raise ValueError("lumped_mass is only available for P1 displacements (vertex rule)")
        self.u = u
        self.material = material
        self.integrator = INTEGRATORS[scheme]
        self.damping = float(damping)
        self.previous = dolfinx.fem.Function(space)
        self.previous.x.array[:] = u.x.array
        self.older = dolfinx.fem.Function(space)
        self.velocity = dolfinx.fem.Function(space)
        if velocity is not None:
            self.velocity.x.array[:] = velocity.x.array
        if not np.all(np.isfinite(self.velocity.x.array)):
            raise ValueError("the initial velocity contains NaN or Inf values")
        self.older_velocity = dolfinx.fem.Function(space)
        self.time = 0.0
        self.steps = 0
        self._last_step: float | None = None
        self.controller = controller or StepController(dt, max_cuts=max_cuts)
        self.boundary_update = boundary_update
        self.max_new_inverted = max_new_inverted

        self._weight = dolfinx.fem.Constant(mesh, 1.0 / dt**2)
        self._target = dolfinx.fem.Function(space)
        metadata = {"quadrature_rule": "vertex", "quadrature_degree": 1} if lumped_mass else {}
        mass_measure = ufl.dx(domain=mesh, metadata=metadata)
        offset = u - self._target
        energy = 0.5 * density * self._weight * ufl.dot(offset, offset) * mass_measure
        if gravity is not None:
            if len(gravity) != d:
                raise ValueError(f"gravity needs {d} components, got {len(gravity)}")
            g = dolfinx.fem.Constant(mesh, np.asarray(gravity, dtype=np.float64))
            energy = energy - density * ufl.dot(g, u) * ufl.dx(domain=mesh)
        if external_energy is not None:
            energy = energy + external_energy
        if boundary_update is not None:
            boundary_update(self.time)
        self.problem = HyperelasticProblem(
            u, material, bcs, external_energy=energy, **problem_options
        )
        self._on_attempt = MonitorList()
        self._kinetic_energy_form = dolfinx.fem.form(
            0.5 * density * ufl.dot(self.velocity, self.velocity) * ufl.dx(domain=mesh)
        )

    def add_monitor(
        self,
        *,
        on_iteration: Callable[[NewtonIteration], None] | None = None,
        on_step_cap: Callable[[StepCap], None] | None = None,
        on_attempt: Callable[[StepAttempt], None] | None = None,
    ) -> Callable[[], None]:
        """Observe Newton iterations, step caps and every attempt of a time step.

        ``on_iteration`` and ``on_step_cap`` see the minimiser of every step (see
        :meth:`~dolfinx_invertible.solvers.minimizer.EnergyMinimizer.add_monitor`);
        ``on_attempt`` gets a :class:`~dolfinx_invertible.solvers.monitors.StepAttempt` after
        every attempt, accepted or not. Returns a function that removes them again.
        """
        remove_solver = self.problem.add_monitor(on_iteration=on_iteration, on_step_cap=on_step_cap)
        remove_attempt = self._on_attempt.add(on_attempt) if on_attempt is not None else None

        def remove() -> None:
            remove_solver()
            if remove_attempt is not None:
                remove_attempt()

        return remove

    @property
    def dt(self) -> float:
        """The step size the next step attempts."""
        return self.controller.step

    def _coefficients(self, step: float) -> tuple[float, float, float]:
        previous = self._last_step if self.integrator.history > 1 else None
        return self.integrator.coefficients(step, previous)

    def _prepare(self, step: float) -> None:
        """Set the weight and target of the inertia term for a step of ``step``."""
        a0, a1, a2 = self._coefficients(step)
        positions = a1 * self.previous.x.array + a2 * self.older.x.array
        velocities = a1 * self.velocity.x.array + a2 * self.older_velocity.x.array
        prediction = -positions / a0 - velocities / a0**2
        weight = a0 * a0
        if self.damping > 0.0:
            # ½ c α₀ ‖u − ũ‖² with ũ = −(α₁uₙ + α₂uₙ₋₁)/α₀ merges with ½ α₀² ‖u − û‖².
            damped = -positions / a0
            weight = a0 * a0 + self.damping * a0
            prediction = (a0 * a0 * prediction + self.damping * a0 * damped) / weight
        self._weight.value = weight
        self._target.x.array[:] = prediction

    def _attempt(self, start: float, end: float) -> SolveResult:
        self._prepare(end - start)
        # The initial guess before the update, so that the update may adjust it (move boundary
        # vertices out of an obstacle that has moved into them).
        self.u.x.array[:] = self.previous.x.array
        if self.boundary_update is not None:
            self.boundary_update(end)
        return self.problem.solve()

    def _restore(self, start: float) -> None:
        if self.boundary_update is not None:
            self.boundary_update(start)
        self.u.x.array[:] = self.previous.x.array

    def _commit(self, step: float) -> None:
        a0, a1, a2 = self._coefficients(step)
        new_velocity = a0 * self.u.x.array + a1 * self.previous.x.array + a2 * self.older.x.array
        self.older.x.array[:] = self.previous.x.array
        self.older_velocity.x.array[:] = self.velocity.x.array
        self.previous.x.array[:] = self.u.x.array
        self.velocity.x.array[:] = new_velocity
        self._last_step = step
        self.time += step
        self.steps += 1

    def _inverted_cells(self) -> int:
        from dolfinx_invertible.fem.diagnostics import cell_diagnostics

        local = int(np.count_nonzero(cell_diagnostics(self.u, self.material)["inverted"]))
        return self.u.function_space.mesh.comm.allreduce(local, op=MPI.SUM)

    def step(self, remaining: float = math.inf) -> SolveResult:
        """Advance by one step (at most ``remaining``), cutting it on failure.

        Raises
        ------
        SolverError
            Newton failed ``max_cuts + 1`` times in a row; ``u``, the velocity and the time are
            those of the last completed step.
        """
        check = None
        if self.max_new_inverted is not None:
            before = self._inverted_cells()

            def check(result: SolveResult) -> str | None:
                new = self._inverted_cells() - before
                if new > self.max_new_inverted:
                    return f"the step inverted {new} more cells (limit {self.max_new_inverted})"
                return None

        def failure(start: float, end: float, result: SolveResult) -> str:
            return (
                f"time step {self.steps + 1} from t = {start:.6g} failed "
                f"{self.controller.consecutive_cuts} times (last dt = {end - start:.3g}): "
                f"{result.describe()}"
            )

        try:
            size, result = take_step(
                self.controller,
                self.time,
                remaining,
                self._attempt,
                self._restore,
                failure,
                check,
                escalate=self.problem.escalate,
                on_attempt=self._on_attempt if self._on_attempt else None,
            )
        except Exception as error:
            if hasattr(error, "step_index"):
                error.step_index = self.steps + 1
            raise
        self._commit(size)
        return result

    def advance(
        self, end_time: float, on_step: Callable[[float, SolveResult], None] | None = None
    ) -> list[SolveResult]:
        """Step until ``end_time``, the last step landing on it.

        ``on_step(t, result)`` is called after every completed step, so output written there
        survives a later failure.
        """
        results = []
        while self.time < end_time - 1e-12 * max(1.0, abs(end_time)):
            result = self.step(end_time - self.time)
            results.append(result)
            if on_step is not None:
                on_step(self.time, result)
        return results

    def checkpoint_fields(self) -> dict[str, Any]:
        """Return the Functions a continued run needs: the state and the one before it."""
        return {
            "displacement": self.previous,
            "velocity": self.velocity,
            "older_displacement": self.older,
            "older_velocity": self.older_velocity,
        }

    def checkpoint_state(self) -> dict[str, Any]:
        """Return the time, the step controller and the solver's mode, as JSON values."""
        return {
            "time": self.time,
            "steps": self.steps,
            "last_step": self._last_step,
            "controller": self.controller.state(),
            "escalated": self.problem.solver.blend_after == 0,
        }

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from a checkpoint: :meth:`checkpoint_fields` hold its Functions already."""
        self.time = float(state["time"])
        self.steps = int(state["steps"])
        self._last_step = None if state["last_step"] is None else float(state["last_step"])
        self.controller.restore(state["controller"])
        if state["escalated"]:
            self.problem.escalate()
        self.u.x.array[:] = self.previous.x.array
        if self.boundary_update is not None:
            self.boundary_update(self.time)

    @property
    def kinetic_energy(self) -> float:
        """½ ∫ρ|v|² dX with the consistent mass (for reports), summed over ranks."""
        local = dolfinx.fem.assemble_scalar(self._kinetic_energy_form)
        return self.u.function_space.mesh.comm.allreduce(local, op=MPI.SUM)
