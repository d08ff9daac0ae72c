"""Conjugate gradients on the exact tangent, stopped at the first direction of negative curvature.

The iterative counterpart of the factorisation's inertia test. CG on the exact tangent K,
preconditioned by an SPD preconditioner built on the projected tangent K₊, minimises Newton's
quadratic model as long as every search direction has positive curvature pᵀKp > 0, and then
converges to the exact Newton direction: the iterative path uses the curvature where it is
positive. At the first search direction with pᵀKp ≤ 0 the model has no minimiser in the Krylov
space; the solver then solves with K₊ instead (the same preconditioner, no new setup), whose
direction is always one of descent. A PETSc KSP of type ``python`` runs it, so SNES, the
Eisenstat–Walker forcing terms and the options work as for any KSP.

The KSP's own operators are (K₊, K₊) and the exact tangent is handed to the context
(:attr:`TruncatedCG.operator`): a multigrid preconditioner computes its finest level's residuals
with the KSP's operator, and on K it would not be positive definite.

With a finite :attr:`TruncatedCG.radius` the solver is Steihaug–Toint's: CG on K from zero
stops where its iterate would leave the ball of that radius in the preconditioner's norm
‖x‖_M = (xᵀMx)^½ (M the preconditioner's matrix, AMG's approximation of the tangent: an energy
norm), or where it meets negative curvature, at the point of the ball's boundary along the
search direction. The CG iterates grow monotonically in that norm and lower the quadratic model
monotonically, so the step is always one of descent and uses the negative curvature instead of
dropping it (:mod:`.trust_region`).

With :attr:`TruncatedCG.indefinite` (set by the direction policy in Newton's local phase,
:mod:`.directions`) the solver meets negative curvature with preconditioned MINRES on K instead,
the same preconditioner, for the exact Newton direction K⁻¹b, and keeps it where it is one of
descent (bᵀx > 0); otherwise it goes on as above (the projected tangent, a blend, or the
boundary). Near a saddle point of the step's energy that the iterates approach by descent, the
exact direction converges quadratically to it, where the projected one converges linearly to the
same point and the trust region's boundary steps leave it for a minimum much further away.
MINRES gets :data:`MINRES_BUDGET` times the iterations of the last solve that converged on a
definite operator (at least :data:`MINRES_BUDGET` × :data:`DEFINITE_FLOOR`): where the exact
tangent is nearly singular it converges, if at all, only after thousands of iterations, to a
direction that the line search then cuts to almost nothing (the tangled scatter at 16³ × 6
cells: MINRES ran to PETSc's cap of 10 000 in four iterations of one step, and converged in a
fifth after 8 200 to a step of 2·10⁻⁴ of itself, against 50–90 for the projected tangent's
solves; out of the collapse at 32³ × 6 cells it converged in 2.5–5 times the definite solves'
iterations, docs/performance.md).

On Dirichlet rows both tangents are the identity and couple to nothing; there the solver
replaces the preconditioner by the identity (:attr:`TruncatedCG.fixed`), which is what it is
meant to approximate. AMG's coarse corrections otherwise reach the clamped nodes, and a solve
stopped early (on the trust region's boundary, at negative curvature, after a few iterations)
would move them: Π then changes by the work of their reaction forces, which the residual's
Dirichlet rows (x − g) do not show, the energy disagrees with the model along the step, and the
iterates leave the boundary values (docs/performance.md, the stretch bar at 16).
"""

from __future__ import annotations

import atexit
import math
import weakref

import numpy as np
from petsc4py import PETSc

from dolfinx_invertible import _compat

__all__ = [
    "BLEND_MARGIN",
    "BOUNDED",
    "DEFINITE_FLOOR",
    "MAX_RESTARTS",
    "MINRES_BUDGET",
    "SMALLEST_WEIGHT",
    "TruncatedCG",
    "truncated_cg",
]

