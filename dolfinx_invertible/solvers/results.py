"""What a nonlinear solve reports (:class:`SolveResult`), and the error when stepping gives up."""

from __future__ import annotations

import dataclasses

from petsc4py import PETSc

__all__ = ["STAGES", "SolveResult", "SolverError", "ksp_reason_name", "snes_reason_name"]


#: The solver stages a failed solve names (``SolveResult.stage``).
STAGES = ("linear solve", "line search", "stalled", "iteration cap", "NaN")


class SolverError(RuntimeError):
    """Stepping gave up: Newton failed after the largest allowed number of step cuts.

    Raised by the stepping loops (load steps and time steps), which fill in every attribute.

    Attributes
    ----------
    reason_name
        PETSc SNES converged reason of the last failed attempt, e.g. ``"DIVERGED_MAX_IT"``.
    stage
        The solver stage that failed in the last attempt: one of :data:`STAGES`.
    step_index
        1-based index of the step that could not be completed.
    time_reached
        Last completed (pseudo-)time; the solution and the loads are restored to it.
    time_tried
        (Pseudo-)time of the last failed attempt.
    result
        The :class:`SolveResult` of the last failed attempt.
    """

    def __init__(
        self,
        message: str,
        *,
        reason_name: str | None = None,
        stage: str | None = None,
        step_index: int | None = None,
        time_reached: float | None = None,
        time_tried: float | None = None,
        result: SolveResult | None = None,
    ) -> None:
        super().__init__(message)
        self.reason_name = reason_name
        self.stage = stage
        self.step_index = step_index
        self.time_reached = time_reached
        self.time_tried = time_tried
        self.result = result


def _reason_names(reasons) -> dict[int, str]:
    names: dict[int, str] = {}
    for name in sorted(vars(reasons)):
        value = getattr(reasons, name)
        if name.startswith("_") or not isinstance(value, int):
            continue
        # CONVERGED_ITERATING and ITERATING share 0; keep the first in sorted order.
        names.setdefault(value, name)
    return names


_REASON_NAMES = _reason_names(PETSc.SNES.ConvergedReason)
_KSP_REASON_NAMES = _reason_names(PETSc.KSP.ConvergedReason)


def snes_reason_name(reason: int) -> str:
    """Return the name of a PETSc ``SNESConvergedReason``, e.g. -5 -> ``"DIVERGED_MAX_IT"``."""
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
        Seconds spent in :meth:`EnergyMinimizer.solve` on this rank.
    residual_history
        Residual norms from the initial guess to the last iterate.
    tangent
        Which tangent produced the result: ``"exact"``, ``"projected"``, or ``"exact+projected"``
        when some iterations fell back to the projected tangent (see
        :class:`~dolfinx_invertible.solvers.hyperelastic.HyperelasticProblem`).
    stage
        For a failed solve, the stage that failed: ``"linear solve"``, ``"line search"``,
        ``"stalled"`` (no progress over a window of iterations), ``"iteration cap"`` or
        ``"NaN"`` (:data:`STAGES`); ``None`` when converged.
    detail
        One sentence on why the solve stopped, e.g. which test converged or what failed.
    where
        For a failed solve, where its last iterate was worst: the node with the largest
        residual entry, what the energy terms report (a contact term: its closest surface
        pair, its bodies and its stiffness) and how often step limits capped the Newton steps
        (:meth:`~dolfinx_invertible.solvers.problem.EnergyProblem.locate`); empty when
        converged.
    linear_reason_name
        PETSc KSP converged reason of the last linear solve, e.g. ``"CONVERGED_RTOL"``.
    projected_iterations
        Newton iterations whose direction came from the projected tangent because the exact
        tangent's was not a descent direction or its linear solve failed.
    blended_iterations
        Of those, the iterations whose direction came from a blend K₊ + w (K − K₊) of the
        projected and the exact tangent that is still positive definite (see
        :class:`~dolfinx_invertible.solvers.minimizer.EnergyMinimizer`).
    tolerance
        The absolute residual tolerance this solve used (see
        :class:`~dolfinx_invertible.solvers.minimizer.EnergyMinimizer`).
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
    stage: str | None = None
    detail: str = ""
    where: str = ""
    linear_reason_name: str | None = None
    projected_iterations: int = 0
    blended_iterations: int = 0
    tolerance: float = 0.0
    svd_share: dict[str, float | None] = dataclasses.field(default_factory=dict)

    @classmethod
    def from_snes(
        cls,
        snes: PETSc.SNES,
        *,
        energy: float | None,
        wall_time: float,
        failure: tuple[int, str, str] | None,
        converged_detail: str | None,
        tolerance: float,
        projected_iterations: int,
        blended_iterations: int,
        where: str = "",
    ) -> SolveResult:
        """Return the result of a solve that ``snes`` has just finished.

        ``failure`` is (reason, stage, detail) where the minimiser ended the solve itself,
        ``converged_detail`` why it declared convergence where its own test did, ``where``
        where a failed solve's last iterate was worst.
        """
        reason = int(snes.getConvergedReason())
        converged = reason > 0
        norm = float(snes.getFunctionNorm())
        stage, detail = None, ""
        if failure is not None:
            _, stage, detail = failure
        elif not converged:
            stage, detail = "line search", f"SNES stopped with {snes_reason_name(reason)}"
        elif converged_detail is not None:
            detail = converged_detail
        else:
            detail = f"residual {norm:.3e} within the tolerance {max(tolerance, 0.0):.3e}"
        history, _ = snes.getConvergenceHistory()
        ksp_reason = snes.getKSP().getConvergedReason()
        return cls(
            converged=converged,
            reason=reason,
            reason_name=snes_reason_name(reason),
            newton_iterations=int(snes.getIterationNumber()),
            linear_iterations=int(snes.getLinearSolveIterations()),
            residual_norm=norm,
            energy=energy,
            wall_time=wall_time,
            residual_history=tuple(float(value) for value in history),
            stage=stage,
            detail=detail,
            where="" if converged else where,
            linear_reason_name=ksp_reason_name(ksp_reason) if ksp_reason != 0 else None,
            projected_iterations=projected_iterations,
            blended_iterations=blended_iterations,
            tolerance=tolerance,
        )

    def describe(self) -> str:
        """Return one line: the PETSc reason, and for a failure the stage and why."""
        if self.converged:
            return f"{self.reason_name} after {self.newton_iterations} Newton iterations"
        text = f"{self.stage} failed ({self.reason_name}"
        if self.linear_reason_name and self.stage == "linear solve":
            text += f", KSP {self.linear_reason_name}"
        text += f") after {self.newton_iterations} Newton iterations"
        text += f": {self.detail}" if self.detail else ""
        return text + (f"; where: {self.where}" if self.where else "")


def point_text(coordinates) -> str:
    """Return a point as the messages write it, e.g. ``(0.5, 0.25, -1)``."""
    return "(" + ", ".join(f"{value:.4g}" for value in coordinates) + ")"


def ksp_reason_name(reason: int) -> str:
    """Return the name of a PETSc ``KSPConvergedReason``, e.g. -3 -> ``"DIVERGED_ITS"``."""
    return _KSP_REASON_NAMES.get(int(reason), f"UNKNOWN_REASON_{int(reason)}")
