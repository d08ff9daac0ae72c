"""What a nonlinear solve reports (:class:`SolveResult`), and the error when stepping gives up."""

from __future__ import annotations

import dataclasses

from petsc4py import PETSc

__all__ = ["SolveResult", "SolverError", "snes_reason_name"]


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
        Which tangent produced the result, where a caller chooses: ``"exact"`` or
        ``"projected"`` (see :class:`~dolfinx_invertible.solvers.hyperelastic.HyperelasticProblem`).
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
