"""Newton directions: which tangent an iteration uses and what replaces a direction that fails.

SNES solves with the tangent the problem assembles (:class:`NewtonDirections` chooses between
the exact and the SPD-projected one where the problem can switch). The minimiser then judges the
direction: a failed linear solve, a direction that is not a descent direction or, where the
factorisation reports its inertia, an indefinite exact tangent, is replaced at the same iterate
by a direction strategy:

- :class:`ProjectedTangent`: solve with the SPD-projected tangent K₊. Always a descent
  direction, but the projection drops all of the cells' negative curvature, even where the mass
  or the rest of the body outweighs most of it, and Newton on K₊ then converges only linearly.
- :class:`BlendedTangent`: solve with K₊ + w (K − K₊) for the largest weight w of a ladder
  (511/512 … 1/64) whose factorisation has no negative pivot (needs a factorisation that
  reports its inertia: MUMPS LDLᵀ); out of a collapsed state at λ/μ = 49 it takes 16 Newton
  iterations where the projected tangent takes 86. It is a last resort, not the default: a step
  that the blend brings home in many iterations has often travelled to another minimum of the
  step's energy (an inverted one, in a collapse) where cutting the step would have kept the
  motion resolved. The policy switches to it after ``blend_after`` projected iterations of a
  solve, and the steppers escalate to it (``blend_after = 0``) when a step's cuts run out.

With a tangent switch, the next tangent is the exact one only in Newton's local phase, after a
full (unshortened) step; the projected one otherwise.

On the iterative path an iteration with the exact tangent K needs a preconditioner that is
positive definite. While the truncated CG has met no negative curvature in the last exact
iteration, the preconditioner is built on K itself: one tangent assembled, and AMG on the
operator CG runs on, as plain Newton–CG. Where it meets negative curvature (or AMG on K is not
definite) the iteration's direction is computed again with AMG on the projected tangent K₊ (the
truncated CG on K, then on K₊ or a blend), and K₊ preconditions the exact iterations until one
of them meets no negative curvature again.

In a trust region a projected preconditioner is kept from one iteration to the next: the
iteration assembles the exact tangent, the operator of its truncated CG, but leaves K₊ of an
earlier iterate in the preconditioning matrix, and PETSc, seeing the matrix unchanged, skips
the AMG set-up. AMG built on any SPD matrix is an SPD preconditioner, so CG and the trust
region's norm stay valid; what an old K₊ loses is only how well it preconditions, and the
Krylov iterations tell: K₊ is built again at the iterate after a solve that needed more than
:data:`KRYLOV_GROWTH` times the Krylov iterations of the first solve after the last build
(plus :data:`KRYLOV_SLACK`), after :data:`PRECONDITIONER_LIFETIME` iterations, and at the first
iteration of every solve. Where the exact tangent has negative curvature in every iteration (a
tangled body crawling through its first step, each iteration a boundary step after 0–1 Krylov
iterations) the assembly of K₊ and the AMG set-up were about half of the run's time
(docs/performance.md). With a line search it is built at every iteration
(:meth:`NewtonDirections._keep_preconditioner`).

In Newton's local phase on the iterative path — after the first iteration of a solve, the last
step full, not bounded by a trust region, and its decrease of the energy at least 3/4 of what
its quadratic model predicted (ρ, the trust region's test for growing its radius) — the
truncated CG meets negative curvature with MINRES on the exact system and keeps that direction
where it is one of descent (:attr:`NewtonDirections.indefinite_newton`, :mod:`.truncated_cg`).
The iterates then converge quadratically to the stationary point they are closing in on, even
where it is a saddle of the step's energy: the collapse at 32³ × 6 cells takes its first step
in 6 iterations, where the projected tangent crawls towards the same point at 0.97 an
iteration and the trust region left it for an inverted minimum after 89–132
(docs/performance.md). Outside the local phase the exact direction, even where it descends,
is a poor one (the tangled scatter at 8³ × 6 cells: 1 784 Newton iterations with it in every
iteration of the line search, 873 with the trust region), so nothing changes there. The direct
path keeps the inertia test: out of a collapsed cube at ν = 0.499 the exact direction in its
local phase led the step to another stationary point (537 263 J against 714 975 J), and the
escalation's blend from 16 iterations to 198.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from petsc4py import PETSc

from dolfinx_invertible.solvers.nullspace import rigid_body_near_nullspace
from dolfinx_invertible.solvers.patterns import copy_into, structure
from dolfinx_invertible.solvers.results import ksp_reason_name
from dolfinx_invertible.solvers.truncated_cg import BOUNDED, TruncatedCG, truncated_cg
from dolfinx_invertible.solvers.trust_region import TrustRegion

__all__ = [
    "BLEND_WEIGHTS",
    "BlendedTangent",
    "NewtonDirections",
    "ProjectedTangent",
    "has_inertia",
    "is_indefinite",
]

_SAME_PATTERN = PETSc.Mat.Structure.SAME_NONZERO_PATTERN

#: Newton iterations a projected preconditioner (K₊ of an earlier iterate and its AMG) is kept
#: for at most in a trust region, and how far the Krylov iterations may grow meanwhile:
#: past KRYLOV_GROWTH times those of the first solve after it was built, plus KRYLOV_SLACK, it
#: is built again at the next iterate (module description).
PRECONDITIONER_LIFETIME = 8
KRYLOV_GROWTH = 1.5
KRYLOV_SLACK = 5

#: Weights of the removed negative curvature tried in a blended tangent, from nearly the exact
#: tangent down to nearly the projected one.
BLEND_WEIGHTS = (1.0 - 1.0 / 512.0, 1.0 - 1.0 / 64.0, 1.0 - 1.0 / 8.0, 0.5, 1.0 / 8.0, 1.0 / 64.0)


def has_inertia(ksp: PETSc.KSP) -> bool:
    """Whether the linear solver's factorisation reports its inertia (MUMPS Cholesky/LDLᵀ)."""
    pc = ksp.getPC()
    return pc.getType() == PETSc.PC.Type.CHOLESKY and pc.getFactorSolverType() == "mumps"


