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
"""

from __future__ import annotations

import atexit
import math
import weakref

from petsc4py import PETSc

__all__ = ["TruncatedCG", "truncated_cg"]

_REASONS = PETSc.KSP.ConvergedReason


class TruncatedCG:
    """The context of a ``python`` KSP (see the module description).

    Attributes
    ----------
    operator
        The exact tangent K; ``None`` uses the KSP's operator (then K₊ alone).
    outcome
        What the last solve returned: ``"exact"`` (CG on the exact tangent converged),
        ``"projected"`` (negative curvature: the projected tangent's direction) or ``"failed"``.
    curvature_iteration
        The CG iteration at which negative curvature was met in the last solve, else ``None``.
    """

    def __init__(self) -> None:
        self.operator: PETSc.Mat | None = None
        self.outcome = "failed"
        self.curvature_iteration: int | None = None
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
            self._work = [b.duplicate() for _ in range(4)]
        return self._work

    def solve(self, ksp: PETSc.KSP, b: PETSc.Vec, x: PETSc.Vec) -> None:
        """Solve with the operator, or past negative curvature with the preconditioning matrix."""
        projected, _ = ksp.getOperators()
        operator = projected if self.operator is None else self.operator
        self.curvature_iteration = None
        reason, iterations = self._cg(ksp, operator, b, x, truncate=True, start=0)
        if reason == _REASONS.CONVERGED_CG_NEG_CURVE:
            self.curvature_iteration = iterations
            reason, iterations = self._cg(ksp, projected, b, x, truncate=False, start=iterations)
            self.outcome = "projected" if reason > 0 else "failed"
            if reason > 0:
                reason = _REASONS.CONVERGED_CG_NEG_CURVE
        else:
            self.outcome = "exact" if reason > 0 else "failed"
        ksp.setIterationNumber(iterations)
        ksp.setConvergedReason(reason)

    def _cg(self, ksp, operator, b, x, *, truncate: bool, start: int) -> tuple[int, int]:
        """Preconditioned CG from x = 0; return (reason, iterations counted from ``start``)."""
        r, z, p, q = self._vectors(b)
        pc = ksp.getPC()
        rtol, atol, _, max_it = ksp.getTolerances()
        x.set(0.0)
        b.copy(r)
        pc.apply(r, z)
        rz = r.dot(z)
        if not (math.isfinite(rz) and rz >= 0.0):
            return _REASONS.DIVERGED_INDEFINITE_PC, start
        norm = math.sqrt(rz)
        target = max(rtol * norm, atol)
        ksp.setResidualNorm(norm)
        ksp.logConvergenceHistory(norm)
        ksp.monitor(start, norm)
        if norm <= target:
            return _REASONS.CONVERGED_ATOL, start
        z.copy(p)
        iteration = start
        for _ in range(max_it):
            operator.mult(p, q)
            curvature = p.dot(q)
            if not math.isfinite(curvature):
                return _REASONS.DIVERGED_NANORINF, iteration
            if curvature <= 0.0:
                if truncate:
                    return _REASONS.CONVERGED_CG_NEG_CURVE, iteration
                return _REASONS.DIVERGED_INDEFINITE_MAT, iteration
            alpha = rz / curvature
            x.axpy(alpha, p)
            r.axpy(-alpha, q)
            pc.apply(r, z)
            rz_next = r.dot(z)
            iteration += 1
            if not (math.isfinite(rz_next) and rz_next >= 0.0):
                return _REASONS.DIVERGED_INDEFINITE_PC, iteration
            norm = math.sqrt(rz_next)
            ksp.setResidualNorm(norm)
            ksp.logConvergenceHistory(norm)
            ksp.monitor(iteration, norm)
            if norm <= target:
                return _REASONS.CONVERGED_RTOL, iteration
            p.aypx(rz_next / rz, z)
            rz = rz_next
        return _REASONS.DIVERGED_MAX_IT, iteration


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
