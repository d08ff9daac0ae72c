"""Newton's method on an energy: PETSc SNES wired to our directions, line search and test.

:class:`EnergyMinimizer` minimises the total potential of an
:class:`~dolfinx_invertible.solvers.problem.EnergyProblem`. The pieces it wires together each
live in a module of their own: :mod:`.directions` (which tangent, and what replaces a failed
direction), :mod:`.line_search` (energy backtracking and the watchdog), :mod:`.convergence`
(tolerances scaled to the problem) and :mod:`.monitors` (what observers are told).
"""

from __future__ import annotations

import contextlib
import math
import time
import weakref
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from petsc4py import PETSc

from dolfinx_invertible import _compat
from dolfinx_invertible.choices import GLOBALIZATIONS
from dolfinx_invertible.solvers.convergence import ConvergenceTest, ScaledTolerances
from dolfinx_invertible.solvers.directions import NewtonDirections
from dolfinx_invertible.solvers.line_search import EnergyLineSearch, SearchStop
from dolfinx_invertible.solvers.monitors import IterationMonitors, NewtonIteration, StepCap
from dolfinx_invertible.solvers.options import DEFAULT_OPTIONS_PREFIX, MinimizerOptions
from dolfinx_invertible.solvers.problem import EnergyProblem
from dolfinx_invertible.solvers.results import SolveResult
from dolfinx_invertible.solvers.step_limit import StepLimit
from dolfinx_invertible.solvers.trust_region import TrustRegion, agreement

__all__ = ["EnergyMinimizer"]

_REASONS = PETSc.SNES.ConvergedReason


def _weakly(method: Callable[..., Any]) -> Callable[..., Any]:
    """Wrap ``method`` as a SNES callback that does not keep its object alive.

    The SNES belongs to the minimizer; a callback bound to the minimizer (or to what it owns)
    closes a cycle through the SNES, and petsc4py objects are opaque to Python's cycle
    collector in some releases (3.24): the minimizer, its mesh and their MPI communicators would
    then live until exit, and MPICH aborts after 2 048 communicators.
    """
    reference = weakref.WeakMethod(method)

    def call(*arguments: Any) -> Any:
        bound = reference()
        if bound is None:
            raise RuntimeError("the SNES outlived the EnergyMinimizer that configured it")
        return bound(*arguments)

    return call