def is_indefinite(ksp: PETSc.KSP) -> bool:
    """Whether the factorised operator has negative pivots (``False`` where none is known).

    The preconditioner in effect decides, not our defaults: options may replace the
    factorisation by a Krylov solver, whose PC has no factor to ask.
    """
    if not has_inertia(ksp):
        return False
    negative, _, _ = ksp.getPC().getFactorMatrix().getInertia()
    return negative > 0


class ProjectedTangent:
    """Replace a direction by the SPD-projected tangent's at the same iterate."""

    kind = "projected"

    def direction(self, directions: NewtonDirections, x: PETSc.Vec, y: PETSc.Vec, ksp) -> str:
        """Solve K₊ y = r at ``x``; return the kind of direction computed."""
        directions.assemble_projected(x)
        directions.solve(ksp, y)
        return self.kind


class BlendedTangent:
    """Replace a direction by the most exact positive definite blend of the two tangents.

    K − K₊ is what the projection removed: the negative curvature of the cells, which the mass
    (or the rest of the body) can outweigh. The blend K₊ + w (K − K₊) keeps as much of it as
    leaves the assembled matrix positive definite (the factorisation's inertia decides). The
    weights of :data:`BLEND_WEIGHTS` are tried from one rung above the last accepted one
    downwards; if none is definite, the plain projected tangent's direction is used.
    """

    kind = "blended"

    def __init__(self) -> None:
        self.rung = 0  # index of the last weight that kept the blend definite
        self._exact: PETSc.Mat | None = None
        self._projected: PETSc.Mat | None = None

    def direction(self, directions: NewtonDirections, x: PETSc.Vec, y: PETSc.Vec, ksp) -> str:
        """Solve with the best definite blend at ``x``; return the kind of direction computed."""
        matrix = directions.matrix
        # The exact tangent SNES just factorised, before the projected one overwrites it.
        self._exact = copy_into(matrix, self._exact)
        directions.assemble_projected(x)
        self._exact.axpy(-1.0, matrix, structure=structure(matrix, self._exact))  # K − K₊
        self._projected = copy_into(matrix, self._projected)
        for rung in range(max(self.rung - 1, 0), len(BLEND_WEIGHTS)):
            self._projected.copy(matrix, structure=_SAME_PATTERN)
            matrix.axpy(BLEND_WEIGHTS[rung], self._exact, structure=structure(self._exact, matrix))
            directions.solve(ksp, y)
            if ksp.getConvergedReason() > 0 and not is_indefinite(ksp):
                self.rung = rung
                return self.kind
        self.rung = len(BLEND_WEIGHTS)
        self._projected.copy(matrix, structure=_SAME_PATTERN)
        directions.solve(ksp, y)
        return ProjectedTangent.kind


