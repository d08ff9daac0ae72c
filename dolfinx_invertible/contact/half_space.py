"""The half-space n·x ≥ c: the ground, a wall, a moving plate."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dolfinx_invertible.contact.motion import RigidMotion, as_vector
from dolfinx_invertible.contact.obstacle import Obstacle

__all__ = ["HalfSpace"]


class HalfSpace(Obstacle):
    """The body stays on the side n·x > c of the plane n·x = c.

    The gap is d = n·x − c with n normalised (``normal`` and ``offset`` are both divided by
    the length of ``normal``), so d is the distance to the plane; ∇d = n, ∇²d = 0. Along
    x + αp the gap d + α n·p is linear: the crossing is α = −d / (n·p) when n·p < 0.

    Parameters
    ----------
    normal
        Normal of the plane pointing towards the body (2 or 3 entries, nonzero).
    offset
        c in n·x = c (before normalisation).
    motion
        Optional :class:`~dolfinx_invertible.contact.motion.RigidMotion`.
    """

    def __init__(
        self, normal: Sequence[float], offset: float = 0.0, *, motion: RigidMotion | None = None
    ) -> None:
        normal = as_vector("normal", normal)
        length = float(np.linalg.norm(normal))
        if not length > 0.0:
            raise ValueError(f"normal must be a nonzero vector, got {normal.tolist()}")
        offset = float(offset)
        if not np.isfinite(offset):
            raise ValueError(f"offset must be finite, got {offset!r}")
        self.dimension = len(normal)
        self.normal = normal / length
        self.offset = offset / length
        super().__init__(motion)

    def _gap(self, y):
        return y @ self.normal - self.offset

    def _gap_derivatives(self, y):
        n, d = y.shape
        gradient = np.broadcast_to(self.normal, (n, d)).copy()
        return self._gap(y), gradient, np.zeros((n, d, d))

    def _crossing_polynomial(self, y, q):
        return self._gap(y), q @ self.normal, np.zeros(len(y))

    def __repr__(self) -> str:
        return (
            f"HalfSpace(normal={self.normal.tolist()}, offset={self.offset!r}, "
            f"motion={self.motion!r})"
        )
