"""Implicit dynamics: backward Euler as minimisation of the incremental potential.

Each step minimises over the new displacement u

    E(u) = ρ/(2h²) ‖u − ũ‖²_M + ∫Ψ(F(u)) dX − ∫ρ g·u dX + (extra potential),
    ũ = uₙ + h vₙ,

whose stationarity condition is M(u − uₙ − h vₙ)/h² + f_int(u) = f_ext: backward Euler. Being a
minimisation, the energy line search applies unchanged. Then vₙ₊₁ = (u − uₙ)/h. The mass matrix
is consistent by default; ``lumped_mass=True`` integrates the inertia term with the vertex rule
(P1 only), which lumps it. Quasi-static scenes use :class:`~dolfinx_invertible.solvers.hyperelastic.
HyperelasticProblem` directly and carry no mass term at all.
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
from dolfinx_invertible.solvers.results import SolverError, SolveResult

__all__ = ["ImplicitDynamics"]


class ImplicitDynamics:
    """Backward Euler time stepping of a hyperelastic body.

    Parameters
    ----------
    u
        Displacement at the initial time (also the unknown of every step).
    material
        The :class:`~dolfinx_invertible.Material`.
    density
        Mass density ρ > 0 in the reference configuration.
    dt
        Time step h > 0.
    bcs
        Dirichlet conditions; for time-dependent data pass ``boundary_update``.
    velocity
        Initial velocity (a Function on the space of ``u``); zero by default.
    gravity
        Body acceleration g (a tuple with one entry per dimension), as the potential −ρ g·u.
    external_energy
        Further UFL potential in ``u`` (tractions, springs, ...).
    boundary_update
        ``boundary_update(t)`` sets the Dirichlet values (and any time-dependent load) for
        time ``t``; called before every solve attempt.
    lumped_mass
        Lump the mass matrix (vertex quadrature; P1 only).
    max_cuts
        Consecutive halvings of the step before :meth:`step` gives up.
    **problem_options
        Passed to :class:`~dolfinx_invertible.solvers.hyperelastic.HyperelasticProblem`
        (``quadrature_degree``, ``project`` — default ``True`` here —, ``petsc_options``,
        ``options_prefix``, ``pc``, ``inversion_free``).
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
        lumped_mass: bool = False,
        max_cuts: int = 6,
        **problem_options,
    ):
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be a finite number > 0, got {dt!r}")
        if not (math.isfinite(density) and density > 0.0):
            raise ValueError(f"density must be a finite number > 0, got {density!r}")
        space = u.function_space
        mesh = space.mesh
        d = mesh.geometry.dim
        if lumped_mass and _compat.element_degree(space) != 1:
            raise ValueError("lumped_mass is only available for P1 displacements (vertex rule)")
        self.u = u
        self.previous = dolfinx.fem.Function(space)
        self.previous.x.array[:] = u.x.array
        self.velocity = dolfinx.fem.Function(space)
        if velocity is not None:
            self.velocity.x.array[:] = velocity.x.array
        if not np.all(np.isfinite(self.velocity.x.array)):
            raise ValueError("the initial velocity contains NaN or Inf values")
        self.dt = dolfinx.fem.Constant(mesh, float(dt))
        self.time = 0.0
        self.steps = 0
        self.max_cuts = int(max_cuts)
        self.boundary_update = boundary_update

        metadata = {"quadrature_rule": "vertex", "quadrature_degree": 1} if lumped_mass else {}
        mass_measure = ufl.dx(domain=mesh, metadata=metadata)
        prediction = self.previous + self.dt * self.velocity
        energy = 0.5 * density / self.dt**2 * ufl.dot(u - prediction, u - prediction) * mass_measure
        if gravity is not None:
            if len(gravity) != d:
                raise ValueError(f"gravity needs {d} components, got {len(gravity)}")
            g = dolfinx.fem.Constant(mesh, np.asarray(gravity, dtype=np.float64))
            energy = energy - density * ufl.dot(g, u) * ufl.dx(domain=mesh)
        if external_energy is not None:
            energy = energy + external_energy
        if boundary_update is not None:
            boundary_update(self.time)
        # Dynamics scenes are where elements get crushed and inverted, and the mass term keeps
        # the projected system well conditioned: project unless told otherwise (an "auto"
        # exact-first attempt mostly fails there and doubles the cost of a step).
        problem_options.setdefault("project", True)
        self.problem = HyperelasticProblem(
            u, material, bcs, external_energy=energy, **problem_options
        )
        self._kinetic_energy_form = dolfinx.fem.form(
            0.5 * density * ufl.dot(self.velocity, self.velocity) * ufl.dx(domain=mesh)
        )

    def step(self) -> SolveResult:
        """Advance by one step of the current ``dt``, halving it on failure.

        Raises
        ------
        SolverError
            Newton failed ``max_cuts + 1`` times in a row; ``u``, the velocity and the time are
            those of the last completed step.
        """
        dt = float(self.dt.value)
        for _ in range(self.max_cuts + 1):
            target = self.time + dt
            if self.boundary_update is not None:
                self.boundary_update(target)
            self.u.x.array[:] = self.previous.x.array
            result = self.problem.solve()
            if result.converged:
                self.velocity.x.array[:] = (self.u.x.array - self.previous.x.array) / dt
                self.previous.x.array[:] = self.u.x.array
                self.time = target
                self.steps += 1
                return result
            dt *= 0.5
            self.dt.value = dt
        if self.boundary_update is not None:
            self.boundary_update(self.time)
        self.u.x.array[:] = self.previous.x.array
        raise SolverError(
            f"backward Euler step {self.steps + 1} from t = {self.time:.6g} failed "
            f"{self.max_cuts + 1} times (last dt = {2 * dt:.3g}): Newton reason "
            f"{result.reason_name}",
            reason_name=result.reason_name,
            step_index=self.steps + 1,
            time_reached=self.time,
            time_tried=self.time + 2 * dt,
        )

    def advance(
        self, end_time: float, on_step: Callable[[float, SolveResult], None] | None = None
    ) -> list[SolveResult]:
        """Step until ``end_time``; after a cut the step grows back (doubling) to the original.

        ``on_step(t, result)`` is called after every completed step, so output written there
        survives a later failure.
        """
        nominal = float(self.dt.value)
        results = []
        while self.time < end_time - 1e-12 * max(1.0, abs(end_time)):
            self.dt.value = min(float(self.dt.value), end_time - self.time)
            result = self.step()
            results.append(result)
            if on_step is not None:
                on_step(self.time, result)
            self.dt.value = min(2.0 * float(self.dt.value), nominal)
        return results

    @property
    def kinetic_energy(self) -> float:
        """½ ∫ρ|v|² dX with the consistent mass (for reports), summed over ranks."""
        local = dolfinx.fem.assemble_scalar(self._kinetic_energy_form)
        return self.u.function_space.mesh.comm.allreduce(local, op=MPI.SUM)
