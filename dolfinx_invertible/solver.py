"""Newton solver and quasi-static load stepping for (invertible) hyperelasticity in DOLFINx.

The solver works on compiled DOLFINx forms of any origin: UFL forms compiled by
``dolfinx.fem.form`` or forms built around custom cell kernels. A problem is given as lists of
forms that are summed: the total potential Π(u), its gradient dΠ/du and the tangent d²Π/du².

- :class:`EnergyProblem` assembles the sums and applies Dirichlet conditions the way DOLFINx's
  own ``NonlinearProblem`` does.
- :class:`NewtonSolver` runs PETSc SNES ``newtonls``: a backtracking line search on Π when the
  problem has an energy, conjugate gradients preconditioned by algebraic multigrid that knows the
  rigid-body modes.
- :func:`solve_load_steps` ramps the load over a pseudo-time in (0, 1] and cuts the increment
  when Newton fails.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import dolfinx.fem
import dolfinx.fem.petsc
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from dolfinx_invertible import _compat

__all__ = [
    "EnergyProblem",
    "NewtonSolver",
    "SolveResult",
    "SolverError",
    "rigid_body_near_nullspace",
    "snes_reason_name",
    "solve_load_steps",
]

DEFAULT_OPTIONS_PREFIX = "dolfinx_invertible_"

# ksp_rtol is tight because an inexact linear solve caps Newton's quadratic rate. snes_stol is 0
# because a line search that shortens the step also makes the step norm small far from a
# solution; convergence is decided on the residual alone.
_DEFAULT_PETSC_OPTIONS: dict[str, Any] = {
    "snes_type": "newtonls",
    "snes_rtol": 1.0e-9,
    "snes_atol": 1.0e-10,
    "snes_stol": 0.0,
    "snes_max_it": 50,
    "ksp_type": "cg",
    "ksp_rtol": 1.0e-10,
}


class SolverError(RuntimeError):
    """Stepping gave up: Newton failed after the largest allowed number of step cuts.

    Raised by :func:`solve_load_steps`, which fills in every attribute; other steppers may give
    only the message.

    Attributes
    ----------
    reason_name
        PETSc SNES converged reason of the last failed attempt, e.g. ``"DIVERGED_MAX_IT"``.
    step_index
        1-based index of the load step (target pseudo-time) that could not be reached.
    time_reached
        Last converged pseudo-time; the solution and the load are restored to it.
    time_tried
        Pseudo-time of the last failed attempt.
    """

    def __init__(
        self,
        message: str,
        *,
        reason_name: str | None = None,
        step_index: int | None = None,
        time_reached: float | None = None,
        time_tried: float | None = None,
    ) -> None:
        super().__init__(message)
        self.reason_name = reason_name
        self.step_index = step_index
        self.time_reached = time_reached
        self.time_tried = time_tried


def _reason_names() -> dict[int, str]:
    names: dict[int, str] = {}
    for name in sorted(vars(PETSc.SNES.ConvergedReason)):
        value = getattr(PETSc.SNES.ConvergedReason, name)
        if name.startswith("_") or not isinstance(value, int):
            continue
        # CONVERGED_ITERATING and ITERATING share 0; keep the first in sorted order.
        names.setdefault(value, name)
    return names


_REASON_NAMES = _reason_names()


def snes_reason_name(reason: int) -> str:
    """The name of a PETSc ``SNESConvergedReason``, e.g. -5 -> ``"DIVERGED_MAX_IT"``."""
    return _REASON_NAMES.get(int(reason), f"UNKNOWN_REASON_{int(reason)}")


@dataclasses.dataclass(frozen=True)
class SolveResult:
    """Outcome of one nonlinear solve.

    Attributes
    ----------
    converged
        Whether SNES reported convergence (a positive converged reason).
    reason
        PETSc ``SNESConvergedReason`` as an integer.
    reason_name
        Its name, e.g. ``"CONVERGED_FNORM_RELATIVE"`` or ``"DIVERGED_LINE_SEARCH"``.
    newton_iterations
        Newton iterations taken.
    linear_iterations
        Krylov iterations summed over all Newton iterations.
    residual_norm
        Euclidean norm of the residual at the last iterate (with Dirichlet rows).
    energy
        Total potential at the solution; ``None`` when the problem has no energy or the solve
        failed.
    wall_time
        Seconds spent in :meth:`NewtonSolver.solve` on this rank.
    residual_history
        Residual norms from the initial guess to the last iterate.
    tangent
        Which tangent produced the result, where a caller chooses: ``"exact"`` or
        ``"projected"`` (see :class:`~dolfinx_invertible.problem.HyperelasticProblem`).
    svd_share
        Where the solve ran our kernels: for each kernel ("energy", "residual", "tangent") the
        share of quadrature-point evaluations, summed over ranks and all assemblies of the
        solve, that went through the SVD path rather than the invariant fast path (``None``
        for a kernel that never ran).
    """

    converged: bool
    reason: int
    reason_name: str
    newton_iterations: int
    linear_iterations: int
    residual_norm: float
    energy: float | None
    wall_time: float
    residual_history: tuple[float, ...] = ()
    tangent: str = ""
    svd_share: dict[str, float | None] = dataclasses.field(default_factory=dict)


def _as_form_list(forms: Any, rank: int, name: str) -> list:
    if forms is None:
        forms = []
    elif not isinstance(forms, (list, tuple)):
        forms = [forms]
    forms = list(forms)
    for form in forms:
        if getattr(form, "rank", rank) != rank:
            raise ValueError(
                f"{name}: expected compiled forms of rank {rank}, got rank {form.rank}"
            )
    return forms


class EnergyProblem:
    """Assembles a potential Π(u), its gradient and its tangent from sums of compiled forms.

    The callbacks have the signatures PETSc SNES expects. Each copies the iterate into ``u``
    (owned values, then a forward ghost update) before assembling, so the forms, whose
    coefficient is ``u``, see the iterate.

    Parameters
    ----------
    u
        The unknown displacement; the forms must depend on it.
    energy
        Compiled scalar forms whose sum is Π(u). ``None`` or empty for materials that only define
        a stress; :class:`NewtonSolver` then uses a line search on the residual norm.
    residual
        Compiled linear forms whose sum is dΠ/du (or the stress residual).
    jacobian
        Compiled bilinear forms whose sum is the tangent; all on the space of ``u``. The first
        one sets the sparsity pattern (see :meth:`create_matrix`).
    bcs
        Dirichlet conditions on the space of ``u``.
    """

    def __init__(
        self,
        u: dolfinx.fem.Function,
        energy: Sequence[Any] | Any | None,
        residual: Sequence[Any] | Any,
        jacobian: Sequence[Any] | Any,
        bcs: Sequence[Any] | None = None,
    ) -> None:
        self.u = u
        self.energy_forms = _as_form_list(energy, 0, "energy")
        self.residual_forms = _as_form_list(residual, 1, "residual")
        self.jacobian_forms = _as_form_list(jacobian, 2, "jacobian")
        if not self.residual_forms:
            raise ValueError("residual: at least one compiled linear form is required")
        if not self.jacobian_forms:
            raise ValueError("jacobian: at least one compiled bilinear form is required")
        self.bcs = list(bcs or [])
        self.comm = u.function_space.mesh.comm
        self._u_vector = _compat.petsc_vector(u)
        self._pattern_checked = False

    @property
    def has_energy(self) -> bool:
        """Whether energy forms were given, i.e. whether :meth:`objective` can be evaluated."""
        return bool(self.energy_forms)

    def create_vector(self) -> PETSc.Vec:
        """A ghosted vector laid out like the dofs of ``u``."""
        return _compat.create_vector(self.residual_forms[0])

    def create_matrix(self) -> PETSc.Mat:
        """A matrix with the sparsity pattern of the first jacobian form.

        Cell and exterior-facet integrals of further forms on the same space fall inside that
        pattern, because every facet belongs to a cell. Interior-facet integrals couple the dofs
        of neighbouring cells, which a cell-only pattern lacks; PETSc is allowed to allocate such
        entries rather than fail, and :meth:`J` warns once if it had to.
        """
        matrix = _compat.create_matrix(self.jacobian_forms[0])
        if len(self.jacobian_forms) > 1:
            matrix.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        return matrix

    def update_solution(self, x: PETSc.Vec) -> None:
        """Copy the owned values of ``x`` into ``u`` and update the ghosts of ``u``."""
        if x.handle != self._u_vector.handle:
            x.copy(self._u_vector)
        self.u.x.scatter_forward()

    def energy_terms(self) -> np.ndarray:
        """The value of each energy form at the current ``u``, summed over all ranks."""
        local = np.array(
            [dolfinx.fem.assemble_scalar(form) for form in self.energy_forms], dtype=np.float64
        )
        return self.comm.allreduce(local, op=MPI.SUM)

    def total_energy(self) -> float | None:
        """Π at the current ``u``, summed over all ranks; ``None`` without energy forms.

        An undefined energy (NaN, e.g. the logarithm of a negative Jacobian determinant) is
        reported as +inf, so a line search treats the state as infinitely bad and backtracks.
        """
        if not self.has_energy:
            return None
        total = float(np.sum(self.energy_terms()))
        return total if not math.isnan(total) else math.inf

    def objective(self, snes: PETSc.SNES | None, x: PETSc.Vec) -> float:
        """SNES objective: Π at ``x``."""
        if not self.has_energy:
            raise ValueError("this problem has no energy forms, so no objective")
        self.update_solution(x)
        return self.total_energy()

    def F(self, snes: PETSc.SNES | None, x: PETSc.Vec, b: PETSc.Vec) -> None:
        """SNES residual: dΠ/du at ``x`` into ``b``, Dirichlet rows holding ``x - g``."""
        self.update_solution(x)
        with b.localForm() as b_local:
            b_local.set(0.0)
        for form in self.residual_forms:
            dolfinx.fem.petsc.assemble_vector(b, form)
        # The ghosted u rather than x: lifting reads ghost values, and x need not carry them.
        _compat.lift_residual(b, self.jacobian_forms, self.bcs, self._u_vector)

    def J(self, snes: PETSc.SNES | None, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat) -> None:
        """SNES Jacobian: the summed tangent at ``x`` into ``A`` (and ``P`` if distinct).

        Dirichlet rows and columns are zero with 1 on the diagonal, exactly once: DOLFINx inserts
        rather than adds the diagonal, so every form but the last is assembled with diagonal 0
        and the last with 1, which yields 1 whether the diagonal is inserted or added.
        """
        self.update_solution(x)
        matrices = [A] if P is None or P.handle == A.handle else [A, P]
        last = len(self.jacobian_forms) - 1
        for matrix in matrices:
            matrix.zeroEntries()
            for index, form in enumerate(self.jacobian_forms):
                diagonal = 1.0 if index == last else 0.0
                _compat.assemble_matrix_into(matrix, form, self.bcs, diagonal)
            matrix.assemble()
        if not self._pattern_checked and len(self.jacobian_forms) > 1:
            self._pattern_checked = True
            mallocs = A.getInfo()["mallocs"]
            if mallocs > 0:
                warnings.warn(
                    f"the jacobian forms needed {int(mallocs)} allocations beyond the sparsity "
                    "pattern of the first form (interior-facet integrals?); pass the form with "
                    "the widest coupling first",
                    RuntimeWarning,
                    stacklevel=2,
                )


def rigid_body_near_nullspace(space: dolfinx.fem.FunctionSpace) -> PETSc.NullSpace:
    """Orthonormal rigid-body modes of a vector space: translations and infinitesimal rotations.

    Three translations and three rotations in 3D, two and one in 2D; algebraic multigrid (GAMG)
    builds its coarse spaces from them. Values come from the dof coordinates, so any nodal
    (Lagrange) vector space works.

    Parameters
    ----------
    space
        Vector function space with one component per geometric dimension.

    Returns
    -------
    PETSc.NullSpace
        Near-nullspace for ``Mat.setNearNullSpace`` on matrices of ``space``.
    """
    dimension = space.mesh.geometry.dim
    block_size = space.dofmap.index_map_bs
    if block_size != dimension:
        raise ValueError(
            f"space: expected {dimension} components per node (a vector space), got {block_size}"
        )
    comm = space.mesh.comm
    owned = space.dofmap.index_map.size_local
    coordinates = space.tabulate_dof_coordinates()[:owned, :dimension]
    # Centring keeps rotations far from translations on meshes placed far from the origin, where
    # Gram–Schmidt would otherwise cancel most digits.
    total = comm.allreduce(owned, op=MPI.SUM)
    centre = comm.allreduce(coordinates.sum(axis=0), op=MPI.SUM) / max(total, 1)
    coordinates = coordinates - centre

    modes: list[np.ndarray] = []
    for component in range(dimension):
        mode = np.zeros((owned, dimension))
        mode[:, component] = 1.0
        modes.append(mode)
    # Rotation about axis k moves component i by -x_j and component j by +x_i.
    planes = [(0, 1)] if dimension == 2 else [(0, 1), (1, 2), (2, 0)]
    for i, j in planes:
        mode = np.zeros((owned, dimension))
        mode[:, i] = -coordinates[:, j]
        mode[:, j] = coordinates[:, i]
        modes.append(mode)

    vectors = []
    for mode in modes:
        vector = PETSc.Vec().createMPI(
            (owned * block_size, PETSc.DECIDE), bsize=block_size, comm=comm
        )
        vector.setArray(mode.reshape(-1))
        vectors.append(vector)
    # Modified Gram–Schmidt: PETSc requires an orthonormal basis.
    for index, vector in enumerate(vectors):
        for previous in vectors[:index]:
            vector.axpy(-vector.dot(previous), previous)
        vector.normalize()
    return PETSc.NullSpace().create(vectors=vectors, comm=comm)


@dataclasses.dataclass(frozen=True)
class _LineSearchStart:
    """What the line search knows at its starting point x, for :meth:`NewtonSolver._objective`."""

    handle: int  # of the PETSc vector x
    energy: float
    energy_scale: float  # sum of the absolute values of the energy forms
    slope: float  # F(x)·y for the Newton step y
    residual_norm: float


@contextlib.contextmanager
def _options_in_database(prefix: str, options: dict[str, Any]) -> Iterator[None]:
    """Put ``options`` under ``prefix`` in PETSc's global database for the duration.

    Names already present (from the command line or the caller's own ``PETSc.Options``) are left
    alone, so they take precedence. Ours are removed afterwards so they cannot leak into another
    solver that shares the prefix; they are pushed again around every solve because PETSc reads
    some options lazily, e.g. those of multigrid levels, which GAMG creates during setup.
    """
    database = PETSc.Options(prefix)
    added = []
    for name, value in options.items():
        if database.hasName(name):
            continue
        database.setValue(name, value)
        added.append(name)
    try:
        yield
    finally:
        for name in added:
            database.delValue(name)


class NewtonSolver:
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
    ``_DEFAULT_PETSC_OPTIONS``, tolerances snes_rtol 1e-9, snes_atol 1e-10, snes_max_it 50,
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
        :class:`~dolfinx_invertible.line_search.InversionFreeStep`): each Newton step is scaled
        down to it before the energy line search.

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
        petsc_options: dict[str, Any] | None = None,
        options_prefix: str = DEFAULT_OPTIONS_PREFIX,
        pc: str = "gamg",
        step_limit: Any | None = None,
    ) -> None:
        self.problem = problem
        self.step_limit = step_limit
        self.options_prefix = options_prefix
        options = dict(_DEFAULT_PETSC_OPTIONS)
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
        return _options_in_database(self.options_prefix, self._options)

    def newton_direction(self, direction: PETSc.Vec) -> int:
        """The Newton direction at the current ``u``, computed as an iteration of :meth:`solve`.

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
        """The SNES objective Π, made usable once Π stops resolving Newton's progress.

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


def _load_targets(steps: int | Sequence[float]) -> list[float]:
    if isinstance(steps, (int, np.integer)) and not isinstance(steps, bool):
        if steps < 1:
            raise ValueError(f"steps: need at least 1 load step, got {steps}")
        return [(index + 1) / int(steps) for index in range(int(steps))]
    try:
        if isinstance(steps, (bool, str, bytes)):
            raise TypeError
        targets = [float(value) for value in steps]
    except TypeError:
        raise ValueError(
            f"steps: expected an int or a sequence of pseudo-times, got {steps!r}"
        ) from None
    if not targets:
        raise ValueError("steps: the sequence of pseudo-times is empty")
    if any(not (0.0 < value <= 1.0) for value in targets):
        raise ValueError(f"steps: pseudo-times must lie in (0, 1], got {targets}")
    if any(later <= earlier for earlier, later in zip(targets, targets[1:])):
        raise ValueError(f"steps: pseudo-times must increase strictly, got {targets}")
    if targets[-1] != 1.0:
        raise ValueError(f"steps: the last pseudo-time must be 1, got {targets[-1]}")
    return targets


def solve_load_steps(
    solver: Any,
    update_load: Callable[[float], None],
    steps: int | Sequence[float],
    max_cuts: int = 6,
    on_step: Callable[[float, SolveResult], None] | None = None,
) -> list[SolveResult]:
    """Quasi-static load stepping over a pseudo-time t from 0 to 1, cutting steps on failure.

    For each pseudo-time, ``update_load(t)`` sets the loads and boundary values (e.g. Constants
    scaled by t) and the solver starts from the previous solution. When Newton fails, the last
    converged solution and load (``update_load`` of that pseudo-time, possibly 0) are restored
    and the increment is halved. After a success the increment doubles again, never past the
    next target pseudo-time, so every target in ``steps`` is hit exactly.

    Parameters
    ----------
    solver
        A :class:`NewtonSolver` or a :class:`~dolfinx_invertible.problem.HyperelasticProblem`
        (anything with ``solve()`` and ``problem.u``); ``u`` holds the state at t = 0 on entry.
    update_load
        Sets the load for a pseudo-time in [0, 1].
    steps
        Number of equal steps, or increasing target pseudo-times in (0, 1] ending with 1.
    max_cuts
        Largest number of consecutive halvings before giving up.
    on_step
        Called as ``on_step(t, result)`` after every converged (sub)step, e.g. to write output
        that survives a later failure.

    Returns
    -------
    list of SolveResult
        One per converged (sub)step, in order.

    Raises
    ------
    SolverError
        Newton still failed after ``max_cuts`` consecutive cuts. The state and load are those of
        the last converged pseudo-time.
    ValueError
        Invalid ``steps`` or ``max_cuts``.
    """
    targets = _load_targets(steps)
    if isinstance(max_cuts, bool) or not isinstance(max_cuts, (int, np.integer)) or max_cuts < 0:
        raise ValueError(f"max_cuts: expected a non-negative int, got {max_cuts!r}")

    u = solver.problem.u
    u_vector = _compat.petsc_vector(u)
    last_converged = u_vector.copy()
    # Increments are sums of halvings of the target spacing; snap rounding residue to the target.
    tolerance = 1.0e-12
    results: list[SolveResult] = []
    time_reached = 0.0
    for step_index, target in enumerate(targets, start=1):
        increment = target - time_reached
        cuts = 0
        while time_reached < target:
            time_tried = time_reached + increment
            if time_tried > target - tolerance:
                time_tried = target
            update_load(time_tried)
            result = solver.solve()
            if result.converged:
                time_reached = time_tried
                u_vector.copy(last_converged)
                results.append(result)
                if on_step is not None:
                    on_step(time_reached, result)
                cuts = 0
                increment = 2.0 * increment
                continue

            last_converged.copy(u_vector)
            u.x.scatter_forward()
            update_load(time_reached)
            if cuts == max_cuts:
                raise SolverError(
                    f"load step {step_index} of {len(targets)} failed: Newton stopped with "
                    f"{result.reason_name} at pseudo-time {time_tried:.6g} after {cuts} "
                    f"consecutive step cuts; last converged pseudo-time {time_reached:.6g}, "
                    "to which the solution and the load are restored",
                    reason_name=result.reason_name,
                    step_index=step_index,
                    time_reached=time_reached,
                    time_tried=time_tried,
                )
            cuts += 1
            increment = 0.5 * (time_tried - time_reached)
    return results
