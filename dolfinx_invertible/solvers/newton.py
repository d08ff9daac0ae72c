"""Newton's method on an energy: PETSc SNES ``newtonls`` with the minimiser's own line search.

:class:`EnergyMinimizer` minimises the total potential of an
:class:`~dolfinx_invertible.solvers.problem.EnergyProblem`. SNES computes the Newton direction;
the minimiser judges it in the line search's pre-check: it replaces a failed or non-descent
direction of the exact tangent by the projected tangent's (where the caller can switch), caps
the step (step limits such as the inversion-free cap), then backtracks on the energy. Its own
convergence test uses tolerances scaled to the problem, so that scaling the stiffness, the
density and the loads by any factor leaves the iterations unchanged.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from petsc4py import PETSc

from dolfinx_invertible import _compat
from dolfinx_invertible.fem.checks import mean_cell_size
from dolfinx_invertible.solvers.nullspace import rigid_body_near_nullspace
from dolfinx_invertible.solvers.options import (
    DEFAULT_OPTIONS_PREFIX,
    DEFAULT_PETSC_OPTIONS,
    linear_solver_options,
    options_in_database,
)
from dolfinx_invertible.solvers.problem import EnergyProblem
from dolfinx_invertible.solvers.results import SolveResult, ksp_reason_name, snes_reason_name
from dolfinx_invertible.solvers.step_limit import StepLimit

__all__ = ["EnergyMinimizer"]

_REASONS = PETSc.SNES.ConvergedReason
# The rounding error of an energy (a sum over cells of sums over quadrature points of terms that
# may cancel) in units of ε times its scale; generous, so that noise is never taken for progress.
_ROUNDING = 100.0 * np.finfo(np.float64).eps
_SAME_PATTERN = PETSc.Mat.Structure.SAME_NONZERO_PATTERN
# Weights of the removed negative curvature tried in a blended tangent (_blended_direction),
# from nearly the exact tangent down to nearly the projected one.
_BLEND_WEIGHTS = (1.0 - 1.0 / 512.0, 1.0 - 1.0 / 64.0, 1.0 - 1.0 / 8.0, 0.5, 1.0 / 8.0, 1.0 / 64.0)


@dataclasses.dataclass
class _SolveState:
    """What one solve's callbacks share."""

    tolerance: float = 0.0
    initial_norm: float | None = None
    failure: tuple[int, str, str] | None = None  # (SNES reason, stage, detail)
    converged_detail: str | None = None
    projected_iterations: int = 0
    # With a tangent switch: the next tangent is the exact one only in the local phase, after a
    # full (unshortened) step; the projected one otherwise.
    exact_next: bool = True
    projected_now: bool = False
    full_step: bool = True
    watchdog: _Watchdog | None = None
    watchdog_spent: bool = False  # after one failed watch, this solve backtracks monotonically
    blend_rung: int = 0  # index of the last weight of K − K₊ that kept the blend definite
    blended_iterations: int = 0
    # Π and its terms at the point in EnergyMinimizer._energy_point, the last one evaluated.
    last_energy: tuple[float, np.ndarray] | None = None


@dataclasses.dataclass
class _Watchdog:
    """The iterate before tentative full Newton steps, to go back to if they do not pay off."""

    energy: float
    slope: float  # −(directional derivative) of the full step from the origin
    residual_norm: float
    remaining: int  # further full steps allowed before the energy must be below the origin's


