"""A trust region around the iterative path's Newton steps (Steihaug–Toint).

With ``globalization="trust-region"`` (and ``"auto"``, the default, wherever the iterative path runs
conjugate gradients on an energy) every Newton direction comes from conjugate gradients on the exact
tangent K, bounded by a radius Δ in the AMG preconditioner's norm
(:class:`~dolfinx_invertible.solvers.truncated_cg.TruncatedCG`): where CG meets negative curvature
the step follows it to the boundary instead of dropping it, as the projected tangent does. The
energy line search still guards every step (Armijo on the accepted length), and the radius follows
how well Newton's quadratic model predicted the energy's decrease:

    ρ = (Π(x) − Π(x − s)) / (rᵀs − ½ sᵀKs)

for the step s taken. The radius halves to the step's length where ρ < 1/4, doubles where ρ > 3/4
and the full step ended on the boundary, and shrinks to the step's length where the line search
shortened it. A step limit's cap (continuous collision detection stopping the step before two
surfaces meet) says where the step must end, not how far the model holds, and leaves the radius:
shrunk to every capped length, the radius would keep the next iterations as short as the
closest pending contact made this one, long after the contact has entered the barrier. A solve
starts without a bound: its first direction is the exact (or, at negative curvature, the
projected) Newton direction, and its length, as far as the line search accepted it, sets Δ.

Where the projected tangent drops all of a cell's negative curvature, Newton on it converges
linearly along a valley of the energy (docs/performance.md, "Scale"): a trust region uses the
curvature instead and bounds the step where the model fails (Conn, Gould and Toint, *Trust-Region
Methods*, 2000, ch. 6–7; Steihaug 1983).
"""

from __future__ import annotations

import math

__all__ = ["TrustRegion", "agreement"]


def agreement(actual: float, predicted: float, rounding: float) -> float:
    """ρ: the energy's actual decrease over a step against its quadratic model's prediction.

    1 where both are below the energy's rounding error (they then say nothing), −∞ where the
    model predicted no decrease.
    """
    if abs(actual) <= rounding and abs(predicted) <= rounding:
        return 1.0
    return actual / predicted if predicted > 0.0 else -math.inf


class TrustRegion:
    """The radius of the trust region and its update from each step's agreement with the model.

    Attributes
    ----------
    radius
        Δ in the preconditioner's norm; ``math.inf`` until a solve's first step is taken.
    ratio
        ρ of the last step (``nan`` before the first).
    """

    #: Below this ρ the radius shrinks.
    SHRINK_BELOW = 0.25
    #: Above this ρ a full step on the boundary doubles the radius.
    GROW_ABOVE = 0.75

    def __init__(self) -> None:
        self.start_solve()

    def start_solve(self) -> None:
        """Begin a solve without a bound."""
        self.radius = math.inf
        self.ratio = math.nan

    def update(
        self,
        *,
        fraction: float,
        cap: float = 1.0,
        step_norm: float,
        boundary: bool,
        actual: float,
        predicted: float,
        rounding: float,
    ) -> None:
        """Adapt the radius after a step of ``fraction`` of a direction.

        Parameters
        ----------
        fraction
            The share of the direction taken (the step limits' cap times the line search's).
        cap
            The step limits' share alone (1 where no limit capped the step).
        step_norm
            The direction's norm in the preconditioner's norm (``nan`` where unknown: the radius
            is then left as it is).
        boundary
            Whether the direction ended on the trust region's boundary.
        actual, predicted
            The energy's decrease over the step and the quadratic model's (of the tangent the
            direction came from).
        rounding
            The energy's rounding error: below it the decreases say nothing, and ρ counts as 1.
        """
        self.ratio = agreement(actual, predicted, rounding)
        if not (math.isfinite(step_norm) and step_norm > 0.0 and fraction > 0.0):
            return
        length = fraction * step_norm
        if fraction < cap:  # the line search shortened the step: the model held only so far
            self.radius = length
        elif not math.isfinite(self.radius):
            self.radius = length / cap
        reached = boundary or length >= self.radius
        if self.ratio < self.SHRINK_BELOW:
            self.radius = 0.5 * length
        elif self.ratio > self.GROW_ABOVE and fraction == 1.0 and reached:
            self.radius = 2.0 * length
