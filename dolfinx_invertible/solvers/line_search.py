"""The energy line search: backtracking on Π with a watchdog for Newton's full steps.

A step along the Newton direction is accepted when Π decreases by the Armijo amount
(``sufficient_decrease`` times the exact directional derivative; the full step whenever it
qualifies). Where the change of Π is below Π's own rounding error, the residual decides
instead: the step is accepted if it reduces the residual norm, unless a longer step of the same
direction raised Π by more than that error (the direction then ascends). If no step of up to
``max_backtracks`` halvings qualifies, the search fails, unless the predicted decrease itself is
below rounding, in which case the iterate is converged as far as floating point can tell.

A watchdog (Chamberlain et al. 1982) lets Newton take the full step when the energy test
rejects it but Newton is about to converge anyway: a full step to a finite energy that fails the
test is taken tentatively, and so are up to ``watchdog_steps`` more; as soon as an iterate's
energy is below the origin's by the Armijo amount, the watch ends. If none is, the search goes
back to the origin and backtracks from there (once per solve; later steps backtrack directly).
So a step plain Newton takes is taken, and the energy still decreases over every watch.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
from petsc4py import PETSc

__all__ = ["EnergyLineSearch", "SearchStop"]


@dataclasses.dataclass(frozen=True)
class SearchStop:
    """Why the line search ended the solve: converged at round-off, or failed."""

    converged: bool
    detail: str


@dataclasses.dataclass
class _Watch:
    """The iterate before tentative full Newton steps, to go back to if they do not pay off."""

    energy: float
    slope: float  # −(directional derivative) of the full step from the origin
    residual_norm: float
    remaining: int  # further full steps allowed before the energy must be below the origin's


class EnergyLineSearch:
    """Backtracking on the energy of an energy problem, with a watchdog.

    Steps are ``x → x − y`` for a Newton direction ``y`` (SNES's sign convention); the search
    scales ``y`` in place to the accepted step.

    Parameters
    ----------
    problem
        The :class:`~dolfinx_invertible.solvers.problem.EnergyProblem`.
    rounding
        ``rounding(terms)`` estimates the rounding error of Π from its terms.
    sufficient_decrease
        Armijo constant.
    max_backtracks
        Halvings of the step before the search gives up.
    watchdog_steps
        Tentative full steps after the first before the energy must have decreased; 0 turns
        the watchdog off.

    Attributes
    ----------
    full_step
        Whether the last step taken was a full Newton step.
    fraction
        The fraction of the Newton direction the last decision took (0 where the solve stops;
        after a failed watch, the fraction of the watch's first direction from its origin).
    decrease
        Π's decrease over the last step :meth:`backtrack` accepted (0 where it failed).
    rounding_error
        The rounding error of Π at the origin of that step.
    """

    def __init__(
        self,
        problem,
        *,
        rounding: Callable[[np.ndarray], float],
        sufficient_decrease: float = 1.0e-4,
        max_backtracks: int = 30,
        watchdog_steps: int = 2,
    ) -> None:
        if int(watchdog_steps) != watchdog_steps or watchdog_steps < 0:
            raise ValueError(f"watchdog_steps must be an integer >= 0, got {watchdog_steps!r}")
        self.problem = problem
        self.rounding = rounding
        self.sufficient_decrease = float(sufficient_decrease)
        self.max_backtracks = int(max_backtracks)
        self.watchdog_steps = int(watchdog_steps)
        self._trial = problem.create_vector()
        self._work = problem.create_vector()
        self._origin = problem.create_vector()
        self._origin_direction = problem.create_vector()
        self._energy_point = problem.create_vector()
        self.start_solve()

    def start_solve(self) -> None:
        """Forget the previous solve: no watch, no energy evaluated."""
        self.full_step = True
        self.fraction = 1.0
        self._watch: _Watch | None = None
        self._watch_spent = False  # after one failed watch, a solve backtracks monotonically
        self._last_energy: tuple[float, np.ndarray] | None = None
        self.decrease = 0.0
        self.rounding_error = 0.0

    @property
    def watching(self) -> bool:
        """Whether the current iterate was reached by tentative full steps."""
        return self._watch is not None

    def energy_at(self, vector: PETSc.Vec) -> tuple[float, np.ndarray]:
        """Return Π and its terms at ``vector`` (+inf where Π is not finite)."""
        # The search ends on the point it accepted, and SNES steps there: the next iteration
        # starts from the energy evaluated last (within a solve, Π depends on u only).
        if self._last_energy is not None and vector.equal(self._energy_point):
            return self._last_energy
        self.problem.update_solution(vector)
        terms = self.problem.energy_terms()
        total = float(np.sum(terms))
        self._last_energy = (total if math.isfinite(total) else math.inf), terms
        vector.copy(self._energy_point)
        return self._last_energy

    def known_energy(self, vector: PETSc.Vec) -> float | None:
        """Return Π at ``vector`` if the search has evaluated it there last, else ``None``."""
        if self._last_energy is not None and vector.equal(self._energy_point):
            return self._last_energy[0]
        return None

    def backtrack(self, x: PETSc.Vec, y: PETSc.Vec, residual: PETSc.Vec) -> SearchStop | None:
        """Shorten ``y`` until the energy test passes at ``x − y``.

        ``residual`` is the residual at ``x``. Sets :attr:`full_step` to whether the full step
        passed (and was full to begin with); returns why the solve must stop, if it must (``y``
        is then zero).
        """
        start, terms = self.energy_at(x)
        watch = self.watchdog_steps > 0 and not self._watch_spent and self.full_step
        slope = residual.dot(y)
        self.rounding_error = self.rounding(terms)
        self.decrease = 0.0
        step = self._search(x, y, start, terms, slope, residual.norm(), watch=watch)
        if step is not None:
            self.decrease = start - self._last_energy[0]
        if step is None:
            self.full_step = False
            self.fraction = 0.0
            return self._search_failed(y, residual.dot(y), terms)
        self.full_step = self.full_step and step == 1.0
        self.fraction = step
        return None

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
        but has finite energy starts a watch and is taken.
        """
        rounding = self.rounding(terms)
        fraction = 1.0
        # Once a longer step of this direction raised Π by more than its rounding error, the
        # direction ascends as far as Π can tell, and a shorter step whose change is lost in
        # the rounding is no progress: the residual test is not asked then. Asked, it accepts
        # steps ever closer to noise wherever Π and the residual disagree along the direction
        # (a kink of Π; directions that moved clamped nodes did, docs/performance.md, the
        # stretch bar at 16), and the iterates creep uphill at round-off until the progress
        # test stops them.
        rose = False
        for _ in range(self.max_backtracks + 1):
            decrease = fraction * slope
            self._trial.waxpy(-1.0, y, x)
            energy, _ = self.energy_at(self._trial)
            if energy <= start - self.sufficient_decrease * decrease:
                return fraction
            if abs(energy - start) <= rounding and not rose:
                self.problem.F(None, self._trial, self._work)
                if self._work.norm() < residual_norm:
                    return fraction
            rose = rose or (math.isfinite(energy) and energy - start > rounding)
            if watch and fraction == 1.0 and math.isfinite(energy):
                x.copy(self._origin)
                y.copy(self._origin_direction)
                self._watch = _Watch(start, slope, residual_norm, self.watchdog_steps)
                return fraction
            y.scale(0.5)
            fraction *= 0.5
        y.scale(1.0 / fraction)
        return None

    def _search_failed(self, y: PETSc.Vec, slope: float, terms: np.ndarray) -> SearchStop:
        """No step passed: converged at round-off if even the predicted decrease is below it."""
        y.set(0.0)  # SNES then stays at x, and the convergence test ends the solve
        if 0.5 * slope <= self.rounding(terms):
            return SearchStop(
                converged=True,
                detail="the predicted energy decrease is below the energy's rounding error and "
                "no step reduces the residual: converged as far as floating point resolves",
            )
        return SearchStop(
            converged=False,
            detail=f"no step down to {0.5**self.max_backtracks:.1e} of the Newton step "
            "decreases the energy",
        )

    def watch_paid_off(self, x: PETSc.Vec) -> bool:
        """Whether Π at ``x`` is below the watch's origin by the Armijo amount."""
        watch = self._watch
        energy, _ = self.energy_at(x)
        return energy <= watch.energy - self.sufficient_decrease * watch.slope

    def end_watch_at_stationary_point(self) -> None:
        """No further tentative steps: the iterate is stationary but above the origin's energy."""
        self._watch.remaining = 0

    def watched_step(
        self,
        x: PETSc.Vec,
        y: PETSc.Vec,
        usable: bool,
        replaceable: bool,
        largest_step: Callable[[PETSc.Vec], float],
    ) -> tuple[bool, SearchStop | None]:
        """At a tentative iterate ``x``: end the watch, take another full step or go back.

        ``usable`` says whether the direction ``y`` is a descent direction, ``replaceable``
        whether a bad one can be replaced; ``largest_step(y)`` is the step limits' cap. Returns
        whether the step ``y`` is decided (otherwise the iteration goes on as usual), and why
        the solve must stop, if it must.
        """
        watch = self._watch
        paid_off = self.watch_paid_off(x)
        # Where the exact tangent gives no descent and nothing can replace it, the watch led
        # somewhere the monotone search would not have gone: go back.
        if paid_off and (usable or replaceable):
            self._watch = None
            return False, None
        if not paid_off and usable and watch.remaining > 0 and largest_step(y) == 1.0:
            self._trial.waxpy(-1.0, y, x)
            energy, _ = self.energy_at(self._trial)
            if math.isfinite(energy):
                watch.remaining -= 1
                self.full_step = True
                self.fraction = 1.0
                return True, None
        # Back to the origin, and backtrack from there along its direction (the full step
        # having failed, from half of it).
        self._watch = None
        self._watch_spent = True
        self.full_step = False
        origin, direction = self._origin, self._origin_direction
        start, terms = self.energy_at(origin)
        direction.scale(0.5)
        fraction = self._search(
            origin, direction, start, terms, 0.5 * watch.slope, watch.residual_norm
        )
        stop = None
        self.fraction = 0.0 if fraction is None else 0.5 * fraction
        if fraction is None:
            stop = self._search_failed(direction, 0.5 * watch.slope, terms)
            if not stop.converged:
                y.set(0.0)
                return True, stop
        # SNES steps to x − y: make that the accepted point origin − direction (the origin
        # itself where the search converged there).
        y.waxpy(-1.0, origin, x)
        y.axpy(1.0, direction)
        return True, stop