class EnergyMinimizer:
    """Newton's method (PETSc SNES ``newtonls``) minimising an :class:`EnergyProblem`.

    Not to be confused with ``dolfinx.nls.petsc.NewtonSolver``: this one drives PETSc SNES and
    minimises an energy. Every Newton iteration:

    1. SNES assembles the tangent and solves for the Newton direction (``linear_solver``).
    2. If that linear solve failed or its direction is not a descent direction (the exact
       tangent is indefinite there) and ``tangent_switch`` is given, the direction is computed
       again from the projected tangent at the same iterate (``result.projected_iterations``
       counts these). Once a solve has taken ``blend_after`` projected iterations (after
       :meth:`escalate`: from the first; by default never) and where
       the factorisation reports its inertia (the direct solver, MUMPS LDLᵀ), the direction
       comes instead from the blend K₊ + w (K − K₊) of the projected tangent K₊ and the exact
       one K with the largest weight w of a ladder (511/512 … 1/64) whose factorisation has no
       negative pivot (``result.blended_iterations`` counts these): the projection drops all of
       the cells' negative curvature, even where the mass or the rest of the body outweighs
       most of it, and Newton on K₊ then converges only linearly (out of a collapsed state at
       λ/μ = 49: 86 iterations, against 16 with the blend). It is a last resort, not
       the default: a step that the blend brings home in many iterations has often travelled
       to another minimum of the step's energy (an inverted one, in a collapse) where cutting
       the step would have kept the motion resolved. The steppers escalate to it when the cuts
       of a step are used up. A failure that remains ends the solve at the stage "linear
       solve" or "line search".
    3. ``step_limits`` cap the step (e.g. the inversion-free cap).
    4. Backtracking on the energy Π: a step is accepted when Π decreases by the Armijo amount
       (``sufficient_decrease`` times the exact directional derivative; the full Newton step
       whenever it qualifies). Where the change of Π is below Π's own rounding error, the
       residual decides instead: the step is accepted if it reduces the residual norm. If no
       step of up to ``max_backtracks`` halvings qualifies, the solve ends at the stage "line
       search", unless the predicted decrease itself is below rounding, in which case the
       iterate is converged as far as floating point can tell.
    5. A watchdog (Chamberlain et al. 1982) lets Newton take the full step when the energy
       test rejects it but Newton is about to converge anyway: a full step to a finite energy
       that fails the test is taken tentatively, and so are up to ``watchdog_steps`` more; as
       soon as an iterate's energy is below the origin's by the Armijo amount, the watch ends.
       If none is, the solve returns to the origin and backtracks from there (once per solve;
       later steps backtrack directly). So a step plain Newton takes is taken, and the energy
       still decreases over every watch. A solve does not end at a tentative iterate whose
       energy is above the origin's.

    A problem without energy forms (a stress-only material such as IFE) has nothing to
    backtrack on; its line search is PETSc's ``l2``, which minimises the residual norm along the
    direction (steps 2 and 3 still apply).

    The solve is converged when the residual norm (Dirichlet rows included, as SNES measures
    it) is at most ``max(atol, rtol · ‖r₀‖)``. ``rtol`` is ``snes_rtol`` (default 1e-9). ``atol``
    is ``snes_atol`` if given; by default it is scaled to the problem: the residual that a
    displacement of ``displacement_tolerance`` (1e-10) times the mean cell size on every free
    dof would produce through the diagonal of the tangent, ``η · h · k · √n`` with k the typical
    (median) magnitude of a free diagonal entry of the last tangent and n the free dofs. It scales
    with the stiffness, the density (through the mass of a dynamic step) and hence with the
    loads, so a problem whose material, density and loads are all scaled by one factor takes
    the same iterations; a solve that starts at a solution takes none.

    Options are set in this order, later ones winning: our defaults (see
    :data:`~dolfinx_invertible.solvers.options.DEFAULT_PETSC_OPTIONS` and
    :func:`~dolfinx_invertible.solvers.options.linear_solver_options`), ``petsc_options``, then
    options already in PETSc's database under ``options_prefix``, such as
    ``-dolfinx_invertible_snes_monitor`` on the command line.

    Parameters
    ----------
    problem
        What to solve.
    petsc_options
        PETSc options without prefix and without leading dash, e.g. ``{"snes_max_it": 10}``;
        ``None`` as a value sets a flag.
    options_prefix
        Prefix of the SNES, its KSP and PC in PETSc's options database.
    linear_solver
        ``"auto"`` (default): a sparse direct solve up to
        :data:`~dolfinx_invertible.solvers.options.DIRECT_SOLVE_LIMIT` unknowns, conjugate
        gradients with ``pc`` above; or ``"direct"``, ``"iterative"``.
    pc
        Preconditioner of the iterative solver: ``"gamg"`` (default; given the rigid-body
        modes), ``"hypre"`` for BoomerAMG, or any other PETSc PC type.
    step_limits
        Step caps applied before the line search, each with ``largest_step(direction, sign)``
        (:class:`~dolfinx_invertible.solvers.step_limit.StepLimit`); the smallest wins.
    tangent_switch
        ``tangent_switch(projected)`` switches the tangent that the problem's Jacobian
        assembles between exact (``False``, the state between iterations) and SPD-projected
        (``True``); given, the projected tangent replaces a failed exact one (step 2 above).
    displacement_tolerance
        η of the default absolute tolerance, relative to the mean cell size.
    sufficient_decrease
        Armijo constant of the energy line search.
    max_backtracks
        Halvings of the step before the line search gives up.
    watchdog_steps
        Tentative full steps after the first before the energy must have decreased (step 5);
        0 turns the watchdog off.
    blend_after
        Projected iterations of a solve after which the exact and the projected tangent are
        blended where the exact one is indefinite (step 2); ``None`` (default) never blends
        until :meth:`escalate` is called.

    Attributes
    ----------
    snes
        The PETSc SNES, e.g. for monitors.
    line_search
        ``"energy"`` (ours) or ``"l2"`` (PETSc's, without energy), unless the options override.
    linear_solver
        ``"direct"`` or ``"iterative"``: what ``"auto"`` chose.
    """

    def __init__(
        self,
        problem: EnergyProblem,
        *,
        petsc_options: dict[str, Any] | None = None,
        options_prefix: str = DEFAULT_OPTIONS_PREFIX,
        linear_solver: str = "auto",
        pc: str = "gamg",
        step_limits: Sequence[StepLimit] = (),
        tangent_switch: Callable[[bool], None] | None = None,
        displacement_tolerance: float = 1.0e-10,
        sufficient_decrease: float = 1.0e-4,
        max_backtracks: int = 30,
        watchdog_steps: int = 2,
        blend_after: int | None = None,
    ) -> None:
        if not (math.isfinite(displacement_tolerance) and displacement_tolerance > 0.0):
            raise ValueError(
                f"displacement_tolerance must be a number > 0, got {displacement_tolerance!r}"
            )
        self.problem = problem
        self.u = problem.u
        self.step_limits = list(step_limits)
        self.tangent_switch = tangent_switch
        self.displacement_tolerance = float(displacement_tolerance)
        self.sufficient_decrease = float(sufficient_decrease)
        self.max_backtracks = int(max_backtracks)
        if int(watchdog_steps) != watchdog_steps or watchdog_steps < 0:
            raise ValueError(f"watchdog_steps must be an integer >= 0, got {watchdog_steps!r}")
        self.watchdog_steps = int(watchdog_steps)
        self.options_prefix = options_prefix

        space = problem.u.function_space
        dimension = space.mesh.geometry.dim
        global_size = space.dofmap.index_map.size_global * space.dofmap.index_map_bs
        options = dict(DEFAULT_PETSC_OPTIONS)
        if not problem.has_energy:
            options["snes_linesearch_type"] = "l2"
        solver_options = linear_solver_options(
            linear_solver, pc, global_size, dimension, problem.comm.size
        )
        options.update(solver_options)
        self.linear_solver = "direct" if solver_options["ksp_type"] == "preonly" else "iterative"
        given = {name.lstrip("-"): value for name, value in (petsc_options or {}).items()}
        options.update(given)
        self._options = options
        database = PETSc.Options(options_prefix)
        self._user_atol = given.get("snes_atol")
        if database.hasName("snes_atol"):
            self._user_atol = database.getReal("snes_atol")

        self._x = problem.create_vector()
        self._residual = problem.create_vector()
        self._backup = problem.create_vector()
        self._trial = problem.create_vector()
        self._work = problem.create_vector()
        self._watch_origin = problem.create_vector()
        self._watch_direction = problem.create_vector()
        self._energy_point = problem.create_vector()
        self._diagonal = problem.create_vector()
        self._matrix = problem.create_matrix()
        self._matrix.setNearNullSpace(rigid_body_near_nullspace(space))
        self._exact: PETSc.Mat | None = None  # allocated at the first blended tangent
        self._projected: PETSc.Mat | None = None
        if blend_after is not None and (int(blend_after) != blend_after or blend_after < 0):
            raise ValueError(f"blend_after must be an integer >= 0 or None, got {blend_after!r}")
        self.blend_after = None if blend_after is None else int(blend_after)
        self._cell_size = mean_cell_size(space.mesh)
        self._stiffness: tuple[float, int] | None = None  # typical |K_ii|, free dofs
        self._state = _SolveState()

        self.snes = PETSc.SNES().create(problem.comm)
        self.snes.setOptionsPrefix(options_prefix)
        self.snes.setFunction(problem.F, self._residual)
        self.snes.setJacobian(self._jacobian, self._matrix, self._matrix)
        self.snes.setLineSearchPreCheck(self._precheck)
        self.snes.setConvergenceTest(self._converged)
        self.snes.setConvergenceHistory(reset=True)
        with self._options_in_effect():
            self.snes.setFromOptions()
            # petsc4py 3.18 has no getter for the line search, so read what setFromOptions read.
            chosen = PETSc.Options(options_prefix).getString("snes_linesearch_type")
        self.line_search = "energy" if chosen == "basic" and problem.has_energy else chosen

    def _options_in_effect(self) -> contextlib.AbstractContextManager[None]:
        return options_in_database(self.options_prefix, self._options)

    # -- tolerances ---------------------------------------------------------------------------
    def _jacobian(self, snes, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat) -> None:
        projected = self.tangent_switch is not None and not self._state.exact_next
        self._state.projected_now = projected
        if projected:
            self.tangent_switch(True)
        try:
            self.problem.J(snes, x, A, P)
        finally:
            if projected:
                self.tangent_switch(False)
        self._record_stiffness(A)

    def _record_stiffness(self, matrix: PETSc.Mat) -> None:
        # The typical magnitude of a free diagonal entry: a median, because the exact tangent
        # can carry a few huge entries (near the kink σᵢ + σⱼ = 0 of an inverted element) that
        # say nothing about the stiffness of the body.
        matrix.getDiagonal(self._diagonal)
        local = np.abs(self._diagonal.getArray(readonly=True)[self.problem.free_owned])
        median = float(np.median(local)) if len(local) else 0.0
        comm = self.problem.comm
        count = comm.allreduce(len(local))
        typical = comm.allreduce(median * len(local)) / max(count, 1)
        self._stiffness = (typical, count)

    def _stiffness_scale(self, x: PETSc.Vec) -> tuple[float, int]:
        """Return the typical free diagonal entry of the tangent and the number of free dofs."""
        if self._stiffness is None:
            # First solve: no tangent assembled yet, so assemble the one SNES is about to.
            self._jacobian(None, x, self._matrix, self._matrix)
        return self._stiffness

    def absolute_tolerance(self) -> float:
        """Return the absolute residual tolerance in effect (see the class description)."""
        if self._user_atol is not None:
            return float(self._user_atol)
        typical, count = self._stiffness_scale(self._x)
        return self.displacement_tolerance * self._cell_size * typical * math.sqrt(count)

    def _energy_rounding(self, terms: np.ndarray) -> float:
        """Return an estimate of the rounding error of Π.

        ε times the terms' magnitudes and the energy scale of a one-cell-size deformation,
        h² · (typical diagonal entry) · (free dofs), which bounds the cancellation inside the
        energy density even where Π itself is near zero (a body at rest).
        """
        typical, count = self._stiffness_scale(self._x)
        scale = float(np.sum(np.abs(terms))) + self._cell_size**2 * typical * count
        return _ROUNDING * scale

    # -- SNES callbacks -----------------------------------------------------------------------
    def _converged(self, snes, iteration: int, norms) -> int:
        state = self._state
        fnorm = float(norms[2])
        if state.failure is not None:
            return state.failure[0]
        if state.converged_detail is not None:
            return _REASONS.CONVERGED_SNORM_RELATIVE
        if not math.isfinite(fnorm):
            state.failure = (_REASONS.DIVERGED_FNORM_NAN, "NaN", "the residual is not finite")
            return _REASONS.DIVERGED_FNORM_NAN
        if iteration == 0:
            state.initial_norm = fnorm
            state.tolerance = self.absolute_tolerance()
        elif state.watchdog is None:  # tentative steps keep the tangent they started with
            state.exact_next = state.full_step
        rtol, _, _, max_it = snes.getTolerances()
        small = fnorm <= state.tolerance or (iteration > 0 and fnorm <= rtol * state.initial_norm)
        if small and state.watchdog is not None and not self._watch_paid_off(snes.getSolution()):
            state.watchdog.remaining = 0  # a stationary point above the origin: go back
            small = False
        if small:
            if fnorm <= state.tolerance:
                return _REASONS.CONVERGED_FNORM_ABS
            return _REASONS.CONVERGED_FNORM_RELATIVE
        if iteration >= max_it:
            state.failure = (
                _REASONS.DIVERGED_MAX_IT,
                "iteration cap",
                f"residual {fnorm:.3e} above the tolerance {state.tolerance:.3e} after "
                f"{max_it} iterations",
            )
            return _REASONS.DIVERGED_MAX_IT
        return _REASONS.ITERATING

    def _fail(self, y: PETSc.Vec, reason: int, stage: str, detail: str) -> None:
        self._state.failure = (reason, stage, detail)
        y.set(0.0)  # SNES then stays at x, and the convergence test reports the failure

    @staticmethod
    def _has_inertia(ksp: PETSc.KSP) -> bool:
        pc = ksp.getPC()
        return pc.getType() == PETSc.PC.Type.CHOLESKY and pc.getFactorSolverType() == "mumps"

    def _indefinite(self, ksp: PETSc.KSP) -> bool:
        """Whether the factorised tangent has negative pivots (MUMPS LDLᵀ reports its inertia).

        A descent direction of an indefinite tangent can still lead far away; where the
        projected tangent is at hand, it is the better direction then. The preconditioner in
        effect decides, not our defaults: ``petsc_options`` or the command line may replace the
        factorisation by a Krylov solver, whose PC has no factor to ask.
        """
        if not self._has_inertia(ksp):
            return False
        negative, _, _ = ksp.getPC().getFactorMatrix().getInertia()
        return negative > 0

    def _direction_ok(self, ksp: PETSc.KSP, y: PETSc.Vec, check_inertia: bool) -> tuple[bool, str]:
        reason = ksp.getConvergedReason()
        if reason < 0:
            return False, f"the linear solve failed ({ksp_reason_name(reason)})"
        if not self.problem.has_energy:
            return True, ""
        if check_inertia and self._indefinite(ksp):
            return False, "the exact tangent is indefinite"
        slope = self._residual.dot(y)
        if not (math.isfinite(slope) and slope > 0.0):
            return False, "the Newton direction is not a descent direction"
        return True, ""

    def _precheck(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        # SNES moves to x − λ·y after this: λ = 1 with our line search, PETSc's choice for l2.
        ksp = self.snes.getKSP()
        state = self._state
        exact = self.tangent_switch is not None and not state.projected_now
        ok, why = self._direction_ok(ksp, y, check_inertia=exact)
        if state.projected_now:
            state.projected_iterations += 1
        if state.watchdog is not None and self._watched_step(x, y, ok):
            return
        if not ok and not state.projected_now and self.tangent_switch is not None:
            self._projected_direction(x, y, ksp)
            ok, why = self._direction_ok(ksp, y, check_inertia=False)
        if not ok:
            stage = "linear solve" if ksp.getConvergedReason() < 0 else "line search"
            reason = (
                _REASONS.DIVERGED_LINEAR_SOLVE
                if stage == "linear solve"
                else _REASONS.DIVERGED_LINE_SEARCH
            )
            self._fail(y, reason, stage, why)
            return
        largest = self._largest_step(y)
        if largest < 1.0:
            y.scale(largest)
        state.full_step = largest == 1.0
        if self.problem.has_energy:
            state.full_step = self._backtrack(x, y) and state.full_step

    def _largest_step(self, y: PETSc.Vec) -> float:
        largest = 1.0
        for limit in self.step_limits:
            largest = min(largest, limit.largest_step(y, sign=-1.0))
        return largest

    def _projected_direction(self, x: PETSc.Vec, y: PETSc.Vec, ksp: PETSc.KSP) -> None:
        # Keep the exact tangent the SNES just factorised: where the factorisation reports its
        # inertia, a blend of the two tangents may be positive definite and much closer to it.
        blend = (
            self.blend_after is not None
            and self._state.projected_iterations >= self.blend_after
            and self._has_inertia(ksp)
        )
        if blend:
            self._exact = self._matrix.copy(self._exact, structure=_SAME_PATTERN)
        self.tangent_switch(True)
        try:
            self._jacobian(None, x, self._matrix, self._matrix)
        finally:
            self.tangent_switch(False)
        self._state.projected_iterations += 1
        self._state.projected_now = True
        if blend and self._blended_direction(y, ksp):
            return
        with self._options_in_effect():
            ksp.setOperators(self._matrix, self._matrix)
            ksp.solve(self._residual, y)

    def _blended_direction(self, y: PETSc.Vec, ksp: PETSc.KSP) -> bool:
        """Solve with K₊ + w (K − K₊) for the largest weight w of a ladder that is definite.

        K − K₊ is what the projection removed: the negative curvature of the cells, which the
        mass (or the rest of the body) can outweigh. The projected tangent keeps none of it, so
        where the exact tangent is only slightly indefinite, Newton on K₊ converges linearly,
        at a rate set by the discarded curvature; the blend keeps as much of it as leaves the
        assembled matrix positive definite (the factorisation's inertia decides), so Newton's
        model stays close to the exact one. The weights of :data:`_BLEND_WEIGHTS` are tried from
        one rung above the last accepted one downwards; if none is definite, the plain projected
        tangent is used (returns ``False``).
        """
        state = self._state
        projected = self._matrix
        self._exact.axpy(-1.0, projected, structure=_SAME_PATTERN)  # K − K₊
        self._projected = projected.copy(self._projected, structure=_SAME_PATTERN)
        for rung in range(max(state.blend_rung - 1, 0), len(_BLEND_WEIGHTS)):
            self._projected.copy(self._matrix, structure=_SAME_PATTERN)
            self._matrix.axpy(_BLEND_WEIGHTS[rung], self._exact, structure=_SAME_PATTERN)
            with self._options_in_effect():
                ksp.setOperators(self._matrix, self._matrix)
                ksp.solve(self._residual, y)
            if ksp.getConvergedReason() > 0 and not self._indefinite(ksp):
                state.blend_rung = rung
                state.blended_iterations += 1
                return True
        state.blend_rung = len(_BLEND_WEIGHTS)
        self._projected.copy(self._matrix, structure=_SAME_PATTERN)
        return False

    def _energy_at(self, vector: PETSc.Vec) -> tuple[float, np.ndarray]:
        # The line search ends on the point it accepted, and SNES steps there: the next
        # iteration starts from the energy evaluated last (within a solve, Π depends on u only).
        state = self._state
        if state.last_energy is not None and vector.equal(self._energy_point):
            return state.last_energy
        self.problem.update_solution(vector)
        terms = self.problem.energy_terms()
        total = float(np.sum(terms))
        state.last_energy = (total if math.isfinite(total) else math.inf), terms
        vector.copy(self._energy_point)
        return state.last_energy

    def _backtrack(self, x: PETSc.Vec, y: PETSc.Vec) -> bool:
        """Shorten ``y`` until the energy test passes; return whether the full step did."""
        state = self._state
        start, terms = self._energy_at(x)
        watch = self.watchdog_steps > 0 and not state.watchdog_spent and state.full_step
        step = self._search(
            x, y, start, terms, self._residual.dot(y), self._residual.norm(), watch=watch
        )
        if step is None:
            self._search_failed(y, self._residual.dot(y), terms)
            return False
        return step == 1.0

    def _search(
        self,
        x: PETSc.Vec,
        y: PETSc.Vec,
        start: float,
        terms: np.ndarray,
        slope: float,
        residual_norm: float,
        *,
        watch: bool = False,
    ) -> float | None:
        """Halve the step ``x → x − y`` until it passes the energy test.

        ``slope`` is −(directional derivative) of Π at ``x`` along −``y``; ``residual_norm``
        that of the residual at ``x``. Returns the accepted fraction of ``y`` (``y`` scaled to
        it), or ``None`` with ``y`` as given. With ``watch``, a full step that fails the test
        but has finite energy starts a watch (step 5 of the class description) and is taken.
        """
        rounding = self._energy_rounding(terms)
        fraction = 1.0
        for _ in range(self.max_backtracks + 1):
            decrease = fraction * slope
            self._trial.waxpy(-1.0, y, x)
            energy, _ = self._energy_at(self._trial)
            if energy <= start - self.sufficient_decrease * decrease:
                return fraction
            if abs(energy - start) <= rounding:
                self.problem.F(None, self._trial, self._work)
                if self._work.norm() < residual_norm:
                    return fraction
            if watch and fraction == 1.0 and math.isfinite(energy):
                x.copy(self._watch_origin)
                y.copy(self._watch_direction)
                self._state.watchdog = _Watchdog(start, slope, residual_norm, self.watchdog_steps)
                return fraction
            y.scale(0.5)
            fraction *= 0.5
        y.scale(1.0 / fraction)
        return None

    def _search_failed(self, y: PETSc.Vec, slope: float, terms: np.ndarray) -> None:
        """No step passed: converged at round-off if even the predicted decrease is below it."""
        if 0.5 * slope <= self._energy_rounding(terms):
            self._state.converged_detail = (
                "the predicted energy decrease is below the energy's rounding error and no step "
                "reduces the residual: converged as far as floating point resolves"
            )
            y.set(0.0)
            return
        self._fail(
            y,
            _REASONS.DIVERGED_LINE_SEARCH,
            "line search",
            f"no step down to {0.5**self.max_backtracks:.1e} of the Newton step decreases the "
            "energy",
        )

    # -- the watchdog ---------------------------------------------------------------------------
    def _watch_paid_off(self, x: PETSc.Vec) -> bool:
        watch = self._state.watchdog
        energy, _ = self._energy_at(x)
        return energy <= watch.energy - self.sufficient_decrease * watch.slope

    def _watched_step(self, x: PETSc.Vec, y: PETSc.Vec, ok: bool) -> bool:
        """At a tentative iterate: end the watch, take another full step or go back.

        Returns whether the step ``y`` is decided (otherwise the iteration goes on as usual).
        """
        state = self._state
        watch = state.watchdog
        paid_off = self._watch_paid_off(x)
        # Where the exact tangent gives no descent and nothing can replace it, the watch led
        # somewhere the monotone search would not have gone: go back.
        if paid_off and (ok or self.tangent_switch is not None):
            state.watchdog = None
            return False
        if not paid_off and ok and watch.remaining > 0 and self._largest_step(y) == 1.0:
            self._trial.waxpy(-1.0, y, x)
            energy, _ = self._energy_at(self._trial)
            if math.isfinite(energy):
                watch.remaining -= 1
                state.full_step = True
                return True
        # Back to the origin, and backtrack from there along its direction (the full step
        # having failed, from half of it).
        state.watchdog = None
        state.watchdog_spent = True
        state.full_step = False
        origin, direction = self._watch_origin, self._watch_direction
        start, terms = self._energy_at(origin)
        direction.scale(0.5)
        fraction = self._search(
            origin, direction, start, terms, 0.5 * watch.slope, watch.residual_norm
        )
        if fraction is None:
            self._search_failed(direction, 0.5 * watch.slope, terms)
            if state.failure is None and state.converged_detail is not None:
                direction.set(0.0)  # converged at the origin: step there
            elif state.failure is not None:
                y.set(0.0)
                return True
        # SNES steps to x − y: make that the accepted point origin − direction.
        y.waxpy(-1.0, origin, x)
        y.axpy(1.0, direction)
        return True

    def escalate(self) -> bool:
        """Blend the tangents from the first projected iteration on (step 2), for good.

        The steppers call it when a step has failed at every cut. Returns ``False`` when there
        is nothing to escalate to: no tangent switch, no inertia from the linear solver (an
        iterative one), or blending from the first iteration already.
        """
        if self.tangent_switch is None or self.blend_after == 0:
            return False
        if not self._has_inertia(self.snes.getKSP()):
            return False
        self.blend_after = 0
        return True

    # -- solving ------------------------------------------------------------------------------
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
            self._jacobian(self.snes, self._x, self._matrix, self._matrix)
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
        them. Newton iterates on a separate vector; ``u`` receives the solution only if the solve
        converged and is otherwise left at its value before the call. Divergence is reported in
        the result (with the stage that failed), not raised.

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
        self._state = state = _SolveState()
        try:
            with self._options_in_effect():
                _compat.snes_solve(self.snes, self._x)
        except BaseException:
            self._restore(u_vector)
            raise

        reason = int(self.snes.getConvergedReason())
        converged = reason > 0
        energy = None
        if converged:
            problem.update_solution(self._x)
            energy = problem.total_energy()
        else:
            self._restore(u_vector)
        history, _ = self.snes.getConvergenceHistory()
        stage, detail = None, ""
        if state.failure is not None:
            _, stage, detail = state.failure
        elif not converged:
            stage, detail = "line search", f"SNES stopped with {snes_reason_name(reason)}"
        elif state.converged_detail is not None:
            detail = state.converged_detail
        else:
            detail = (
                f"residual {float(self.snes.getFunctionNorm()):.3e} within the tolerance "
                f"{max(state.tolerance, 0.0):.3e}"
            )
        ksp_reason = self.snes.getKSP().getConvergedReason()
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
            stage=stage,
            detail=detail,
            linear_reason_name=ksp_reason_name(ksp_reason) if ksp_reason != 0 else None,
            projected_iterations=state.projected_iterations,
            blended_iterations=state.blended_iterations,
            tolerance=state.tolerance,
        )

    def _restore(self, u_vector: PETSc.Vec) -> None:
        self._backup.copy(u_vector)
        self.problem.u.x.scatter_forward()
