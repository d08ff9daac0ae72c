"""Newton's method on an energy: PETSc SNES ``newtonls`` with an energy line search.

:class:`EnergyMinimizer` minimises the total potential of an
:class:`~dolfinx_invertible.solvers.problem.EnergyProblem`: the energy is the SNES objective, so
the backtracking line search works on it; conjugate gradients are preconditioned by algebraic
multigrid that knows the rigid-body modes.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time
from typing import Any

import numpy as np
from petsc4py import PETSc

from dolfinx_invertible import _compat
from dolfinx_invertible.solvers.nullspace import rigid_body_near_nullspace
from dolfinx_invertible.solvers.options import (
    DEFAULT_OPTIONS_PREFIX,
    DEFAULT_PETSC_OPTIONS,
    options_in_database,
)
from dolfinx_invertible.solvers.problem import EnergyProblem
from dolfinx_invertible.solvers.results import SolveResult, snes_reason_name
from dolfinx_invertible.solvers.step_limit import StepLimit

__all__ = ["EnergyMinimizer"]


@dataclasses.dataclass(frozen=True)
class _LineSearchStart:
    """What the line search knows at its starting point x (see ``EnergyMinimizer._objective``)."""

    handle: int  # of the PETSc vector x
    energy: float
    energy_scale: float  # sum of the absolute values of the energy forms
    slope: float  # F(x)·y for the Newton step y
    residual_norm: float


class EnergyMinimizer:
    """Newton's method (PETSc SNES ``newtonls``) for an :class:`EnergyProblem`.

    Not to be confused with ``dolfinx.nls.petsc.NewtonSolver``: this one drives PETSc SNES and
    can minimise an energy. With energy forms it is an energy minimiser: Π is the SNES objective
    and the backtracking line search ``bt`` shortens a step until Π does not rise (PETSc's test
    admits a rise of α·λ·F·y with α = 1e-4), which keeps Newton from jumping into inverted or
    otherwise high-energy states; an energy that cannot be evaluated (NaN) counts as +inf. Near
    the solution, where Π can no longer resolve the progress, the residual decides instead (see
    ``_objective``). Without energy forms (a material that only defines a stress) there is
    nothing to backtrack on; the line search is then ``l2``, which minimises the residual norm
    along the Newton direction.

    The linear solver is conjugate gradients (the tangent of an energy is symmetric; pass
    ``ksp_type`` for a non-symmetric one, and note that CG fails on an indefinite tangent, which
    load stepping then answers with a smaller step) preconditioned by GAMG, which is given the
    rigid-body modes as near-nullspace; ``pc="hypre"`` selects BoomerAMG instead, which does not
    use them.

    Options are set in this order, later ones winning: our defaults (see
    ``DEFAULT_PETSC_OPTIONS``, tolerances snes_rtol 1e-9, snes_atol 1e-10, snes_max_it 50,
    ksp_rtol 1e-10), ``petsc_options``, then options already in PETSc's database under
    ``options_prefix``, such as ``-dolfinx_invertible_snes_monitor`` on the command line.

    Parameters
    ----------
    problem
        What to solve.
    petsc_options
        PETSc options without prefix and without leading dash, e.g. ``{"snes_max_it": 10}``;
        ``None`` as a value sets a flag.
    options_prefix
        Prefix of the SNES, its KSP and PC in PETSc's options database.
    pc
        ``"gamg"`` (default), ``"hypre"`` for BoomerAMG, or any other PETSc PC type.
    step_limit
        Optional object with ``largest_step(direction, sign) -> float`` (e.g.
        :class:`~dolfinx_invertible.solvers.step_limit.InversionFreeStep`): each Newton step is
        scaled down to it before the energy line search.

    Attributes
    ----------
    snes
        The PETSc SNES, e.g. for monitors.
    line_search
        SNES line search type in effect: ``"bt"`` with energy, ``"l2"`` without, unless
        overridden by the options.
    """

    def __init__(
        self,
        problem: EnergyProblem,
        *,
        petsc_options: dict[str, Any] | None = None,
        options_prefix: str = DEFAULT_OPTIONS_PREFIX,
        pc: str = "gamg",
        step_limit: StepLimit | None = None,
    ) -> None:
        self.problem = problem
        self.u = problem.u
        self.step_limit = step_limit
        self.options_prefix = options_prefix
        options = dict(DEFAULT_PETSC_OPTIONS)
        options["snes_linesearch_type"] = "bt" if problem.has_energy else "l2"
        options["pc_type"] = pc
        if pc == "hypre":
            options["pc_hypre_type"] = "boomeramg"
        for name, value in (petsc_options or {}).items():
            options[name.lstrip("-")] = value
        self._options = options

        self._x = problem.create_vector()
        self._residual = problem.create_vector()
        self._backup = problem.create_vector()
        self._matrix = problem.create_matrix()
        self._matrix.setNearNullSpace(rigid_body_near_nullspace(problem.u.function_space))

        comm = problem.comm
        self.snes = PETSc.SNES().create(comm)
        self.snes.setOptionsPrefix(options_prefix)
        self.snes.setFunction(problem.F, self._residual)
        self.snes.setJacobian(problem.J, self._matrix, self._matrix)
        self._work = problem.create_vector()
        self._line_search_start: _LineSearchStart | None = None
        if problem.has_energy:
            self.snes.setObjective(self._objective)
            self.snes.setLineSearchPreCheck(self._start_line_search)
        self.snes.setConvergenceHistory(reset=True)
        with self._options_in_effect():
            self.snes.setFromOptions()
            # petsc4py 3.18 has no getter for the line search, so read what setFromOptions read.
            self.line_search = PETSc.Options(options_prefix).getString("snes_linesearch_type")

    def _options_in_effect(self) -> contextlib.AbstractContextManager[None]:
        return options_in_database(self.options_prefix, self._options)

    def newton_direction(self, direction: PETSc.Vec) -> int:
        """Compute the Newton direction at the current ``u`` as an iteration of :meth:`solve` does.

        Imposes the Dirichlet values, assembles residual and tangent and solves with the KSP that
        SNES uses (same options, preconditioner and near-nullspace); no line search, and ``u``
        keeps its value. Meant for benchmarks and diagnostics.

        Parameters
        ----------
        direction
            Receives the solution δ of tangent · δ = residual (a vector of
            :meth:`EnergyProblem.create_vector`'s layout).

        Returns
        -------
        int
            Krylov iterations; ``self.snes.getKSP().getConvergedReason()`` tells whether it
            converged.
        """
        u_vector = _compat.petsc_vector(self.problem.u)
        u_vector.copy(self._backup)
        u_vector.copy(self._x)
        _compat.set_dirichlet_values(self._x, self.problem.bcs)
        try:
            self.problem.F(self.snes, self._x, self._residual)
            self.problem.J(self.snes, self._x, self._matrix, self._matrix)
            ksp = self.snes.getKSP()
            with self._options_in_effect():
                ksp.setOperators(self._matrix, self._matrix)
                ksp.solve(self._residual, direction)
        finally:
            self._restore(u_vector)
        return int(ksp.getIterationNumber())

    def solve(self) -> SolveResult:
        """Solve from the current ``u`` with the current loads and boundary values.

        The Dirichlet values are imposed on the initial guess, so every Newton direction keeps
        them. Newton iterates on a separate vector; ``u`` receives the solution only if SNES
        converged and is otherwise left at its value before the call. Divergence is reported in
        the result, not raised.

        Returns
        -------
        SolveResult
            Convergence, iteration counts, final residual norm and energy.
        """
        start = time.perf_counter()
        problem = self.problem
        u_vector = _compat.petsc_vector(problem.u)
        u_vector.copy(self._backup)
        u_vector.copy(self._x)
        _compat.set_dirichlet_values(self._x, problem.bcs)
        self._line_search_start = None
        try:
            with self._options_in_effect():
                self.snes.solve(None, self._x)
        except BaseException:
            self._restore(u_vector)
            raise
        finally:
            self._line_search_start = None

        reason = int(self.snes.getConvergedReason())
        converged = reason > 0
        energy = None
        if converged:
            problem.update_solution(self._x)
            energy = problem.total_energy()
        else:
            self._restore(u_vector)
        history, _ = self.snes.getConvergenceHistory()
        return SolveResult(
            converged=converged,
            reason=reason,
            reason_name=snes_reason_name(reason),
            newton_iterations=int(self.snes.getIterationNumber()),
            linear_iterations=int(self.snes.getLinearSolveIterations()),
            residual_norm=float(self.snes.getFunctionNorm()),
            energy=energy,
            wall_time=time.perf_counter() - start,
            residual_history=tuple(float(norm) for norm in history),
        )

    def _restore(self, u_vector: PETSc.Vec) -> None:
        self._backup.copy(u_vector)
        self.problem.u.x.scatter_forward()

    def _start_line_search(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        # The line search evaluates the objective at x first; computing it here costs nothing
        # extra, and the per-form values give the scale of the energy's rounding error.
        self.problem.update_solution(x)
        if self.step_limit is not None:
            # SNES moves to x − λ y: cap y before the energy backtracking starts.
            largest = self.step_limit.largest_step(y, sign=-1.0)
            if largest < 1.0:
                y.scale(largest)
        terms = self.problem.energy_terms()
        energy = float(np.sum(terms))
        gradient = self._residual  # SNES keeps the residual at x in the vector it was given
        self._line_search_start = _LineSearchStart(
            handle=x.handle,
            energy=energy if not math.isnan(energy) else math.inf,
            energy_scale=float(np.sum(np.abs(terms))),
            slope=float(gradient.dot(y)),
            residual_norm=float(gradient.norm()),
        )

    def _objective(self, snes: PETSc.SNES, x: PETSc.Vec) -> float:
        """Return the SNES objective Π, made usable once Π stops resolving Newton's progress.

        Close to a solution the decrease of Π along a Newton step, about half the slope F·y, falls
        below the rounding error of Π itself (a sum over cells of terms much larger than the
        decrease); the backtracking test then compares noise and fails at random. PETSc would
        stop there with the residual still above tolerance. So a step that the energy test would
        reject is accepted anyway if it increased Π by no more than a rounding-sized amount
        (1e-6 of the energy's scale) and at least halved the residual norm: in that regime the
        residual is the reliable measure of progress. Accepting means returning a value below
        the starting energy, which passes PETSc's test whichever sign convention it uses for the
        slope (PETSc 3.18 uses +F·y, so its "sufficient decrease" admits a rise of α·λ·F·y).
        """
        start = self._line_search_start
        if start is None:
            return self.problem.objective(snes, x)
        if x.handle == start.handle:
            return start.energy
        energy = self.problem.objective(snes, x)
        if energy <= start.energy or not math.isfinite(start.energy):
            return energy
        if energy - start.energy > 1.0e-6 * max(start.energy_scale, abs(start.energy)):
            return energy
        self.problem.F(snes, x, self._work)
        if self._work.norm() > 0.5 * start.residual_norm:
            return energy
        return start.energy - abs(start.slope)
