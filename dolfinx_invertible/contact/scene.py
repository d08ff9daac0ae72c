"""A scene: several rigid obstacles that a body must stay clear of at once."""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np
from numpy.typing import ArrayLike

from dolfinx_invertible.contact.obstacle import Obstacle

__all__ = ["Scene"]


class Scene:
    """An ordered collection of obstacles of one dimension, evaluated together at a time t.

    Parameters
    ----------
    obstacles
        One :class:`~dolfinx_invertible.contact.obstacle.Obstacle`, several, or a Scene
        (whose obstacles are taken over).
    """

    def __init__(self, obstacles: Obstacle | Sequence[Obstacle] | Scene) -> None:
        if isinstance(obstacles, Scene):
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
            raise ValueError("obstacles: a scene needs at least one obstacle")
        for index, obstacle in enumerate(obstacles):
            if not isinstance(obstacle, Obstacle):
                raise ValueError(f"obstacles[{index}] is not an Obstacle: {obstacle!r}")
        dimensions = {obstacle.dimension for obstacle in obstacles}
        if len(dimensions) != 1:
            raise ValueError(f"obstacles of different dimensions in one scene: {dimensions}")
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

    def first_crossing(self, x: ArrayLike, direction: ArrayLike, t: float = 0.0) -> np.ndarray:
        """First α > 0 at which ``x + α · direction`` reaches any obstacle: shape (n,)."""
        x = np.asarray(x, dtype=np.float64)
        if len(x) == 0:
            return np.zeros(0)
        crossings = [obstacle.first_crossing(x, direction, t) for obstacle in self.obstacles]
        return np.min(np.stack(crossings), axis=0)

    def __repr__(self) -> str:
        return f"Scene({self.obstacles!r})"
