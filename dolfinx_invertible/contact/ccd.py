"""Continuous collision detection of points moving on straight paths against rigid obstacles.

Along a Newton step every boundary point moves on a straight path x + α p, α ∈ [0, 1]. For each
shape the first α at which the gap reaches zero is the first positive root of a polynomial of
degree at most two in α (a plane: linear; a sphere, cylinder or cone: quadratic, see the shapes'
modules), which :func:`first_crossing` finds in closed form. :func:`collision_free_step` turns
the first crossings into a step: ``fraction`` of the first crossing, at most 1, so that the gap
of every point stays positive at every step the line search may try.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from dolfinx_invertible.contact.scene import Scene

__all__ = ["collision_free_step", "first_crossing"]


def first_crossing(c0: ArrayLike, c1: ArrayLike, c2: ArrayLike) -> np.ndarray:
    """First α > 0 where c₀ + c₁α + c₂α² falls to 0, elementwise, given c₀ > 0; else inf.

    With c₀ > 0 the first positive root, when there is one, is 2c₀ / (−c₁ + √(c₁² − 4c₀c₂))
    in all cases (c₂ of either sign or zero): this form of the smaller root does not cancel.
    A non-positive denominator or a negative discriminant means no positive root.
    """
    c0 = np.asarray(c0, dtype=np.float64)
    c1 = np.asarray(c1, dtype=np.float64)
    c2 = np.asarray(c2, dtype=np.float64)
    discriminant = c1 * c1 - 4.0 * c0 * c2
    root = np.sqrt(np.maximum(discriminant, 0.0))
    denominator = -c1 + root
    crossing = discriminant >= 0.0
    crossing &= denominator > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        alpha = np.where(crossing, 2.0 * c0 / np.where(crossing, denominator, 1.0), math.inf)
    return np.atleast_1d(alpha)


def collision_free_step(
    scene: Scene, positions: np.ndarray, direction: np.ndarray, t: float, *, fraction: float = 0.9
) -> float:
    """Largest α ≤ 1 for the motion ``positions + α · direction`` against ``scene`` at time t.

    The step is ``fraction`` times the first crossing of any point with any obstacle, capped
    at 1; it is 0 if some point is not outside an obstacle to begin with. For a plane the gap
    is linear along the path, so the gap left at the step is at least 1 − ``fraction`` of the
    current gap; for the curved shapes it is positive too (the step is short of the first root).

    Parameters
    ----------
    scene
        A :class:`~dolfinx_invertible.contact.scene.Scene`.
    positions, direction
        Current positions and their motion per unit step, (n, d).
    t
        Time at which the obstacles are evaluated.
    fraction
        Share of the first crossing that the step may reach, in (0, 1).
    """
    if not (0.0 < fraction < 1.0):
        raise ValueError(f"fraction must lie in (0, 1), got {fraction!r}")
    if len(positions) == 0:
        return 1.0
    crossing = scene.first_crossing(positions, direction, t)
    first = float(np.min(crossing))
    return min(1.0, fraction * first)
