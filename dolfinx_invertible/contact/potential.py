"""The barrier potential of a weighted point set against rigid obstacles, with an SPD Hessian.

    E(x₁, …, xₙ) = Σᵢ wᵢ Σₒ b(dₒ(xᵢ, t)),

with wᵢ a point's share of the boundary, dₒ the gap to obstacle o and b the
:class:`~dolfinx_invertible.contact.barrier.Barrier`. Each point's gradient and Hessian are

    gᵢ = wᵢ Σₒ b′(dₒ) ∇dₒ,    Hᵢ = wᵢ Σₒ (b″(dₒ) ∇dₒ ∇dₒᵀ + b′(dₒ) ∇²dₒ).

b″ ≥ 0 and b′ ≤ 0, so the first part is positive semidefinite and the second is so where the
obstacle curves away from the body (∇²d ≤ 0: inside a bowl, tube or cone; zero for a plane)
and not where it bulges towards it (a ball, a roller). The projected Hessian replaces each
point's d × d block by its positive part V max(Λ, 0) Vᵀ.

A point on or inside an obstacle (d ≤ 0) has no barrier value: the energy is +∞ there and the
gradient NaN, so a solver that starts from, or is given, such a state fails visibly.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from dolfinx_invertible.contact.barrier import Barrier
from dolfinx_invertible.contact.obstacle import Obstacle
from dolfinx_invertible.contact.obstacles import Obstacles

__all__ = ["BarrierPotential", "project_blocks"]


def project_blocks(blocks: np.ndarray) -> np.ndarray:
    """Return the positive parts of symmetric d × d blocks (k, d, d): V max(Λ, 0) Vᵀ."""
    if len(blocks) == 0:
        return blocks.copy()
    symmetric = 0.5 * (blocks + np.swapaxes(blocks, 1, 2))
    values, vectors = np.linalg.eigh(symmetric)
    return (vectors * np.maximum(values, 0.0)[:, None, :]) @ np.swapaxes(vectors, 1, 2)


class BarrierPotential:
    """Σᵢ wᵢ Σₒ b(dₒ(xᵢ, t)) over points xᵢ (n, d) with weights wᵢ (n,).

    Parameters
    ----------
    obstacles
        The :class:`~dolfinx_invertible.contact.obstacles.Obstacles`, or what it accepts.
    barrier
        The :class:`~dolfinx_invertible.contact.barrier.Barrier`.
    """

    def __init__(
        self, obstacles: Obstacles | Obstacle | Sequence[Obstacle], barrier: Barrier
    ) -> None:
        self.obstacles = Obstacles(obstacles)
        if not isinstance(barrier, Barrier):
            raise ValueError(f"barrier must be a Barrier, got {barrier!r}")
        self.barrier = barrier

    def _check(self, positions, weights) -> tuple[np.ndarray, np.ndarray]:
        positions = np.asarray(positions, dtype=np.float64)
        weights = np.asarray(weights, dtype=np.float64)
        if positions.ndim != 2 or positions.shape[1] != self.obstacles.dimension:
            raise ValueError(
                f"positions must have shape (n, {self.obstacles.dimension}), got {positions.shape}"
            )
        if weights.shape != (len(positions),):
            raise ValueError(f"weights must have shape ({len(positions)},), got {weights.shape}")
        return positions, weights

    def energy(self, positions: ArrayLike, weights: ArrayLike, t: float = 0.0) -> float:
        """Return E; +∞ if a point is on or inside an obstacle."""
        positions, weights = self._check(positions, weights)
        gaps = self.obstacles.gaps(positions, t)
        if not np.all(gaps > 0.0):
            return math.inf
        return float(np.sum(weights[None, :] * self.barrier.value(gaps)))

    def _active_pairs(self, positions, t):
        """(obstacle, point) pairs with d < d̂, and every obstacle's gaps (obstacles, n)."""
        gaps = self.obstacles.gaps(positions, t)
        return gaps < self.barrier.distance, gaps

    def gradient(self, positions: ArrayLike, weights: ArrayLike, t: float = 0.0) -> np.ndarray:
        """Return ∂E/∂xᵢ (n, d); NaN rows at points on or inside an obstacle."""
        positions, weights = self._check(positions, weights)
        gradient = np.zeros_like(positions)
        active, gaps = self._active_pairs(positions, t)
        feasible = np.all(gaps > 0.0, axis=0)
        active &= feasible[None, :]
        for index, obstacle in enumerate(self.obstacles):
            points = np.flatnonzero(active[index])
            if len(points) == 0:
                continue
            gap, gap_gradient, _ = obstacle.gap_derivatives(positions[points], t)
            slope = weights[points] * self.barrier.derivative(gap)
            gradient[points] += slope[:, None] * gap_gradient
        gradient[~feasible] = math.nan
        return gradient

    def hessians(
        self, positions: ArrayLike, weights: ArrayLike, t: float = 0.0, *, project: bool = True
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return the points with a nonzero Hessian and their d × d blocks ∂²E/∂xᵢ².

        ``project`` (default) gives each block's positive part; ``False`` the exact block.
        Points on or inside an obstacle are left out (they have no Hessian).

        Returns
        -------
        (points, blocks)
            Indices (k,) into ``positions`` and blocks (k, d, d).
        """
        positions, weights = self._check(positions, weights)
        active, gaps = self._active_pairs(positions, t)
        feasible = np.all(gaps > 0.0, axis=0)
        active &= feasible[None, :]
        points = np.flatnonzero(np.any(active, axis=0))
        slot = np.full(len(positions), -1)
        slot[points] = np.arange(len(points))
        d = positions.shape[1]
        blocks = np.zeros((len(points), d, d))
        for index, obstacle in enumerate(self.obstacles):
            these = np.flatnonzero(active[index])
            if len(these) == 0:
                continue
            gap, gap_gradient, gap_hessian = obstacle.gap_derivatives(positions[these], t)
            w = weights[these]
            curvature = w * self.barrier.second_derivative(gap)
            slope = w * self.barrier.derivative(gap)
            blocks[slot[these]] += (
                curvature[:, None, None] * gap_gradient[:, :, None] * gap_gradient[:, None, :]
                + slope[:, None, None] * gap_hessian
            )
        if project:
            blocks = project_blocks(blocks)
        return points, blocks