class EnergyMinimizer:
    """Newton's method (PETSc SNES ``newtonls``) minimising an :class:`EnergyProblem`.

    Not to be confused with ``dolfinx.nls.petsc.NewtonSolver``: this one drives PETSc SNES and
    minimises an energy. Every Newton iteration:

    1. SNES assembles the tangent and solves for the Newton direction (``linear_solver``).
    2. If that linear solve failed or its direction is not a descent direction (the exact
       tangent is indefinite there) and ``tangent_switch`` is given, the direction is computed
       again from the projected tangent at the same iterate, or, after ``blend_after`` such
       iterations of a solve and where the factorisation reports its inertia, from a positive
       definite blend of the two tangents (:mod:`.directions`). A failure that remains ends
       the solve at the stage "linear solve" or "line search".
    3. ``step_limits`` cap the step (e.g. the inversion-free cap).
    4. The energy line search with a watchdog (:mod:`.line_search`) shortens the step. A solve
       does not end at a tentative iterate whose energy is above its origin's.

    A problem without energy forms (a stress-only material such as IFE) has nothing to
    backtrack on; its line search is PETSc's ``l2``, which minimises the residual norm along the
    direction (steps 2 and 3 still apply). The solve is converged when the residual norm is at
    most ``max(atol, rtol · ‖r₀‖)`` with ``atol`` scaled to the problem (:mod:`.convergence`),
    so that scaling the stiffness, the density and the loads by one factor leaves the
    iterations unchanged.

    Options: our defaults, then ``petsc_options``, then those in PETSc's database under
    ``options_prefix`` (the command line), later ones winning (:mod:`.options`).

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
    tangent
        What the problem's own tangent is (``"exact"`` or ``"projected"``), as monitors name it.
    displacement_tolerance
        η of the default absolute tolerance, relative to the mean cell size.
    sufficient_decrease
        Armijo constant of the energy line search.
    max_backtracks
        Halvings of the step before the line search gives up.
    watchdog_steps
        Tentative full steps after the first before the energy must have decreased; 0 turns
        the watchdog off.
    blend_after
        Projected iterations of a solve after which the exact and the projected tangent are
        blended where the exact one is indefinite; ``None`` (default) never blends until
        :meth:`escalate` is called.
    globalization
        ``"line-search"``: steps 2–4 above. ``"trust-region"``: every direction is conjugate
        gradients on the exact tangent bounded by a trust region, following negative curvature
        to its boundary (:mod:`.trust_region`); the energy line search guards each step,
        without the watchdog. Needs the iterative path (conjugate gradients), an energy and a
        ``tangent_switch``. ``"auto"`` (default): the trust region where it applies, else the
        line search.
    indefinite_newton
        In Newton's local phase on the iterative path (the last step full and its energy
        decrease at least 3/4 of its quadratic model's), keep the exact tangent's direction
        past negative curvature where it is one of descent, solved by MINRES
        (:mod:`.directions`): the iterates then converge quadratically to the stationary point
        they approach, a saddle of the step's energy included. ``False`` takes the projected
        tangent (line search) or the trust region's boundary there. The direct path keeps its
        inertia test either way.

    Attributes
    ----------
    problem
        The :class:`EnergyProblem`.
    line_search
        ``"energy"`` (ours) or ``"l2"`` (PETSc's, without energy), unless the options override.
    linear_solver
        ``"direct"`` or ``"iterative"``: what ``"auto"`` chose.
    directions
        The direction policy (:class:`~dolfinx_invertible.solvers.directions.NewtonDirections`).
    tolerances
        The scaled tolerances
        (:class:`~dolfinx_invertible.solvers.convergence.ScaledTolerances`).
    globalization
        ``"line-search"`` or ``"trust-region"``: what ``globalization`` chose.
    trust_region
        The :class:`~dolfinx_invertible.solvers.trust_region.TrustRegion` of a trust-region
        solver (its radius), else ``None``.
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
        tangent: str = "exact",
        displacement_tolerance: float = 1.0e-10,
        sufficient_decrease: float = 1.0e-4,
        max_backtracks: int = 30,
        watchdog_steps: int = 2,
        blend_after: int | None = None,
        globalization: str = "auto",
        indefinite_newton: bool = True,
    ) -> None:
        GLOBALIZATIONS.check(globalization)
        self.problem = problem
        self.u = problem.u
        self.step_limits = tuple(step_limits)
        self._capped_by: str | None = None  # the step limit that capped the last step
        # Per Newton iteration of the current solve, the smallest cap below 1 and its limit,
        # and the directions the solve computed.
        self._caps: dict[int, tuple[float, str]] = {}
        self._direction_count = 0
        self.options_prefix = options_prefix

        self.options = MinimizerOptions(problem, petsc_options, options_prefix, linear_solver, pc)
        self.linear_solver = self.options.linear_solver
        self._x = problem.create_vector()
        self._residual = problem.create_vector()
        self._backup = problem.create_vector()
        self.tolerances = ScaledTolerances(
            problem,
            displacement_tolerance=displacement_tolerance,
            absolute_tolerance=self.options.absolute_tolerance,
            assemble_tangent=lambda: self.directions.assemble(
                None, self._x, self.directions.matrix, self.directions.matrix
            ),
        )
        self.directions = directions = NewtonDirections(
            problem,
            self._residual,
            self.options,
            tangent_switch=tangent_switch,
            blend_after=blend_after,
            assembled=self.tolerances.record_stiffness,
            tangent=tangent,
            indefinite_newton=indefinite_newton,
        )
        self._search = EnergyLineSearch(
            problem,
            rounding=self.tolerances.energy_rounding,
            sufficient_decrease=sufficient_decrease,
            max_backtracks=max_backtracks,
            watchdog_steps=watchdog_steps,
        )
        self._test = ConvergenceTest(self.tolerances)
        self._monitors = IterationMonitors()

        self.snes = PETSc.SNES().create(problem.comm)
        self.snes.setOptionsPrefix(options_prefix)
        self.snes.setFunction(_weakly(problem.F), self._residual)
        self.snes.setJacobian(_weakly(directions.assemble), *directions.snes_matrices)
        self.snes.setLineSearchPreCheck(_weakly(self._precheck))
        self.snes.setConvergenceTest(_weakly(self._converged))
        self.snes.setConvergenceHistory(reset=True)
        self.snes.setMonitor(_weakly(self._monitor))
        chosen = self.options.configure(self.snes)
        directions.choose_krylov_method(self.snes.getKSP())
        self.line_search = "energy" if chosen == "basic" and problem.has_energy else chosen
        applies = directions.truncated is not None and self.line_search == "energy"
        if globalization == "trust-region" and not applies:
            raise ValueError(
                "globalization='trust-region' needs the iterative path (conjugate gradients: "
                f"linear_solver='iterative'; here {self.linear_solver!r} with ksp_type "
                f"{self.snes.getKSP().getType()!r}), a tangent switch (project='auto') and an "
                "energy (not a stress-only material such as IFE)"
            )
        self.globalization = "line-search"
        self.trust_region: TrustRegion | None = None
        if globalization != "line-search" and applies:
            self.globalization = "trust-region"
            self.trust_region = directions.trust_region = TrustRegion()
            # A trust region takes no step its model has not vouched for.
            self._search.watchdog_steps = 0
        self._work = problem.create_vector()

    # -- public properties and observation ------------------------------------------------
    @property
    def krylov_solver(self) -> PETSc.KSP:
        """The PETSc KSP that solves for the Newton directions."""
        return self.snes.getKSP()

    @property
    def max_iterations(self) -> int:
        """The Newton iteration cap of a solve (``snes_max_it``); settable."""
        return int(self.snes.getTolerances()[3])

    @max_iterations.setter
    def max_iterations(self, value: int) -> None:
        self.snes.setTolerances(max_it=int(value))

    @property
    def stall_window(self) -> int | None:
        """Iterations without progress that end a solve as stalled (``None``: never); settable.

        Defaults to :data:`~dolfinx_invertible.solvers.convergence.STALL_WINDOW`.
        """
        return self._test.window

    @stall_window.setter
    def stall_window(self, value: int | None) -> None:
        self._test.window = None if value is None else int(value)

    @property
    def blend_after(self) -> int | None:
        """Projected iterations after which tangents blend (``None``: after :meth:`escalate`)."""
        return self.directions.blend_after

    def add_monitor(
        self,
        *,
        on_iteration: Callable[[NewtonIteration], None] | None = None,
        on_step_cap: Callable[[StepCap], None] | None = None,
    ) -> Callable[[], None]:
        """Call ``on_iteration`` after every Newton iteration and ``on_step_cap`` for every cap.

        Both are called on every rank (collective work inside them is allowed). Returns a
        function that removes them again.
        """
        return self._monitors.add(on_iteration, on_step_cap)

    @contextlib.contextmanager
    def options_override(self, options: dict[str, Any]) -> Iterator[None]:
        """Use further PETSc ``options`` (without prefix) for the duration, e.g. a longer cap."""
        try:
            with self.options.override(self.snes, options):
                self.directions.choose_krylov_method(self.snes.getKSP())
                yield
        finally:
            self.directions.choose_krylov_method(self.snes.getKSP())

    def escalate(self) -> bool:
        """Blend the tangents from the first projected iteration on, for good.

        The steppers call it when a step has failed at every cut. Returns ``False`` when there
        is nothing to escalate to: no tangent switch, no definiteness test (the inertia of a
        factorisation, or the truncated CG's curvature), a trust region (whose steps use the
        negative curvature already), or blending from the first iteration already.
        """
        return self.directions.escalate(self.snes.getKSP())

    def absolute_tolerance(self) -> float:
        """Return the absolute residual tolerance in effect (see :mod:`.convergence`)."""
        return self.tolerances.absolute_tolerance()

    # -- SNES callbacks -------------------------------------------------------------------
    def _stop(self, stop: SearchStop | None) -> None:
        if stop is not None and stop.converged:
            self._test.converge(stop.detail)
        elif stop is not None:
            self._test.fail(_REASONS.DIVERGED_LINE_SEARCH, "line search", stop.detail)

    def _largest_step(self, y: PETSc.Vec) -> float:
        largest = 1.0
        iteration = int(self.snes.getIterationNumber())
        self._capped_by = None
        for limit in self.step_limits:
            cap = limit.largest_step(y, sign=-1.0)
            self._monitors.capped(limit, cap, iteration)
            if cap < largest:
                largest, self._capped_by = cap, type(limit).__name__
        if self._capped_by is not None:
            earlier = self._caps.get(iteration, (1.0, ""))
            self._caps[iteration] = min(earlier, (largest, self._capped_by))
        return largest

    def _where(self) -> str:
        """Where the failed solve's last iterate is worst, and how the step limits acted."""
        parts = [self.problem.locate(self._x)]
        if self._caps:
            smallest, limit = min(self._caps.values())
            parts.append(
                f"step limits capped {len(self._caps)} of {self._direction_count} "
                f"Newton steps (the smallest cap {smallest:.2g} of the step, by {limit})"
            )
        return "; ".join(part for part in parts if part)

    def _precheck(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        # SNES moves to x − λ·y after this: λ = 1 with our line search, PETSc's choice for l2.
        ksp = self.snes.getKSP()
        directions, search = self.directions, self._search
        has_energy = self.problem.has_energy
        monitors = self._monitors
        monitors.start_direction()
        self._direction_count += 1
        directions.model_ratio = math.nan  # until a step is taken and measured
        directions.settle(x, y, ksp)
        ok, why = directions.judge(ksp, y, has_energy=has_energy)
        directions.count_iteration()
        if search.watching:
            decided, stop = search.watched_step(
                x, y, ok, directions.replaceable, self._largest_step
            )
            if decided:
                self._stop(stop)
                monitors.step_length = search.fraction
                return
        if not ok and not directions.projected_now and directions.replaceable:
            directions.replace(x, y, ksp)
            ok, why = directions.judge(ksp, y, has_energy=has_energy)
        if not ok:
            # SNES then stays at x, and the convergence test reports the failure.
            y.set(0.0)
            monitors.step_length = 0.0
            if ksp.getConvergedReason() < 0:
                self._test.fail(_REASONS.DIVERGED_LINEAR_SOLVE, "linear solve", why)
            else:
                self._test.fail(_REASONS.DIVERGED_LINE_SEARCH, "line search", why)
            return
        largest = self._largest_step(y)
        floor = 0.5**search.max_backtracks
        if largest < floor:
            # No step the line search could take: a cap, not a stall (the step is cut).
            y.set(0.0)
            monitors.step_length = 0.0
            self._test.fail(
                _REASONS.DIVERGED_LINE_SEARCH,
                "line search",
                f"{self._capped_by} allows {largest:.1e} of the Newton step, below the line "
                f"search's floor of {floor:.1e}",
            )
            return
        # Options may have replaced the truncated CG for a while (options_override). Only the
        # truncated CG reads ρ (its local phase, its trust region): the direct path skips it.
        measured = has_energy and directions.truncated is not None
        bounded = measured and self.trust_region is not None
        slope, curvature = self._model_terms(y) if measured else (math.nan, math.nan)
        if largest < 1.0:
            y.scale(largest)
        search.full_step = largest == 1.0
        monitors.step_length = largest
        if not has_energy:
            return
        self._stop(search.backtrack(x, y, self._residual))
        fraction = monitors.step_length = largest * search.fraction
        if not measured:
            return
        predicted = fraction * slope - 0.5 * fraction**2 * curvature
        directions.model_ratio = agreement(search.decrease, predicted, search.rounding_error)
        if bounded:
            truncated = directions.truncated
            self.trust_region.update(
                fraction=fraction,
                cap=largest,
                step_norm=truncated.step_norm if math.isfinite(slope) else math.nan,
                boundary=truncated.boundary,
                actual=search.decrease,
                predicted=predicted,
                rounding=search.rounding_error,
            )

    def _model_terms(self, y: PETSc.Vec) -> tuple[float, float]:
        """Return the slope rᵀy and the curvature yᵀKy of the tangent ``y`` came from.

        That is the exact tangent but for a solve's first direction, before the trust region
        has a radius, where the truncated CG may have fallen back to the projected one.
        """
        matrix = self.directions.direction_tangent
        if matrix is None:
            return math.nan, math.nan
        matrix.mult(y, self._work)
        return self._residual.dot(y), y.dot(self._work)

    def _converged(self, snes, iteration: int, norms) -> int:
        if iteration > 0 and not self._search.watching:
            # Tentative steps keep the tangent they started with.
            self.directions.after_step(self._search.full_step)
        search = self._search
        # A tentative iterate of the watchdog may lie above its origin: not a measure of progress.
        energy = None if search.watching else search.known_energy(snes.getSolution())
        return self._test.check(
            iteration,
            float(norms[2]),
            snes,
            self._watch_unpaid,
            energy=energy,
            rounding=search.rounding_error,
        )

    def _watch_unpaid(self) -> bool:
        """Veto convergence at a tentative iterate above the origin's energy (then go back)."""
        search = self._search
        if search.watching and not search.watch_paid_off(self.snes.getSolution()):
            search.end_watch_at_stationary_point()
            return True
        return False

    def _monitor(self, snes, iteration: int, norm: float) -> None:
        self._monitors.iteration_done(
            snes,
            iteration,
            norm,
            problem=self.problem,
            energy=self._search.known_energy,
            direction=self.directions.kind,
            replacement_linear_iterations=self.directions.replacement_linear_iterations,
        )

    # -- solving --------------------------------------------------------------------------
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
            Krylov iterations; :attr:`krylov_solver` tells whether it converged.
        """
        u_vector = _compat.petsc_vector(self.problem.u)
        u_vector.copy(self._backup)
        u_vector.copy(self._x)
        _compat.set_dirichlet_values(self._x, self.problem.bcs)
        ksp = self.snes.getKSP()
        try:
            self.problem.F(self.snes, self._x, self._residual)
            directions = self.directions
            directions.assemble(self.snes, self._x, *directions.snes_matrices)
            directions.solve(ksp, direction, replacement=False)
            directions.settle(self._x, direction, ksp)
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
        self._monitors.start_solve()
        self._caps = {}
        self._direction_count = 0
        self._test.start_solve()
        self.directions.start_solve()
        self._search.start_solve()
        if self.trust_region is not None:
            self.trust_region.start_solve()
        try:
            with self.options.in_effect():
                _compat.snes_solve(self.snes, self._x)
        except BaseException:
            self._restore(u_vector)
            raise

        converged = self.snes.getConvergedReason() > 0
        energy = None
        where = ""
        if converged:
            problem.update_solution(self._x)
            energy = problem.total_energy()
        else:
            where = self._where()
            self._restore(u_vector)
        return SolveResult.from_snes(
            self.snes,
            energy=energy,
            wall_time=time.perf_counter() - start,
            failure=self._test.failure,
            converged_detail=self._test.converged_detail,
            tolerance=self._test.tolerance,
            projected_iterations=self.directions.projected_iterations,
            blended_iterations=self.directions.blended_iterations,
            where=where,
        )

    def _restore(self, u_vector: PETSc.Vec) -> None:
        self._backup.copy(u_vector)
        self.problem.u.x.scatter_forward()
