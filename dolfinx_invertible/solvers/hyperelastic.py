"""A hyperelastic problem for an existing DOLFINx script: material + BCs + extra UFL terms."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

from mpi4py import MPI

import dolfinx
import numpy as np
import ufl

from dolfinx_invertible.choices import ELASTIC_ROUTES, TANGENTS
from dolfinx_invertible.constitutive.material import Material
from dolfinx_invertible.fem.checks import check_boundary_conditions, check_mesh
from dolfinx_invertible.fem.forms import HyperelasticForms
from dolfinx_invertible.fem.ufl_forms import UFLNeoHookeanForms
from dolfinx_invertible.solvers.minimizer import EnergyMinimizer
from dolfinx_invertible.solvers.monitors import NewtonIteration, StepCap
from dolfinx_invertible.solvers.options import DEFAULT_OPTIONS_PREFIX
from dolfinx_invertible.solvers.problem import EnergyProblem, EnergyTerm
from dolfinx_invertible.solvers.results import SolveResult
from dolfinx_invertible.solvers.step_limit import InversionFreeStep, StepLimit

__all__ = ["HyperelasticProblem", "external_forms"]


def external_forms(u, energy) -> tuple[Any, Any, Any | None]:
    """Compiled (energy, residual, jacobian) of a UFL potential in ``u``; jacobian None if zero.

    A potential linear in ``u`` (a dead load) has a zero second derivative, which UFL reduces to
    an empty form that DOLFINx cannot compile; it then contributes nothing to the tangent.
    """
    residual = ufl.derivative(energy, u)
    jacobian = ufl.derivative(residual, u)
    jacobian_is_zero = ufl.algorithms.expand_derivatives(jacobian).empty()
    return (
        dolfinx.fem.form(energy),
        dolfinx.fem.form(residual),
        None if jacobian_is_zero else dolfinx.fem.form(jacobian),
    )


class HyperelasticProblem:
    """Minimise ∫Ψ(F) dX + (extra UFL potential) over ``u`` subject to Dirichlet conditions.

    Parameters
    ----------
    u
        Displacement (vector P1/P2 Lagrange); holds the initial guess and, after
        :meth:`solve`, the solution.
    material
        The :class:`~dolfinx_invertible.Material`.
    bcs
        ``dolfinx.fem.DirichletBC`` objects on the space of ``u``.
    external_energy
        A UFL scalar form in ``u`` added to the elastic energy: loads as potentials, e.g.
        ``-ufl.dot(traction, u) * ds`` or ``-ufl.dot(body_force, u) * dx``, springs, penalties.
        Its residual and tangent come from ``ufl.derivative`` and are assembled into the same
        PETSc vector and matrix as the elastic kernels.
    quadrature_degree
        See :class:`~dolfinx_invertible.fem.forms.HyperelasticForms`.
    project
        ``True``: always the SPD-projected tangent (robust, but Newton then converges only
        linearly wherever the exact tangent is indefinite, e.g. under compression);
        ``False``: always the exact tangent (quadratic convergence; a solve fails where the
        exact tangent gives no descent direction); ``"auto"`` (default): the exact tangent,
        and in any Newton iteration where its direction is not a descent direction or its linear
        solve fails, the projected tangent's at the same iterate. ``result.tangent`` says which
        were used (``"exact+projected"`` for both), ``result.projected_iterations`` how often
        the projected one stepped in.
    petsc_options, options_prefix, linear_solver, pc, displacement_tolerance, blend_after,
    globalization, indefinite_newton
        See :class:`~dolfinx_invertible.solvers.minimizer.EnergyMinimizer`; command-line options
        with the prefix override everything.
    inversion_free
        If given (a fraction in (0, 1), 0.1 in the classical method), cap every Newton step so
        that no quadrature point's volume falls below that fraction of its current value
        (:class:`~dolfinx_invertible.solvers.step_limit.InversionFreeStep`); meant for plain
        barrier energies such as Neo-Hookean without extension, started from an uninverted
        state.
    step_limits
        Further step caps (:class:`~dolfinx_invertible.solvers.step_limit.StepLimit`), e.g.
        continuous collision detection against obstacles.
    terms
        Energy contributions that are not forms
        (:class:`~dolfinx_invertible.solvers.problem.EnergyTerm`), e.g. a contact barrier. A
        term that can switch between its exact and projected Hessian follows ``"auto"``; with
        ``True`` or ``False`` (no replacement of a bad direction) it adds the projected one.
    elastic
        How the elastic energy is assembled: ``"kernels"`` (default, this package's numba
        kernels) or ``"ufl"`` (DOLFINx's own route, UFL compiled by FFCx: plain Neo-Hookean
        only, exact tangent only — the baseline of comparisons).

    Attributes
    ----------
    forms
        The :class:`~dolfinx_invertible.fem.forms.HyperelasticForms` of the material.
    energy_problem, solver
        The :class:`~dolfinx_invertible.solvers.problem.EnergyProblem` that assembles the
        summed forms and the :class:`~dolfinx_invertible.solvers.minimizer.EnergyMinimizer`.
    """

    def __init__(
        self,
        u,
        material: Material,
        bcs: Sequence[Any] = (),
        *,
        external_energy=None,
        quadrature_degree: int | None = None,
        project: bool | str = "auto",
        petsc_options: dict[str, Any] | None = None,
        options_prefix: str = DEFAULT_OPTIONS_PREFIX,
        linear_solver: str = "auto",
        pc: str = "gamg",
        displacement_tolerance: float = 1.0e-10,
        inversion_free: float | None = None,
        step_limits: Sequence[StepLimit] = (),
        terms: Sequence[EnergyTerm] = (),
        elastic: str = "kernels",
        blend_after: int | None = None,
        globalization: str = "auto",
        indefinite_newton: bool = True,
    ):
        mesh = u.function_space.mesh
        allowed = [choice.value for choice in TANGENTS.values()]
        if project not in allowed:
            raise ValueError(f"project must be one of {allowed}, got {project!r}")
        ELASTIC_ROUTES.check(elastic)
        if elastic == "ufl":
            if project is True:
                raise ValueError("DOLFINx's own route (elastic='ufl') has no projected tangent")
            project = False
        self.project = project
        # The forms validate the space and geometry first: the volume check assumes both.
        if elastic == "ufl":
            self.forms = UFLNeoHookeanForms(u, material, quadrature_degree=quadrature_degree)
        else:
            self.forms = HyperelasticForms(
                u, material, quadrature_degree=quadrature_degree, project=project is True
            )
        check_mesh(mesh)
        bcs = list(bcs)
        check_boundary_conditions(bcs, mesh.comm)
        local_finite = bool(np.all(np.isfinite(u.x.array)))
        if not mesh.comm.allreduce(local_finite, op=MPI.LAND):
            raise ValueError("the initial displacement u contains NaN or Inf values")
        self.u = u
        has_energy = material.extension is None or material.extension.has_energy
        energy = [self.forms.energy] if has_energy else []
        residual = [self.forms.residual]
        jacobian = [self.forms.jacobian]
        if external_energy is not None:
            extra_energy, extra_residual, extra_jacobian = external_forms(u, external_energy)
            if has_energy:
                energy.append(extra_energy)
            residual.append(extra_residual)
            if extra_jacobian is not None:
                jacobian.append(extra_jacobian)
        self.energy_problem = EnergyProblem(u, energy, residual, jacobian, bcs, terms=terms)
        # Terms that follow the tangent add their exact Hessian only where the minimiser can
        # replace a direction that is not a descent direction, i.e. with the tangent switch.
        self.energy_problem.set_term_projection(project != "auto")
        limits = list(step_limits)
        if inversion_free is not None:
            limits.append(
                InversionFreeStep(u, inversion_free, quadrature_degree=self.forms.quadrature_degree)
            )
        self.solver = EnergyMinimizer(
            self.energy_problem,
            petsc_options=petsc_options,
            options_prefix=options_prefix,
            linear_solver=linear_solver,
            pc=pc,
            step_limits=limits,
            tangent_switch=self._switch_tangent if project == "auto" else None,
            tangent="projected" if project is True else "exact",
            displacement_tolerance=displacement_tolerance,
            blend_after=blend_after,
            globalization=globalization,
            indefinite_newton=indefinite_newton,
        )

    def _switch_tangent(self, projected: bool) -> None:
        self.forms.set_projection(projected)
        self.energy_problem.set_term_projection(projected)

    def add_monitor(
        self,
        *,
        on_iteration: Callable[[NewtonIteration], None] | None = None,
        on_step_cap: Callable[[StepCap], None] | None = None,
    ) -> Callable[[], None]:
        """Observe the Newton iterations and step caps of every solve; see the minimiser's.

        Returns a function that removes the monitors again.
        """
        return self.solver.add_monitor(on_iteration=on_iteration, on_step_cap=on_step_cap)

    def escalate(self) -> bool:
        """Switch to the slower, more robust Newton (blended tangents); see the minimiser's."""
        return self.solver.escalate()

    def solve(self) -> SolveResult:
        """Solve from the current ``u``; return a :class:`~dolfinx_invertible.SolveResult`.

        On failure ``u`` keeps its value from before the call (see ``result.converged`` and
        ``result.describe()``). ``result.svd_share`` says how often the kernels needed the SVD
        during the solve.
        """
        self.forms.reset_path_counts()
        result = self.solver.solve()
        if self.project == "auto":
            tangent = "exact+projected" if result.projected_iterations else "exact"
        else:
            tangent = "projected" if self.project else "exact"
        counts = self.forms.path_counts()
        # One reduction for all kernels: rows (points, points through the SVD).
        totals = self.u.function_space.mesh.comm.allreduce(
            np.array(list(counts.values()), dtype=np.int64).reshape(-1, 2), op=MPI.SUM
        )
        shares = {
            kind: float(svd_points / points) if points > 0 else None
            for kind, (points, svd_points) in zip(counts, totals, strict=True)
        }
        return dataclasses.replace(result, tangent=tangent, svd_share=shares)
