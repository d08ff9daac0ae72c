"""Lagged Coulomb friction against rigid obstacles, smoothed as in IPC (Li et al. 2020, §5).

Over a time step from t₀ to t₁, a boundary vertex i in contact with obstacle o (gap below d̂ at
the step's start) resists its sliding relative to the obstacle's surface with the dissipative
potential

    D = Σ μ λᵢₒ f₀(‖uᵢₒ‖),    uᵢₒ = Pᵢₒ (xᵢ − xᵢ(t₀) − Δoᵢₒ),

where, all lagged at the step's start: λᵢₒ = −wᵢ b′(dᵢₒ) ≥ 0 the barrier's normal force,
Pᵢₒ = I − n nᵀ the projection on the obstacle's tangent plane (n the unit gap gradient), and
Δoᵢₒ the motion of the obstacle's material point under the vertex over the step (zero for a
fixed obstacle; a rotating roller drags). f₀ is C¹ at 0: f₀(y) = y for y ≥ ε and
−y³/(3ε²) + y²/ε + ε/3 below, ε = ε_v (t₁ − t₀), so that a vertex slower than ε_v sticks
elastically and a faster one feels the force μλ against its tangential motion. Its Hessian is
positive semidefinite as it stands: along u, μλ f₀″ ≥ 0; across, μλ f₀′/y > 0.
"""

from __future__ import annotations

import math

import numpy as np

from dolfinx_invertible.contact.barrier import Barrier
from dolfinx_invertible.contact.obstacles import Obstacles

__all__ = ["DEFAULT_FRICTION_VELOCITY", "ObstacleFriction", "mollifier"]

#: ε_v [m/s]: sliding slower than this is treated as sticking (elastically).
DEFAULT_FRICTION_VELOCITY = 1e-3


def mollifier(y: np.ndarray, threshold: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return f₀(y), f₀′(y)/y and f₀″(y) of the smoothed friction for y ≥ 0 (see above)."""
    y = np.asarray(y, dtype=np.float64)
    inside = y < threshold
    e = threshold
    value = np.where(inside, -(y**3) / (3 * e * e) + y * y / e + e / 3, y)
    safe = np.where(inside, 1.0, np.maximum(y, e))
    slope_over_y = np.where(inside, 2.0 / e - y / (e * e), 1.0 / safe)
    curvature = np.where(inside, 2.0 / e - 2.0 * y / (e * e), 0.0)
    return value, slope_over_y, curvature


class ObstacleFriction:
    """The friction potential D of one time step against rigid obstacles (see the module).

    Parameters
    ----------
    coefficient
        μ ≥ 0.
    velocity
        ε_v > 0 [m/s].
    """

    def __init__(self, coefficient: float, velocity: float = DEFAULT_FRICTION_VELOCITY) -> None:
        coefficient, velocity = float(coefficient), float(velocity)
        if not (math.isfinite(coefficient) and coefficient >= 0.0):
            raise ValueError(f"the friction coefficient must be >= 0, got {coefficient!r}")
        if not (math.isfinite(velocity) and velocity > 0.0):
            raise ValueError(f"the friction velocity must be > 0, got {velocity!r}")
        self.coefficient = coefficient
        self.velocity = velocity
        self.threshold = 1.0
        self._points = np.zeros(0, dtype=np.int64)
        self._start = np.zeros((0, 0))
        self._force = np.zeros(0)
        self._projection = np.zeros((0, 0, 0))

    def lag(
        self,
        positions: np.ndarray,
        weights: np.ndarray,
        obstacles: Obstacles,
        barrier: Barrier,
        start: float,
        end: float,
    ) -> None:
        """Fix λ, P and Δo at the step's start (``positions`` at time ``start``) for ``end``."""
        self.threshold = self.velocity * max(float(end) - float(start), 0.0)
        points, starts, forces, projections = [], [], [], []
        gaps = obstacles.gaps(positions, start)
        for index, obstacle in enumerate(obstacles):
            near = np.flatnonzero((gaps[index] > 0.0) & (gaps[index] < barrier.distance))
            if len(near) == 0 or self.coefficient == 0.0:
                continue
            gap, gradient, _ = obstacle.gap_derivatives(positions[near], start)
            length = np.linalg.norm(gradient, axis=1)
            normal = gradient / np.maximum(length, 1e-300)[:, None]
            forces.append(-weights[near] * barrier.derivative(gap) * length)
            d = positions.shape[1]
            projections.append(np.eye(d)[None] - normal[:, :, None] * normal[:, None, :])
            # Where the obstacle's material point under the vertex goes over the step.
            starts.append(positions[near] + _obstacle_motion(obstacle, positions[near], start, end))
            points.append(near)
        d = positions.shape[1]
        self._points = np.concatenate(points) if points else np.zeros(0, dtype=np.int64)
        self._start = np.concatenate(starts) if starts else np.zeros((0, d))
        self._force = np.concatenate(forces) if forces else np.zeros(0)
        self._projection = np.concatenate(projections) if projections else np.zeros((0, d, d))

    @property
    def active(self) -> int:
        """The number of (vertex, obstacle) pairs the friction acts on this step."""
        return len(self._points)

    def _sliding(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        relative = positions[self._points] - self._start
        tangential = np.einsum("kij,kj->ki", self._projection, relative)
        return tangential, np.linalg.norm(tangential, axis=1)

    def energy(self, positions: np.ndarray) -> float:
        """Return D at ``positions`` (this rank's points)."""
        if not self.active or self.threshold == 0.0:
            return 0.0
        _, length = self._sliding(positions)
        value, _, _ = mollifier(length, self.threshold)
        return float(np.sum(self.coefficient * self._force * value))

    def gradient(self, positions: np.ndarray) -> np.ndarray:
        """Return ∂D/∂xᵢ, (n, d)."""
        result = np.zeros_like(positions)
        if not self.active or self.threshold == 0.0:
            return result
        tangential, length = self._sliding(positions)
        _, slope_over_y, _ = mollifier(length, self.threshold)
        np.add.at(
            result,
            self._points,
            (self.coefficient * self._force * slope_over_y)[:, None] * tangential,
        )
        return result

    def hessians(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the points and their d × d blocks ∂²D/∂xᵢ² (positive semidefinite)."""
        d = positions.shape[1]
        if not self.active or self.threshold == 0.0:
            return np.zeros(0, dtype=np.int64), np.zeros((0, d, d))
        tangential, length = self._sliding(positions)
        _, slope_over_y, curvature = mollifier(length, self.threshold)
        direction = tangential / np.maximum(length, 1e-300)[:, None]
        along = direction[:, :, None] * direction[:, None, :]
        scale = self.coefficient * self._force
        blocks = scale[:, None, None] * (
            slope_over_y[:, None, None] * (self._projection - along)
            + curvature[:, None, None] * along
        )
        return self._points, blocks


def _obstacle_motion(obstacle, points: np.ndarray, start: float, end: float) -> np.ndarray:
    """Displacement over [start, end] of the obstacle's material points at ``points``."""
    motion = obstacle.motion
    if motion is None or end == start:
        return np.zeros_like(points)
    body, _ = motion.to_body(points, start)
    rotation = motion.rotation(end)
    moved = (body - motion.pivot) @ rotation.T + motion.pivot + motion.offset(end)
    return moved - points
