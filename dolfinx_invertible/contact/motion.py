"""Prescribed rigid motions of obstacles: a rotation about a fixed axis, then a translation.

A body point y of an obstacle (its shape as constructed) is at time t at

    x = R(t) (y − p) + p + T(t),

with p the pivot, R(t) the rotation by the angle θ(t) about the axis through p (in 2D, the
rotation in the plane) and T(t) the translation. The inverse map y(x, t) = R(t)ᵀ(x − p − T(t)) + p
carries a world point into the obstacle's own frame, where its gap is evaluated.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

__all__ = ["RigidMotion", "as_vector", "rotation_matrix"]


def as_vector(name: str, value, dimension: int | None = None) -> np.ndarray:
    """Return ``value`` as a finite float vector of 2 or 3 entries (or ``dimension`` entries)."""
    array = np.asarray(value, dtype=np.float64)
    sizes = (2, 3) if dimension is None else (dimension,)
    if array.ndim != 1 or array.shape[0] not in sizes:
        wanted = " or ".join(str(size) for size in sizes)
        raise ValueError(f"{name} must be a vector of {wanted} entries, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite, got {array.tolist()}")
    return array.copy()


def as_unit_vector(name: str, value, dimension: int | None = None) -> np.ndarray:
    """Return ``value`` normalised to length 1; refuse a zero vector."""
    array = as_vector(name, value, dimension)
    length = float(np.linalg.norm(array))
    if not length > 0.0:
        raise ValueError(f"{name} must be a nonzero vector, got {array.tolist()}")
    return array / length


def rotation_matrix(angle: float, axis: np.ndarray | None, dimension: int) -> np.ndarray:
    """Rotation by ``angle`` (radians): in the plane for 2D, about the unit ``axis`` in 3D."""
    c, s = math.cos(angle), math.sin(angle)
    if dimension == 2:
        return np.array([[c, -s], [s, c]])
    # Rodrigues: R = cI + s[a]ₓ + (1 − c) a aᵀ.
    a = axis
    cross = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return c * np.eye(3) + s * cross + (1.0 - c) * np.outer(a, a)


class RigidMotion:
    """A rigid motion prescribed as functions of time.

    Parameters
    ----------
    dimension
        2 or 3, that of the obstacle it moves.
    translation
        ``translation(t)`` returns T(t), a vector of ``dimension`` entries; zero if omitted.
    angle
        ``angle(t)`` returns θ(t) in radians; no rotation if omitted.
    axis
        Rotation axis in 3D (normalised here); default the z axis. Must be omitted in 2D.
    pivot
        A point on the rotation axis (the centre of rotation in 2D); default the origin.
    """

    def __init__(
        self,
        dimension: int,
        *,
        translation: Callable[[float], Sequence[float]] | None = None,
        angle: Callable[[float], float] | None = None,
        axis: Sequence[float] | None = None,
        pivot: Sequence[float] | None = None,
    ) -> None:
        if dimension not in (2, 3):
            raise ValueError(f"dimension must be 2 or 3, got {dimension!r}")
        if translation is not None and not callable(translation):
            raise ValueError("translation must be a function of time t returning a vector")
        if angle is not None and not callable(angle):
            raise ValueError("angle must be a function of time t returning radians")
        self.dimension = dimension
        self.translation = translation
        self.angle = angle
        if dimension == 2:
            if axis is not None:
                raise ValueError("axis: a 2D motion rotates in the plane; give no axis")
            self.axis = None
        else:
            self.axis = as_unit_vector("axis", (0.0, 0.0, 1.0) if axis is None else axis, 3)
        self.pivot = np.zeros(dimension) if pivot is None else as_vector("pivot", pivot, dimension)

    def offset(self, t: float) -> np.ndarray:
        """Return the translation T(t)."""
        if self.translation is None:
            return np.zeros(self.dimension)
        return as_vector(f"translation({t!r})", self.translation(t), self.dimension)

    def rotation(self, t: float) -> np.ndarray:
        """Return the rotation matrix R(t)."""
        if self.angle is None:
            return np.eye(self.dimension)
        theta = float(self.angle(t))
        if not math.isfinite(theta):
            raise ValueError(f"angle({t!r}) must be finite, got {theta!r}")
        return rotation_matrix(theta, self.axis, self.dimension)

    def to_body(self, x: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Map world points ``x`` (n, d) into the obstacle's frame; also return R(t)."""
        R = self.rotation(t)
        shift = self.pivot + self.offset(t)
        # Row vectors: yᵀ = (x − p − T)ᵀ R + pᵀ.
        return (x - shift) @ R + self.pivot, R

    def __repr__(self) -> str:
        return (
            f"RigidMotion(dimension={self.dimension}, translation={self.translation!r}, "
            f"angle={self.angle!r}, axis={self.axis!r}, pivot={self.pivot.tolist()!r})"
        )
