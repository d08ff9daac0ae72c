"""The inside of a circular cone: a tube whose radius varies linearly along its axis."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from dolfinx_invertible.constitutive.validation import check_positive
from dolfinx_invertible.contact.motion import RigidMotion, as_unit_vector, as_vector
from dolfinx_invertible.contact.obstacle import Obstacle, radial_frame

__all__ = ["Cone"]


class Cone(Obstacle):
    """Inside of the cone of radius r(s) = r₀ + k s about the axis through c along a.

    With s = a·(x − c) the position along the axis, P = I − aaᵀ, w = P(x − c), ρ = |w| and
    e = w/ρ, the gap is the distance to the cone's generating line in the plane through the
    axis,

        d = (r₀ + k s − ρ) / L,   L = √(1 + k²),

    positive inside; ∇d = (k a − e)/L, ∇²d = −(P − eeᵀ)/(ρ L). Past the apex (r₀ + k s < 0)
    every point is outside the tube (d < 0): the tube is closed there.

    Crossing along x + αp: with m(α) = r₀ + k s(α) (linear in α) and ρ(α)² (quadratic),
    d > 0 means m > ρ ≥ 0, and there f = m² − ρ² = (m − ρ)(m + ρ) > 0. Starting inside, f
    can only vanish where m = ρ (m = −ρ would need m ≤ 0 first, i.e. m = ρ = 0), so the first
    positive root of the quadratic f is the first crossing:
    f = (m₀ − ρ₀)(m₀ + ρ₀) + 2α (m₀ k a·p − w₀·Pp) + α² (k²(a·p)² − |Pp|²).

    Parameters
    ----------
    point
        c, where the radius is r₀ (2 or 3 entries).
    axis
        Direction a of the axis (normalised here).
    radius
        r₀ > 0.
    slope
        k, the change of radius per unit length along a (negative: the tube narrows along a).
    motion
        Optional :class:`~dolfinx_invertible.contact.motion.RigidMotion`.
    """

    def __init__(
        self,
        point: Sequence[float],
        axis: Sequence[float],
        radius: float,
        slope: float,
        *,
        motion: RigidMotion | None = None,
    ) -> None:
        self.point = as_vector("point", point)
        self.dimension = len(self.point)
        self.axis = as_unit_vector("axis", axis, self.dimension)
        self.radius = check_positive("radius", radius)
        slope = float(slope)
        if not math.isfinite(slope):
            raise ValueError(f"slope must be finite, got {slope!r}")
        self.slope = slope
        self._length = math.sqrt(1.0 + slope * slope)
        self._projector = np.eye(self.dimension) - np.outer(self.axis, self.axis)
        super().__init__(motion)

    @classmethod
    def between(
        cls,
        start: Sequence[float],
        end: Sequence[float],
        start_radius: float,
        end_radius: float,
        *,
        motion: RigidMotion | None = None,
    ) -> Cone:
        """Return the cone whose radius goes from ``start_radius`` at ``start`` to ``end_radius``.

        The cone continues beyond both points (closing at its apex if the radius shrinks).
        """
        start = as_vector("start", start)
        end = as_vector("end", end, len(start))
        length = float(np.linalg.norm(end - start))
        if not length > 0.0:
            raise ValueError("start and end must be different points")
        check_positive("end_radius", end_radius)
        slope = (float(end_radius) - check_positive("start_radius", start_radius)) / length
        return cls(start, end - start, start_radius, slope, motion=motion)

    def _gap(self, y):
        v = y - self.point
        s = v @ self.axis
        rho = np.linalg.norm(v @ self._projector, axis=1)
        return (self.radius + self.slope * s - rho) / self._length

    def _gap_derivatives(self, y):
        v = y - self.point
        s = v @ self.axis
        rho, e, curvature = radial_frame(v @ self._projector, self._projector)
        gap = (self.radius + self.slope * s - rho) / self._length
        gradient = (self.slope * self.axis[None, :] - e) / self._length
        return gap, gradient, -curvature / self._length

    def _crossing_polynomial(self, y, q):
        v = y - self.point
        m = self.radius + self.slope * (v @ self.axis)
        w = v @ self._projector
        rho = np.linalg.norm(w, axis=1)
        dm = self.slope * (q @ self.axis)
        dw = q @ self._projector
        c0 = (m - rho) * (m + rho)
        c1 = 2.0 * (m * dm - np.einsum("ij,ij->i", w, dw))
        c2 = dm * dm - np.einsum("ij,ij->i", dw, dw)
        return c0, c1, c2

    def __repr__(self) -> str:
        return (
            f"Cone(point={self.point.tolist()}, axis={self.axis.tolist()}, "
            f"radius={self.radius!r}, slope={self.slope!r}, motion={self.motion!r})"
        )