_REASONS = PETSc.KSP.ConvergedReason
#: A blend's weight is this share of the largest one the direction of negative curvature allows.
BLEND_MARGIN = 1.0 - 1.0 / 512.0
#: Below this weight the blend is the projected tangent (the smallest rung of the direct path's
#: ladder, :data:`~dolfinx_invertible.solvers.directions.BLEND_WEIGHTS`).
SMALLEST_WEIGHT = 1.0 / 64.0
#: Restarts with a lower weight before the projected tangent is taken.
MAX_RESTARTS = 6
#: MINRES's iterations, in units of the last solve's on a definite operator (module description).
MINRES_BUDGET = 10
#: The fewest iterations that count as a definite solve's in MINRES's budget.
DEFINITE_FLOOR = 50
#: Work vectors: CG's five, MINRES's nine.
_WORK_VECTORS = 9
#: The outcome of a solve that stopped on the trust region's boundary.
BOUNDED = "bounded"


class TruncatedCG:
    """The context of a ``python`` KSP (see the module description).

    Attributes
    ----------
    operator
        The exact tangent K; ``None`` uses the KSP's operator (then K₊ alone).
    indefinite
        Past negative curvature, solve K x = b by MINRES and keep x where bᵀx > 0 (see the
        module description); default ``False``.
    blend
        Past negative curvature, solve with the blend w K + (1 − w) K₊ of the largest weight
        that the directions met allow (restarting from the iterate reached), rather than with
        K₊ alone.
    restart
        Past negative curvature, restart with the projected tangent or a blend (``True``), or
        stop with ``DIVERGED_INDEFINITE_MAT`` (``False``: the preconditioner is built on the
        exact tangent, which then cannot precondition the projected one).
    weight
        The weight w of the last solve's direction: 1 exact, 0 projected.
    outcome
        What the last solve returned: ``"exact"`` (CG on the exact tangent converged),
        ``"bounded"`` (stopped on the trust region's boundary), ``"blended"``, ``"projected"``
        or ``"failed"``.
    curvature_iteration
        The CG iteration at which negative curvature was met in the last solve, else ``None``.
    radius
        The trust region's radius in the preconditioner's norm; ``math.inf`` (default) solves
        without one.
    boundary
        Whether the last solve stopped on the trust region's boundary.
    step_norm
        The preconditioner's norm of the last solve's solution (``nan`` where a blend
        restarted from a nonzero iterate, whose norm the recurrences do not give).
    definite_iterations
        The iterations of the last solve that converged on a definite operator (K without
        negative curvature met, a definite blend, or K₊), ``None`` before the first; the unit
        of MINRES's budget.
    fixed
        Local indices of the owned rows where K and K₊ are the identity and couple to nothing
        (Dirichlet rows); empty by default. The preconditioner is replaced by the identity
        there (see the module description).
    """

    def __init__(self) -> None:
        self.operator: PETSc.Mat | None = None
        self.indefinite = False
        self.blend = False
        self.restart = True
        self.weight = 1.0
        self.outcome = "failed"
        self.curvature_iteration: int | None = None
        self.radius = math.inf
        self.boundary = False
        self.step_norm = math.nan
        self.definite_iterations: int | None = None
        self.fixed = np.zeros(0, dtype=np.int32)
        self._work: list[PETSc.Vec] | None = None

    def setUp(self, ksp: PETSc.KSP) -> None:  # noqa: N802 (petsc4py's name)
        """Forget the work vectors: the operators may have changed size."""
        self._work = None

    def reset(self, ksp: PETSc.KSP) -> None:
        """Release the work vectors."""
        self._release()

    def destroy(self, ksp: PETSc.KSP) -> None:
        """Release the work vectors with the KSP (before PETSc finalises)."""
        self._release()

    def _release(self) -> None:
        for vector in self._work or ():
            vector.destroy()
        self._work = None

    def _vectors(self, b: PETSc.Vec) -> list[PETSc.Vec]:
        if self._work is None or self._work[0].getSizes() != b.getSizes():
            self._work = [b.duplicate() for _ in range(_WORK_VECTORS)]
        return self._work

    def solve(self, ksp: PETSc.KSP, b: PETSc.Vec, x: PETSc.Vec) -> None:
        """Solve with the exact tangent, a definite blend, or the projected tangent."""
        projected, _ = ksp.getOperators()
        exact = projected if self.operator is None else self.operator
        rtol, atol, _, max_it = ksp.getTolerances()
        z = self._vectors(b)[1]
        self._precondition(ksp, b, z)
        bz = b.dot(z)
        self.curvature_iteration = None
        self.weight = 1.0
        self.boundary = False
        self.step_norm = math.nan
        if not (math.isfinite(bz) and bz >= 0.0):
            self._finish(ksp, _REASONS.DIVERGED_INDEFINITE_PC, 0, "failed")
            return
        target = max(rtol * math.sqrt(bz), atol)
        x.set(0.0)
        weight, iterations, restarts = 1.0, 0, 0
        indefinite = self.indefinite and self.restart
        while True:
            start = iterations
            reason, iterations, limit = self._cg(
                ksp, exact, projected, weight, b, x, target, iterations, max_it, indefinite
            )
            if reason != _compat.KSP_CONVERGED_NEGATIVE_CURVATURE or self.boundary:
                if reason > 0 and not self.boundary:
                    self.definite_iterations = iterations - start
                break
            if self.curvature_iteration is None:
                self.curvature_iteration = iterations
            if indefinite:
                indefinite = False
                budget = MINRES_BUDGET * max(self.definite_iterations or 0, DEFINITE_FLOOR)
                reason, iterations = self._minres(
                    ksp, exact, b, x, target, iterations, min(max_it, iterations + budget)
                )
                if reason > 0 and b.dot(x) > 0.0:
                    break
                reason = _compat.KSP_CONVERGED_NEGATIVE_CURVATURE
                if math.isfinite(self.radius):  # Steihaug–Toint's step after all
                    x.set(0.0)
                    continue
            if not self.restart:
                reason = _REASONS.DIVERGED_INDEFINITE_MAT
                break
            restarts += 1
            weight = min(weight, limit) * BLEND_MARGIN if self.blend else 0.0
            if weight < SMALLEST_WEIGHT or restarts > MAX_RESTARTS:
                weight = 0.0
                x.set(0.0)
        self.weight = weight
        if reason < 0:
            outcome = "failed"
        elif self.boundary:
            outcome = BOUNDED
        elif weight == 1.0:
            outcome = "exact"
        else:
            outcome = "blended" if weight > 0.0 else "projected"
            reason = _compat.KSP_CONVERGED_NEGATIVE_CURVATURE
        self._finish(ksp, reason, iterations, outcome)

    def _finish(self, ksp: PETSc.KSP, reason: int, iterations: int, outcome: str) -> None:
        self.outcome = outcome
        ksp.setIterationNumber(iterations)
        ksp.setConvergedReason(reason)

    def _cg(self, ksp, exact, projected, weight, b, x, target, start, max_it, indefinite=False):
        """Preconditioned CG on w K + (1 − w) K₊ from ``x``; return (reason, iterations, w*).

        Stops at a search direction p of non-positive curvature unless w = 0 (then K₊ alone,
        which has none: that is a failure); w* = pᵀK₊p / (pᵀK₊p − pᵀKp) is the largest weight
        that direction allows. From ``x`` = 0 it tracks ‖x‖_M, ‖p‖_M and xᵀMp by Steihaug's
        recurrences and stops on the boundary of a finite :attr:`radius` (at negative curvature
        too, where ``restart`` allows it).
        """
        r, z, p, q, k = self._vectors(b)[:5]

        def apply(vector, result) -> tuple[float, float]:
            # Returns (pᵀK p, pᵀK₊ p) where computed, for the weight that keeps p definite.
            if weight == 0.0:
                projected.mult(vector, result)
                return math.nan, vector.dot(result)
            exact.mult(vector, result)
            if weight == 1.0:
                return vector.dot(result), math.nan
            projected.mult(vector, k)
            exact_curvature, projected_curvature = vector.dot(result), vector.dot(k)
            result.scale(weight)
            result.axpy(1.0 - weight, k)
            return exact_curvature, projected_curvature

        from_zero = not x.norm(PETSc.NormType.NORM_INFINITY) > 0.0
        if from_zero:
            b.copy(r)
        else:
            apply(x, q)
            b.copy(r)
            r.axpy(-1.0, q)
        self._precondition(ksp, r, z)
        rz = r.dot(z)
        iteration = start
        if not (math.isfinite(rz) and rz >= 0.0):
            return _REASONS.DIVERGED_INDEFINITE_PC, iteration, math.nan
        norm = math.sqrt(rz)
        ksp.setResidualNorm(norm)
        ksp.logConvergenceHistory(norm)
        ksp.monitor(iteration, norm)
        if norm <= target:
            if from_zero:
                self.step_norm = 0.0
            return _REASONS.CONVERGED_RTOL, iteration, math.nan
        z.copy(p)
        # ‖x‖²_M, xᵀMp and ‖p‖²_M (Steihaug 1983), valid from x = 0 only.
        xx, xp, pp = 0.0, 0.0, rz
        bounded = from_zero and math.isfinite(self.radius)
        while iteration < max_it:
            exact_curvature, projected_curvature = apply(p, q)
            curvature = p.dot(q)
            if not math.isfinite(curvature):
                return _REASONS.DIVERGED_NANORINF, iteration, math.nan
            if curvature <= 0.0 and bounded and self.restart and not indefinite:
                self._to_boundary(x, p, xx, xp, pp)
                return _compat.KSP_CONVERGED_NEGATIVE_CURVATURE, iteration, math.nan
            if curvature <= 0.0:
                if weight == 0.0:
                    return _REASONS.DIVERGED_INDEFINITE_MAT, iteration, math.nan
                if math.isnan(projected_curvature):
                    projected.mult(p, k)
                    projected_curvature = p.dot(k)
                drop = projected_curvature - exact_curvature
                limit = projected_curvature / drop if drop > 0.0 else 0.0
                return _compat.KSP_CONVERGED_NEGATIVE_CURVATURE, iteration, limit
            alpha = rz / curvature
            if bounded and xx + alpha * (2.0 * xp + alpha * pp) >= self.radius**2:
                self._to_boundary(x, p, xx, xp, pp)
                return _REASONS.CONVERGED_STEP_LENGTH, iteration + 1, math.nan
            x.axpy(alpha, p)
            r.axpy(-alpha, q)
            self._precondition(ksp, r, z)
            rz_next = r.dot(z)
            iteration += 1
            xx += alpha * (2.0 * xp + alpha * pp)
            if from_zero:
                self.step_norm = math.sqrt(max(xx, 0.0))
            if not (math.isfinite(rz_next) and rz_next >= 0.0):
                return _REASONS.DIVERGED_INDEFINITE_PC, iteration, math.nan
            norm = math.sqrt(rz_next)
            ksp.setResidualNorm(norm)
            ksp.logConvergenceHistory(norm)
            ksp.monitor(iteration, norm)
            if norm <= target:
                return _REASONS.CONVERGED_RTOL, iteration, math.nan
            beta = rz_next / rz
            xp = beta * (xp + alpha * pp)
            pp = rz_next + beta * beta * pp
            p.aypx(beta, z)
            rz = rz_next
        return _REASONS.DIVERGED_MAX_IT, iteration, math.nan

    def _minres(self, ksp, exact, b, x, target, start, max_it) -> tuple[int, int]:
        """Preconditioned MINRES on K from x = 0; return (reason, iterations).

        K symmetric and indefinite, the preconditioner M symmetric positive definite (Paige and
        Saunders 1975, with Lanczos in M⁻¹'s inner product); the residual is measured in M⁻¹'s
        norm, as CG's, and falls monotonically.
        """
        v_old, v, v_new, z, z_new, w_old, w, w_new, q = self._vectors(b)[:9]
        x.set(0.0)
        v_old.set(0.0)
        w_old.set(0.0)
        w.set(0.0)
        b.copy(v)
        self._precondition(ksp, v, z)
        gamma = math.sqrt(max(v.dot(z), 0.0))
        gamma_old, eta = 1.0, gamma
        c_old, c, s_old, s = 1.0, 1.0, 0.0, 0.0
        iteration = start
        while iteration < max_it and gamma > 0.0:
            z.scale(1.0 / gamma)
            exact.mult(z, q)
            delta = z.dot(q)
            # v_new = K z − (δ/γ) v − (γ/γ_old) v_old
            q.copy(v_new)
            v_new.axpy(-delta / gamma, v)
            v_new.axpy(-gamma / gamma_old, v_old)
            self._precondition(ksp, v_new, z_new)
            gamma_new_squared = v_new.dot(z_new)
            if not (math.isfinite(gamma_new_squared) and gamma_new_squared >= 0.0):
                return _REASONS.DIVERGED_INDEFINITE_PC, iteration
            gamma_new = math.sqrt(gamma_new_squared)
            alpha0 = c * delta - c_old * s * gamma
            alpha1 = math.hypot(alpha0, gamma_new)
            alpha2 = s * delta + c_old * c * gamma
            alpha3 = s_old * gamma
            if alpha1 == 0.0:
                return _REASONS.DIVERGED_BREAKDOWN, iteration
            c_new, s_new = alpha0 / alpha1, gamma_new / alpha1
            # w_new = (z − α₃ w_old − α₂ w) / α₁
            z.copy(w_new)
            w_new.axpy(-alpha3, w_old)
            w_new.axpy(-alpha2, w)
            w_new.scale(1.0 / alpha1)
            x.axpy(c_new * eta, w_new)
            eta = -s_new * eta
            iteration += 1
            norm = abs(eta)
            ksp.setResidualNorm(norm)
            ksp.logConvergenceHistory(norm)
            ksp.monitor(iteration, norm)
            if not math.isfinite(norm):
                return _REASONS.DIVERGED_NANORINF, iteration
            if norm <= target:
                return _REASONS.CONVERGED_RTOL, iteration
            v, v_old, v_new = v_new, v, v_old
            z, z_new = z_new, z
            w_old, w, w_new = w, w_new, w_old
            gamma_old, gamma = gamma, gamma_new
            c_old, c, s_old, s = c, c_new, s, s_new
        return _REASONS.DIVERGED_MAX_IT, iteration

    def _precondition(self, ksp: PETSc.KSP, r: PETSc.Vec, z: PETSc.Vec) -> None:
        """Apply the preconditioner, z = M⁻¹ r, but the identity on the :attr:`fixed` rows."""
        ksp.getPC().apply(r, z)
        if len(self.fixed):
            z.array[self.fixed] = r.array_r[self.fixed]

    def _to_boundary(self, x, p, xx: float, xp: float, pp: float) -> None:
        """Move ``x`` along ``p`` (σ ≥ 0) to ‖x + σp‖_M = :attr:`radius`."""
        gap = max(self.radius**2 - xx, 0.0)
        sigma = gap / (xp + math.sqrt(xp * xp + pp * gap)) if gap > 0.0 else 0.0
        x.axpy(sigma, p)
        self.boundary = True
        self.step_norm = self.radius


# KSPs whose type is ``python``: PETSc must drop their Python contexts while the interpreter and
# PETSc are both alive. An exit handler registered after petsc4py's runs before PETSc finalises
# (handlers run last-registered first); a context destroyed later crashes the process.
_PYTHON_KSPS: list[weakref.ref] = []


@atexit.register
def _release_contexts() -> None:
    for reference in _PYTHON_KSPS:
        ksp = reference()
        if ksp is not None and ksp.handle:
            ksp.setType(PETSc.KSP.Type.CG)
    _PYTHON_KSPS.clear()


def truncated_cg(ksp: PETSc.KSP) -> TruncatedCG:
    """Make ``ksp`` a :class:`TruncatedCG`; return its context."""
    context = TruncatedCG()
    ksp.setType(PETSc.KSP.Type.PYTHON)
    ksp.setPythonContext(context)
    _PYTHON_KSPS[:] = [reference for reference in _PYTHON_KSPS if reference() is not None]
    _PYTHON_KSPS.append(weakref.ref(ksp))
    return context