class NewtonDirections:
    """The direction policy of a minimiser: the tangent of each iteration and its replacement.

    Parameters
    ----------
    problem
        The :class:`~dolfinx_invertible.solvers.problem.EnergyProblem`.
    residual
        The residual vector of the current iterate.
    options
        The minimiser's :class:`~dolfinx_invertible.solvers.options.MinimizerOptions`.
    tangent_switch
        ``tangent_switch(projected)`` switches the problem's tangent between exact and
        SPD-projected; ``None`` means no replacement is possible.
    blend_after
        Projected iterations of a solve after which :class:`BlendedTangent` replaces
        :class:`ProjectedTangent` (where the factorisation reports its inertia); ``None``
        never, until :meth:`escalate`.
    assembled
        Called with each assembled tangent (the tolerances read its diagonal).
    tangent
        What the problem's own tangent is, as monitors name it: ``"exact"`` or ``"projected"``.
    trust_region
        The :class:`~dolfinx_invertible.solvers.trust_region.TrustRegion` whose radius bounds
        the truncated CG's directions, and with which every iteration takes the exact tangent;
        ``None`` (default): no bound, and the projected tangent outside Newton's local phase.
    indefinite_newton
        Keep the exact direction past negative curvature in Newton's local phase (see the
        module description).

    Attributes
    ----------
    matrix, preconditioner
        The matrices SNES assembles the tangent and its preconditioning matrix into (one and
        the same but on the iterative path, where the latter holds the projected tangent).
    kind
        Where the current iteration's direction came from (:data:`.monitors.DIRECTION_KINDS`).
    projected_iterations, blended_iterations
        Iterations of the current solve whose direction came from the projected tangent (a
        blend included) and from a blend.
    replacement_linear_iterations
        Krylov iterations of the current iteration's replacement solves.
    indefinite_newton
        Whether Newton's local phase keeps the exact tangent's direction past negative
        curvature where it descends (see the module description).
    local_phase
        Whether the current iteration is in Newton's local phase (the module description;
        iterative path only, ``False`` on the direct path).
    model_ratio
        ρ of the last step: its energy decrease over its quadratic model's (``nan`` before
        the first, where the step was not measured, and on the direct path).
    exact_preconditioner
        Whether the next exact iteration of the iterative path preconditions with AMG on the
        exact tangent (no negative curvature met in the last one) rather than the projected.
    preconditioned_by
        What the current iteration's preconditioning matrix is: ``"exact"``, ``"projected"``,
        or ``"exact failed"`` (solved again with the projected one, see :meth:`settle`).
    direction_tangent
        The matrix holding the tangent the current direction was solved with (``None`` for a
        blend, which no matrix holds).
    preconditioner_age
        Iterations since the projected preconditioner (K₊ and its AMG) was built: 0 at the
        iterate it was built at, more where it was kept (the module description); ``None``
        where the preconditioning matrix is not a projected one that can be kept.
    """

    def __init__(
        self,
        problem,
        residual: PETSc.Vec,
        options,
        *,
        tangent_switch: Callable[[bool], None] | None,
        blend_after: int | None,
        assembled: Callable[[PETSc.Mat], None],
        tangent: str = "exact",
        trust_region: TrustRegion | None = None,
        indefinite_newton: bool = True,
    ) -> None:
        if blend_after is not None and (int(blend_after) != blend_after or blend_after < 0):
            raise ValueError(f"blend_after must be an integer >= 0 or None, got {blend_after!r}")
        if tangent not in ("exact", "projected"):
            raise ValueError(f"tangent must be 'exact' or 'projected', got {tangent!r}")
        self.problem = problem
        self.residual = residual
        self.options = options
        self.tangent_switch = tangent_switch
        self.blend_after = None if blend_after is None else int(blend_after)
        self.tangent = tangent
        self.trust_region = trust_region
        self._assembled = assembled
        #: Local indices of the owned Dirichlet rows (components unrolled).
        self.fixed = np.flatnonzero(~problem.free_owned).astype(np.int32)
        near_nullspace = rigid_body_near_nullspace(problem.u.function_space)
        self.matrix = problem.create_matrix()
        self.matrix.setNearNullSpace(near_nullspace)
        # The iterative path preconditions CG on the exact tangent with the projected one.
        self.preconditioner = self.matrix
        if options.linear_solver == "iterative" and tangent_switch is not None:
            self.preconditioner = problem.create_matrix()
            self.preconditioner.setNearNullSpace(near_nullspace)
        self.exact_preconditioner = True
        self.preconditioner_age: int | None = None
        self._krylov_after_build: int | None = None
        self._krylov_last: int | None = None
        self.indefinite_newton = bool(indefinite_newton)
        self.preconditioned_by = "projected"
        self.direction_tangent: PETSc.Mat | None = self.matrix
        self._projected = ProjectedTangent()
        self._blended = BlendedTangent()
        #: The truncated CG solving for the directions where the iterative path runs it.
        self.truncated: TruncatedCG | None = None
        self._ksp: PETSc.KSP | None = None
        self.start_solve()

    def choose_krylov_method(self, ksp: PETSc.KSP) -> None:
        """Make ``ksp`` a truncated CG where the iterative path preconditions with K₊.

        Any other Krylov method the options ask for is run as PETSc has it.
        """
        self.truncated = None
        if self.preconditioner is not self.matrix and ksp.getType() == PETSc.KSP.Type.CG:
            self._ksp = ksp  # the context lives as long as this reference (truncated_cg)
            self.truncated = truncated_cg(ksp)
            self.truncated.operator = self.matrix
            self.truncated.fixed = self.fixed

    @property
    def replaceable(self) -> bool:
        """Whether a failed direction can be replaced (the problem has a tangent switch)."""
        return self.tangent_switch is not None

    def start_solve(self) -> None:
        """Begin a solve: the exact tangent first, no replacements counted."""
        self._exact_next = True
        self.local_phase = False
        self._full_step = True
        self._last_kind = self.tangent
        self.model_ratio = math.nan
        self._steps = 0
        self.projected_now = False
        self.projected_iterations = 0
        self.blended_iterations = 0
        self.replacement_linear_iterations = 0
        self.kind = self.tangent
        self._blended.rung = 0
        self.preconditioner_age = None

    # -- the tangent of an iteration --------------------------------------------------------
    def assemble(self, snes, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat) -> None:
        """SNES Jacobian callback: the exact tangent, or outside Newton's local phase projected.

        On the iterative path SNES hands :attr:`preconditioner` as both matrices: the tangent
        goes into :attr:`matrix` (the truncated CG's operator), and into ``P`` the tangent the
        preconditioner is built on (the projected one, or the exact one while it has shown no
        negative curvature).
        """
        if P.handle == self.preconditioner.handle and P.handle != self.matrix.handle:
            A = self.matrix
        projected = self.tangent_switch is not None and not self._exact_next
        self.projected_now = projected
        self.kind = ProjectedTangent.kind if projected else self.tangent
        self.replacement_linear_iterations = 0
        if self.truncated is not None:
            self.local_phase = (
                self._steps > 0
                and self._full_step
                and self._last_kind != BOUNDED
                and self.model_ratio > TrustRegion.GROW_ABOVE
            )
            self.truncated.blend = self._blending()
            self.truncated.indefinite = self.indefinite_newton and self.local_phase
            if self.trust_region is not None:
                self.truncated.radius = self.trust_region.radius
        self._assemble_tangent_into(x, A, projected)
        self.direction_tangent = A
        self.preconditioned_by = "projected"
        if P is not None and P.handle != A.handle:
            if projected or (self.exact_preconditioner and self.truncated is not None):
                if P.assembled:
                    copy_into(A, P)
                else:  # a copy needs an assembled target
                    self._assemble_tangent_into(x, P, projected)
                if not projected:
                    self.preconditioned_by = "exact"
                self.preconditioner_age = None
            elif self._keep_preconditioner():
                # P unchanged: PETSc skips the AMG set-up too (module description).
                self.preconditioner_age += 1
            else:
                self._build_projected_preconditioner(x)
        if self.truncated is not None:
            self.truncated.restart = self.preconditioned_by != "exact"
        self._assembled(A)

    def _assemble_tangent_into(self, x: PETSc.Vec, matrix: PETSc.Mat, projected: bool) -> None:
        if projected:
            self.tangent_switch(True)
        try:
            self.problem.J(None, x, matrix, matrix)
        finally:
            if projected:
                self.tangent_switch(False)

    def _build_projected_preconditioner(self, x: PETSc.Vec) -> None:
        """Assemble K₊ at ``x`` into :attr:`preconditioner` (its AMG is set up anew)."""
        self._assemble_tangent_into(x, self.preconditioner, True)
        self.preconditioner_age = 0
        self._krylov_after_build = None

    def _keep_preconditioner(self) -> bool:
        """Whether this iteration keeps the projected preconditioner of an earlier iterate.

        Kept in a trust region while it is younger than :data:`PRECONDITIONER_LIFETIME`
        iterations and the last solve needed at most :data:`KRYLOV_GROWTH` times the Krylov
        iterations (plus :data:`KRYLOV_SLACK`) of the first solve after it was built. With a
        line search, the truncated CG's fallback at negative curvature solves with K₊, and that
        direction is the step itself: K₊ of an earlier iterate gave another step and, out of a
        collapse, led to another minimiser (tests/solvers/test_hyperelastic.py). In a trust
        region only a solve's first direction, always on a K₊ just built, is the projected one.
        """
        age = self.preconditioner_age
        if self.trust_region is None or age is None or age + 1 >= PRECONDITIONER_LIFETIME:
            return False
        first, last = self._krylov_after_build, self._krylov_last
        return first is None or last is None or last <= KRYLOV_GROWTH * first + KRYLOV_SLACK

    def assemble_projected(self, x: PETSc.Vec) -> None:
        """Assemble the projected tangent at ``x`` into :attr:`matrix`."""
        self.tangent_switch(True)
        try:
            self.assemble(None, x, self.matrix, self.matrix)
        finally:
            self.tangent_switch(False)

    def solve(self, ksp: PETSc.KSP, y: PETSc.Vec, *, replacement: bool = True) -> None:
        """Solve :attr:`matrix` · y = residual (with the options in effect).

        A replacement direction's solve preconditions with :attr:`matrix` itself and counts
        its Krylov iterations; otherwise the preconditioning matrix is SNES's.
        """
        with self.options.in_effect():
            if replacement:
                ksp.setOperators(self.matrix, self.matrix)
            else:
                ksp.setOperators(*self.snes_matrices)
            ksp.solve(self.residual, y)
        if replacement:
            self.replacement_linear_iterations += int(ksp.getIterationNumber())

    @property
    def snes_matrices(self) -> tuple[PETSc.Mat, PETSc.Mat]:
        """The (operator, preconditioning matrix) SNES hands its KSP."""
        return (self.preconditioner, self.preconditioner)

    def after_step(self, full_step: bool) -> None:
        """Choose the next tangent: the exact one after a full step, or in a trust region."""
        self._exact_next = full_step or self.trust_region is not None
        self._full_step = full_step
        self._last_kind = self.kind
        self._steps += 1

    # -- judging and replacing --------------------------------------------------------------
    def judge(self, ksp: PETSc.KSP, y: PETSc.Vec, *, has_energy: bool) -> tuple[bool, str]:
        """Return whether ``y`` is usable, and if not why.

        Usable: the linear solve converged and, on an energy, ``y`` is a descent direction, and
        where the exact tangent was factorised with a known inertia, it was definite.
        """
        reason = ksp.getConvergedReason()
        truncated = self.truncated
        if self.preconditioner_age is not None:
            self._krylov_last = int(ksp.getIterationNumber())
            if self._krylov_after_build is None:
                self._krylov_after_build = self._krylov_last
        if truncated is not None and not self.projected_now:
            if reason > 0 and self.preconditioned_by == "projected":
                self.exact_preconditioner = (
                    truncated.outcome == "exact" and truncated.curvature_iteration is None
                )
            if truncated.outcome in (ProjectedTangent.kind, BlendedTangent.kind):
                # Negative curvature: the truncated CG solved with the projected tangent or a
                # definite blend instead.
                self.projected_now = True
                self.kind = truncated.outcome
                self.direction_tangent = self.preconditioner
                if truncated.outcome == BlendedTangent.kind:
                    self.blended_iterations += 1
                    self.direction_tangent = None
            elif truncated.outcome == BOUNDED:
                self.kind = BOUNDED
        if reason < 0:
            return False, f"the linear solve failed ({ksp_reason_name(reason)})"
        if not has_energy:
            return True, ""
        check_inertia = self.tangent_switch is not None and not self.projected_now
        if check_inertia and is_indefinite(ksp):
            return False, "the exact tangent is indefinite"
        slope = self.residual.dot(y)
        if not (math.isfinite(slope) and slope > 0.0):
            return False, "the Newton direction is not a descent direction"
        return True, ""

    def count_iteration(self) -> None:
        """Count the iteration whose direction came from the projected tangent."""
        if self.projected_now:
            self.projected_iterations += 1

    def _blending(self) -> bool:
        """Whether the current iteration blends: after ``blend_after`` projected iterations."""
        return self.blend_after is not None and self.projected_iterations >= self.blend_after

    def settle(self, x: PETSc.Vec, y: PETSc.Vec, ksp: PETSc.KSP) -> None:
        """Make ``y`` the iteration's direction: solved again where needed, exact on Dirichlet rows.

        The truncated CG on K with the exact tangent's own preconditioner stops at negative
        curvature (or an indefinite preconditioner); where it did at ``x``, the direction is
        solved again with AMG on K₊, the iterative path's usual one, and K₊ preconditions the
        exact iterations from now on (until one meets no negative curvature). Then the
        Dirichlet rows get their exact step (:meth:`_keep_dirichlet_rows`). Call before
        :meth:`judge`.
        """
        if self.preconditioned_by == "exact" and ksp.getConvergedReason() <= 0:
            self.preconditioned_by = "exact failed"
            self.exact_preconditioner = False
            self._build_projected_preconditioner(x)
            self.truncated.restart = True
            self.solve(ksp, y, replacement=False)
            self.replacement_linear_iterations += int(ksp.getIterationNumber())
        self._keep_dirichlet_rows(y)

    def _keep_dirichlet_rows(self, y: PETSc.Vec) -> None:
        """Give ``y`` the Newton step of the Dirichlet rows exactly: their residual, x − g.

        There the tangent is the identity, so a factorisation gives it anyway; an iterative
        solve stopped early does not (AMG's coarse corrections reach the Dirichlet nodes), and
        a direction that moves a clamped node changes Π by the work of its reaction force,
        which the residual's Dirichlet row does not show: the energy then disagrees with the
        model along the direction (docs/performance.md, the stretch bar at 16).
        """
        if len(self.fixed):
            y.array[self.fixed] = self.residual.array_r[self.fixed]

    def replace(self, x: PETSc.Vec, y: PETSc.Vec, ksp: PETSc.KSP) -> None:
        """Compute the direction at ``x`` again with the strategy in effect."""
        blend = self._blending() and has_inertia(ksp)
        strategy = self._blended if blend else self._projected
        kind = strategy.direction(self, x, y, ksp)
        self.projected_iterations += 1
        self.projected_now = True
        self.kind = kind
        self.direction_tangent = self.matrix
        if kind == BlendedTangent.kind:
            self.blended_iterations += 1
            self.direction_tangent = None
        self._keep_dirichlet_rows(y)

    def escalate(self, ksp: PETSc.KSP) -> bool:
        """Blend from the first projected iteration on, for good; ``False`` if nothing changes.

        Nothing changes without a tangent switch, without a definiteness test (the inertia of
        a factorisation, or the truncated CG's curvature), in a trust region (whose steps use
        the negative curvature already), or when blending from the first iteration already.
        """
        if self.tangent_switch is None or self.blend_after == 0 or self.trust_region is not None:
            return False
        if self.truncated is None and not has_inertia(ksp):
            return False
        self.blend_after = 0
        return True
