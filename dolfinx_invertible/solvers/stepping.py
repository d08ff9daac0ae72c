"""Quasi-static load stepping over a pseudo-time in (0, 1], cutting the increment on failure."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

import dolfinx.fem
import numpy as np

from dolfinx_invertible import _compat
from dolfinx_invertible.solvers.results import SolverError, SolveResult

__all__ = ["Solvable", "solve_load_steps"]


class Solvable(Protocol):
    """What a stepping loop drives: a solve from the current state of ``u``.

    :class:`~dolfinx_invertible.solvers.newton.EnergyMinimizer` and
    :class:`~dolfinx_invertible.solvers.hyperelastic.HyperelasticProblem` are both.
    """

    u: dolfinx.fem.Function

    def solve(self) -> SolveResult:
        """Solve from the current ``u``; on failure ``u`` keeps its value."""
        ...


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
    if any(later <= earlier for earlier, later in zip(targets[:-1], targets[1:], strict=True)):
        raise ValueError(f"steps: pseudo-times must increase strictly, got {targets}")
    if targets[-1] != 1.0:
        raise ValueError(f"steps: the last pseudo-time must be 1, got {targets[-1]}")
    return targets


def solve_load_steps(
    solver: Solvable,
    update_load: Callable[[float], None],
    steps: int | Sequence[float],
    *,
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
        An :class:`~dolfinx_invertible.solvers.newton.EnergyMinimizer` or a
        :class:`~dolfinx_invertible.solvers.hyperelastic.HyperelasticProblem`
        (any :class:`Solvable`); its ``u`` holds the state at t = 0 on entry.
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

    u = solver.u
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
