"""Several rigid obstacles that a body must stay clear of at once, and the collision-free step.

Along a Newton step every boundary point moves on a straight path x + α p, α ∈ [0, 1].
:meth:`Obstacles.path_crossing` gives the first α at which each point reaches any obstacle
(every shape finds its own crossing in closed form), and :meth:`Obstacles.collision_free_step`
turns these into a step: ``fraction`` of the first crossing, at most 1, so that the gap of every
point stays positive at every step the line search may try.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np
from numpy.typing import ArrayLike

from dolfinx_invertible.contact.obstacle import Obstacle

__all__ = ["Obstacles"]


class Obstacles:
    """An ordered collection of obstacles of one dimension, evaluated together at a time t.

    Parameters
    ----------
    obstacles
        One :class:`~dolfinx_invertible.contact.obstacle.Obstacle`, several, or an Obstacles
        (whose obstacles are taken over).

    Attributes
    ----------
    obstacles
        The obstacles, a list.
    dimension
        Their dimension, 2 or 3.
    """

    def __init__(self, obstacles: Obstacle | Sequence[Obstacle] | Obstacles) -> None:
        if isinstance(obstacles, Obstacles):
            obstacles = obstacles.obstacles
        elif isinstance(obstacles, Obstacle):
            obstacles = [obstacles]
        try:
            obstacles = list(obstacles)
        except TypeError:
            raise ValueError(
                f"obstacles: expected an Obstacle or a sequence of them, got {obstacles!r}"
            ) from None
        if not obstacles:
            raise ValueError("obstacles: at least one obstacle is needed")
        for index, obstacle in enumerate(obstacles):
            if not isinstance(obstacle, Obstacle):
                raise ValueError(f"obstacles[{index}] is not an Obstacle: {obstacle!r}")
        dimensions = {obstacle.dimension for obstacle in obstacles}
        if len(dimensions) != 1:
            raise ValueError(f"obstacles of different dimensions together: {dimensions}")
        self.obstacles = obstacles
        self.dimension = dimensions.pop()

    def __len__(self) -> int:
        return len(self.obstacles)

    def __iter__(self) -> Iterator[Obstacle]:
        return iter(self.obstacles)

    def __getitem__(self, index: int) -> Obstacle:
        return self.obstacles[index]

    def gaps(self, x: ArrayLike, t: float = 0.0) -> np.ndarray:
        """Return the gap of every point ``x`` (n, d) to every obstacle: shape (obstacles, n)."""
        x = np.asarray(x, dtype=np.float64)
        if len(x) == 0:
            return np.zeros((len(self), 0))
        return np.stack([obstacle.gap(x, t) for obstacle in self.obstacles])

    def path_crossing(self, x: ArrayLike, direction: ArrayLike, t: float = 0.0) -> np.ndarray:
        """First α > 0 at which ``x + α · direction`` reaches any obstacle: shape (n,).

        ``inf`` where the path reaches none, 0 where the point is not outside all of them.
        """
        x = np.asarray(x, dtype=np.float64)
        if len(x) == 0:
            return np.zeros(0)
        crossings = [obstacle.path_crossing(x, direction, t) for obstacle in self.obstacles]
        return np.min(np.stack(crossings), axis=0)

    def collision_free_step(
        self, positions: np.ndarray, direction: np.ndarray, t: float, *, fraction: float = 0.9
    ) -> float:
        """Largest α ≤ 1 for the motion ``positions + α · direction`` at time t.

        The step is ``fraction`` times the first crossing of any point with any obstacle,
        capped at 1; it is 0 if some point is not outside an obstacle to begin with. For a plane
        the gap is linear along the path, so the gap left at the step is at least
        1 − ``fraction`` of the current gap; for the curved shapes it is positive too (the step
        is short of the first root).

        Parameters
        ----------
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
        crossing = self.path_crossing(positions, direction, t)
        first = float(np.min(crossing))
        return min(1.0, fraction * first)

    def __repr__(self) -> str:
        return f"Obstacles({self.obstacles!r})"
