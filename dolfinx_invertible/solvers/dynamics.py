"""Implicit dynamics as minimisation of an incremental potential, one integrator per scheme.

Each step minimises over the new displacement u

    E(u) = ρ W/2 ‖u − ũ‖²_M + ∫Ψ(F(u)) dX − ∫ρ g·u dX + (extra potential),

where the weight W and the target ũ come from the integrator
(:mod:`~dolfinx_invertible.solvers.integrators`: backward Euler, BDF2, Newmark; backward Euler:
W = 1/h², ũ = uₙ + h vₙ). Its stationarity condition is the integrator's discrete momentum
balance; being a minimisation, the energy line search and the step limits apply unchanged. The
mass matrix is consistent by default; ``lumped_mass=True`` integrates the inertia term with the
vertex rule (P1 only), which lumps it. Quasi-static problems step with
:class:`~dolfinx_invertible.solvers.quasi_static.QuasiStatic` and carry no mass term at all; both
are :class:`~dolfinx_invertible.solvers.stepper.Stepper` siblings under the same step controller.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from mpi4py import MPI

import dolfinx
import numpy as np
import ufl
from petsc4py import PETSc

from dolfinx_invertible import _compat
from dolfinx_invertible.choices import SCHEMES
from dolfinx_invertible.constitutive.material import Material
from dolfinx_invertible.solvers.hyperelastic import HyperelasticProblem
from dolfinx_invertible.solvers.results import SolveResult
from dolfinx_invertible.solvers.stepper import Stepper
from dolfinx_invertible.solvers.stepping import StepController

__all__ = ["ImplicitDynamics"]


class ImplicitDynamics(Stepper):
    """Implicit time stepping of a hyperelastic body: backward Euler, BDF2 or Newmark.

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
        A name of :data:`~dolfinx_invertible.choices.SCHEMES`: ``"backward-euler"`` (default;
        first order, strongly damping), ``"bdf2"`` (second order, variable step) or
        ``"newmark"`` (average acceleration: second order, no numerical damping).
    damping
        Mass-proportional damping coefficient c ≥ 0 [1/s]: a force −c ρ v per unit volume.
    lumped_mass
        Lump the mass matrix (vertex quadrature; P1 only).
    max_cuts
        Consecutive step cuts before a step gives up (when no ``controller`` is given).
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
    integrator
        The :class:`~dolfinx_invertible.solvers.integrators.Integrator`: the state at the start
        of the next step and its history.
    time
        Time of the current state.
    steps
        Completed steps.
    velocity
        Velocity of the current state.
    """

    step_name = "time step"

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
        SCHEMES.check(scheme)
        space = u.function_space
        mesh = space.mesh
        d = mesh.geometry.dim
        if lumped_mass and _compat.element_degree(space) != 1:
            raise ValueError("lumped_mass is only available for P1 displacements (vertex rule)")
        initial_velocity = None
        if velocity is not None:
            initial_velocity = velocity.x.array
            if not np.all(np.isfinite(initial_velocity)):
                raise ValueError("the initial velocity contains NaN or Inf values")
        self.material = material
        self.integrator = SCHEMES.resolve(scheme)(space, u.x.array, initial_velocity)
        self.damping = float(damping)
        self.max_new_inverted = max_new_inverted
        self.density = float(density)

        self._weight = dolfinx.fem.Constant(mesh, 1.0 / dt**2)
        self._target = dolfinx.fem.Function(space)
        metadata = {"quadrature_rule": "vertex", "quadrature_degree": 1} if lumped_mass else {}
        self._mass_measure = ufl.dx(domain=mesh, metadata=metadata)
        offset = u - self._target
        energy = 0.5 * density * self._weight * ufl.dot(offset, offset) * self._mass_measure
        if gravity is not None:
            if len(gravity) != d:
                raise ValueError(f"gravity needs {d} components, got {len(gravity)}")
            g = dolfinx.fem.Constant(mesh, np.asarray(gravity, dtype=np.float64))
            energy = energy - density * ufl.dot(g, u) * ufl.dx(domain=mesh)
        if external_energy is not None:
            energy = energy + external_energy
        if boundary_update is not None:
            boundary_update(0.0)
        problem = HyperelasticProblem(u, material, bcs, external_energy=energy, **problem_options)
        super().__init__(
            problem, controller or StepController(dt, max_cuts=max_cuts), boundary_update
        )
        self._kinetic_energy_form = dolfinx.fem.form(
            0.5 * density * ufl.dot(self.velocity, self.velocity) * ufl.dx(domain=mesh)
        )
        self.integrator.start(self)

    @property
    def dt(self) -> float:
        """The step size the next step attempts."""
        return self.controller.step

    @property
    def velocity(self) -> dolfinx.fem.Function:
        """Velocity of the current state."""
        return self.integrator.velocity

    @property
    def previous(self) -> dolfinx.fem.Function:
        """Displacement of the current state (``u`` holds an iterate during a step)."""
        return self.integrator.displacement

    def _attempt(self, start: float, end: float) -> SolveResult:
        weight, target = self.integrator.inertia(end - start, self.damping)
        self._weight.value = weight
        self._target.x.array[:] = target
        # The initial guess before the update, so that the update may adjust it (move boundary
        # vertices out of an obstacle that has moved into them).
        self.u.x.array[:] = self.previous.x.array
        self._set_time(end)
        return self.problem.solve()

    def _restore(self, start: float) -> None:
        self._set_time(start)
        self.u.x.array[:] = self.previous.x.array

    def _commit(self, size: float) -> None:
        self.integrator.commit(self.u.x.array, size)
        self.time += size

    def _inverted_cells(self) -> int:
        from dolfinx_invertible.fem.diagnostics import cell_diagnostics

        local = int(np.count_nonzero(cell_diagnostics(self.u, self.material)["inverted"]))
        return self.u.function_space.mesh.comm.allreduce(local, op=MPI.SUM)

    def _check(self) -> Callable[[SolveResult], str | None] | None:
        if self.max_new_inverted is None:
            return None
        before = self._inverted_cells()

        def check(result: SolveResult) -> str | None:
            new = self._inverted_cells() - before
            if new > self.max_new_inverted:
                return f"the step inverted {new} more cells (limit {self.max_new_inverted})"
            return None

        return check

    def _failure(self, start: float, end: float, result: SolveResult) -> str:
        return (
            f"time step {self.steps + 1} from t = {start:.6g} failed "
            f"{self.controller.consecutive_cuts} times (last dt = {end - start:.3g}): "
            f"{result.describe()}"
        )

    @contextlib.contextmanager
    def inertia_weight(self, weight: float) -> Iterator[None]:
        """Assemble with the inertia term's weight (1/dt² in a step) set to ``weight``.

        0 leaves the elastic terms and the loads alone, 1 adds the mass term once; the step's
        weight is restored on leaving.
        """
        saved = self._weight.value.copy()
        self._weight.value = weight
        try:
            yield
        finally:
            self._weight.value = saved

    def static_acceleration(self) -> np.ndarray:
        """Return a with M a = −∇(Π − ∫ρ g·u) at the current ``u``: the momentum balance at rest.

        The local array (ghosts included) of the acceleration the forces alone give, zero at
        the Dirichlet dofs; Newmark's rule starts from it. Collective.
        """
        space = self.u.function_space
        energy_problem = self.problem.energy_problem
        with self.inertia_weight(0.0):
            force = energy_problem.create_vector()
            energy_problem.F(None, _compat.petsc_vector(self.u), force)
        trial, test = ufl.TrialFunction(space), ufl.TestFunction(space)
        mass_form = dolfinx.fem.form(self.density * ufl.dot(trial, test) * self._mass_measure)
        mass = _compat.create_matrix(mass_form)
        _compat.assemble_matrix_into(mass, mass_form, energy_problem.bcs, 1.0)
        mass.assemble()
        force.scale(-1.0)
        with force.localForm() as local:
            local.array[energy_problem.constrained_dofs] = 0.0
        acceleration = dolfinx.fem.Function(space)
        solver = PETSc.KSP().create(space.mesh.comm)
        solver.setOperators(mass)
        solver.setType("cg")
        solver.getPC().setType("jacobi")
        solver.setTolerances(rtol=1e-14, atol=0.0, max_it=1000)
        solver.solve(force, _compat.petsc_vector(acceleration))
        acceleration.x.scatter_forward()
        for item in (solver, mass, force):
            item.destroy()
        return acceleration.x.array.copy()

    def checkpoint_fields(self) -> dict[str, Any]:
        """Return the Functions a continued run needs: the integrator's state and history."""
        return self.integrator.fields()

    def checkpoint_state(self) -> dict[str, Any]:
        """Return the time, the step controller, the solver's mode and the integrator's state."""
        return {**super().checkpoint_state(), "integrator": self.integrator.state()}

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from a checkpoint: :meth:`checkpoint_fields` hold its Functions already."""
        super().restore(state)
        self.integrator.restore(state["integrator"])
        self.u.x.array[:] = self.previous.x.array
        self._set_time(self.time)

    @property
    def kinetic_energy(self) -> float:
        """½ ∫ρ|v|² dX with the consistent mass (for reports), summed over ranks."""
        local = dolfinx.fem.assemble_scalar(self._kinetic_energy_form)
        return self.u.function_space.mesh.comm.allreduce(local, op=MPI.SUM)
