"""The minimiser's convergence test: tolerances scaled to the problem, a budget by progress.

A solve is converged when the residual norm (Dirichlet rows included, as SNES measures it) is at
most ``max(atol, rtol · ‖r₀‖)``. ``rtol`` is ``snes_rtol``; ``atol`` is ``snes_atol`` where given
and otherwise scaled to the problem: the residual that a displacement of η times the mean cell
size h on every free dof would produce through the diagonal of the tangent, ``η · h · k · √n``,
with k the typical (median) magnitude of a free diagonal entry of the last tangent and n the
number of free dofs. It scales with the stiffness, the density (through the mass of a dynamic
step) and hence with the loads, so a problem whose material, density and loads are all scaled by
one factor takes the same iterations, and a solve that starts at a solution takes none. The same
scales bound the rounding error of the energy, which the line search needs to tell progress from
noise.

A solve's budget is its progress, not a count: it goes on while the residual or the energy keeps
falling, and stops early, at the stage ``"stalled"``, once over the last :data:`STALL_WINDOW`
iterations the smallest residual so far has not halved and the energy has fallen by less than
:data:`STALL_ENERGY` of its magnitude (above its rounding error): a step that cannot be taken
is then cut after a few dozen iterations. ``snes_max_it`` stays as a safeguard, far above what
a converging solve needs (default 200: with the trust region's boundary steps, the collapse at
32³ × 6 cells converged its first step in 89–132 iterations, its energy falling all the way).
A solve that is still descending is never
stopped by the progress test: how long a crawl through a non-convex energy lasts does not show in
its rates (the same solve's last three iterations take the residual from 4e-3 to 2e-6).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from petsc4py import PETSc

from dolfinx_invertible import _compat
from dolfinx_invertible.fem.checks import mean_cell_size

__all__ = ["STALL_ENERGY", "STALL_WINDOW", "ConvergenceTest", "ScaledTolerances"]

_REASONS = PETSc.SNES.ConvergedReason

# The rounding error of an energy (a sum over cells of sums over quadrature points of terms that
# may cancel) in units of ε times its scale; generous, so that noise is never taken for progress.
_ROUNDING = 100.0 * np.finfo(np.float64).eps

#: Iterations over which a solve must make progress (the progress test of :class:`ConvergenceTest`).
STALL_WINDOW = 20
#: The relative fall of the energy over :data:`STALL_WINDOW` iterations that counts as progress.
STALL_ENERGY = 1.0e-7


class ScaledTolerances:
    """The absolute residual tolerance and the energy's rounding error of a problem.

    Parameters
    ----------
    problem
        The :class:`~dolfinx_invertible.solvers.problem.EnergyProblem`.
    displacement_tolerance
        η of the absolute tolerance, relative to the mean cell size.
    absolute_tolerance
        A fixed absolute tolerance (the user's ``snes_atol``) instead of the scaled one.
    assemble_tangent
        Assembles the tangent at the current iterate (and reports it through
        :meth:`record_stiffness`); called when a scale is needed before any tangent was.
    """

    def __init__(
        self,
        problem,
        *,
        displacement_tolerance: float,
        absolute_tolerance: float | None,
        assemble_tangent: Callable[[], None],
    ) -> None:
        if not (math.isfinite(displacement_tolerance) and displacement_tolerance > 0.0):
            raise ValueError(
                f"displacement_tolerance must be a number > 0, got {displacement_tolerance!r}"
            )
        self.problem = problem
        self.displacement_tolerance = float(displacement_tolerance)
        self.fixed = None if absolute_tolerance is None else float(absolute_tolerance)
        self._assemble_tangent = assemble_tangent
        self._cell_size = mean_cell_size(problem.u.function_space.mesh)
        self._diagonal = problem.create_vector()
        self._stiffness: tuple[float, int] | None = None  # typical |K_ii|, free dofs

    def record_stiffness(self, matrix: PETSc.Mat) -> None:
        """Take the stiffness scale from an assembled tangent.

        The typical magnitude of a free diagonal entry: a median, because the exact tangent can
        carry a few huge entries (near the kink σᵢ + σⱼ = 0 of an inverted element) that say
        nothing about the stiffness of the body.
        """
        matrix.getDiagonal(self._diagonal)
        local = np.abs(self._diagonal.getArray(readonly=True)[self.problem.free_owned])
        median = float(np.median(local)) if len(local) else 0.0
        comm = self.problem.comm
        count = comm.allreduce(len(local))
        typical = comm.allreduce(median * len(local)) / max(count, 1)
        self._stiffness = (typical, count)

    def stiffness_scale(self) -> tuple[float, int]:
        """Return the typical free diagonal entry of the tangent and the number of free dofs."""
        if self._stiffness is None:
            self._assemble_tangent()
        return self._stiffness

    def absolute_tolerance(self) -> float:
        """Return the absolute residual tolerance in effect."""
        if self.fixed is not None:
            return self.fixed
        typical, count = self.stiffness_scale()
        return self.displacement_tolerance * self._cell_size * typical * math.sqrt(count)

    def energy_rounding(self, terms: np.ndarray) -> float:
        """Return an estimate of the rounding error of Π given its terms.

        ε times the terms' magnitudes and the energy scale of a one-cell-size deformation,
        h² · (typical diagonal entry) · (free dofs), which bounds the cancellation inside the
        energy density even where Π itself is near zero (a body at rest).
        """
        typical, count = self.stiffness_scale()
        scale = float(np.sum(np.abs(terms))) + self._cell_size**2 * typical * count
        return _ROUNDING * scale


class ConvergenceTest:
    """SNES's convergence test of the minimiser, and the outcome of the solve so far.

    Besides the residual test it ends a solve that the minimiser has declared failed (a linear
    solve or line search that failed) or converged (nothing left to gain above round-off), a
    residual that is not finite, a solve that has stalled (see the module description) and a
    solve at the iteration cap.

    Parameters
    ----------
    tolerances
        The :class:`ScaledTolerances` of the problem.

    Attributes
    ----------
    failure
        (SNES reason, stage, detail) of a failed solve, else ``None``.
    converged_detail
        Why the minimiser declared convergence itself, else ``None``.
    tolerance
        The absolute residual tolerance of the current solve.
    window
        The iterations of the progress test (``None`` turns it off); :data:`STALL_WINDOW`.
    """

    def __init__(self, tolerances: ScaledTolerances) -> None:
        self.tolerances = tolerances
        self.window: int | None = STALL_WINDOW
        self.start_solve()

    def start_solve(self) -> None:
        """Begin a solve: nothing failed, no tolerance yet."""
        self.failure: tuple[int, str, str] | None = None
        self.converged_detail: str | None = None
        self.tolerance = 0.0
        self._initial_norm = math.inf
        #: The smallest residual norm so far after each iteration, and the energy there.
        self._best: list[float] = []
        self._energies: list[float | None] = []

    def fail(self, reason: int, stage: str, detail: str) -> None:
        """End the solve as failed at ``stage`` (one of the stages of a SolveResult)."""
        self.failure = (reason, stage, detail)

    def converge(self, detail: str) -> None:
        """End the solve as converged, for the reason ``detail``."""
        self.converged_detail = detail

    def check(
        self,
        iteration: int,
        norm: float,
        snes: PETSc.SNES,
        reject: Callable[[], bool],
        energy: float | None = None,
        rounding: float = 0.0,
    ) -> int:
        """Return SNES's converged reason after ``iteration`` with residual norm ``norm``.

        ``reject()`` may veto a residual that passed (it is asked only then); ``energy`` is Π at
        the iterate where known, ``rounding`` its rounding error (for the progress test).
        """
        if self.failure is not None:
            return self.failure[0]
        if self.converged_detail is not None:
            return _REASONS.CONVERGED_SNORM_RELATIVE
        if not math.isfinite(norm):
            self.fail(_compat.SNES_DIVERGED_NOT_FINITE, "NaN", "the residual is not finite")
            return _compat.SNES_DIVERGED_NOT_FINITE
        if iteration == 0:
            self._initial_norm = norm
            self.tolerance = self.tolerances.absolute_tolerance()
        rtol, _, _, max_it = snes.getTolerances()
        passed = None
        if norm <= self.tolerance:
            passed = _REASONS.CONVERGED_FNORM_ABS
        elif iteration > 0 and norm <= rtol * self._initial_norm:
            passed = _REASONS.CONVERGED_FNORM_RELATIVE
        if passed is not None and not reject():
            return passed
        self._best.append(min(norm, self._best[-1]) if self._best else norm)
        self._energies.append(energy)
        stalled = self._stalled(rounding)
        if stalled is not None:
            self.fail(_REASONS.DIVERGED_MAX_IT, "stalled", stalled)
            return _REASONS.DIVERGED_MAX_IT
        if iteration >= max_it:
            self.fail(
                _REASONS.DIVERGED_MAX_IT,
                "iteration cap",
                f"residual {norm:.3e} above the tolerance {self.tolerance:.3e} after "
                f"{max_it} iterations",
            )
            return _REASONS.DIVERGED_MAX_IT
        return _REASONS.ITERATING

    def _stalled(self, rounding: float) -> str | None:
        """Why the solve has made no progress over the last window, or ``None`` if it has."""
        window = self.window
        if window is None or len(self._best) <= window:
            return None
        before, now = self._best[-1 - window], self._best[-1]
        if now < 0.5 * before:
            return None
        energies = self._energies[-1 - window :]
        if energies[0] is None or energies[-1] is None:
            return None  # no energy to judge by (stress-only, a watchdog's tentative step)
        fall = energies[0] - energies[-1]
        if fall > max(STALL_ENERGY * abs(energies[-1]), rounding):
            return None
        return (
            f"no progress over the last {window} iterations: the smallest residual only "
            f"from {before:.3e} to {now:.3e} (tolerance {self.tolerance:.3e}), the energy "
            f"fell by {fall:.3e}"
        )
