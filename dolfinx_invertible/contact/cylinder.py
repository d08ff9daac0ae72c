"""An infinite circular cylinder: outside it (a roller) or inside it (a tube)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dolfinx_invertible.constitutive.validation import check_positive
from dolfinx_invertible.contact.motion import RigidMotion, as_unit_vector, as_vector
from dolfinx_invertible.contact.obstacle import Obstacle, radial_frame

__all__ = ["Cylinder"]


class Cylinder(Obstacle):
    """The cylinder of radius r about the line through ``point`` along the unit ``axis`` a.

    With P = I − aaᵀ, w = P(x − c), ρ = |w| (the distance to the axis) and e = w/ρ: outside
    (a roller) d = ρ − r, ∇d = e, ∇²d = (P − eeᵀ)/ρ; inside (a tube) d = r − ρ and the
    derivatives change sign. Along x + αp, w moves by αPp, so ρ² is quadratic in α and the
    crossing is the first positive root of ±(ρ² − r²). In 2D the "cylinder" is the strip
    |distance to the line| < r (inside: a channel); there ∇²d = 0 away from the line.

    Parameters
    ----------
    point
        A point c on the axis (2 or 3 entries).
    axis
        Direction of the axis (normalised here).
    radius
        r > 0.
    inside
        ``False`` (default): the body is outside the cylinder; ``True``: inside it.
    motion
        Optional :class:`~dolfinx_invertible.contact.motion.RigidMotion`.
    """

    def __init__(
        self,
        point: Sequence[float],
        axis: Sequence[float],
        radius: float,
        *,
        inside: bool = False,
        motion: RigidMotion | None = None,
    ) -> None:
        self.point = as_vector("point", point)
        self.dimension = len(self.point)
        self.axis = as_unit_vector("axis", axis, self.dimension)
        self.radius = check_positive("radius", radius)
        if not isinstance(inside, (bool, np.bool_)):
            raise ValueError(f"inside must be True or False, got {inside!r}")
        self.inside = bool(inside)
        self.sign = -1.0 if self.inside else 1.0
        self._projector = np.eye(self.dimension) - np.outer(self.axis, self.axis)
        super().__init__(motion)

    def _radial(self, v):
        return v @ self._projector  # P is symmetric

    def _gap(self, y):
        rho = np.linalg.norm(self._radial(y - self.point), axis=1)
        return self.sign * (rho - self.radius)

    def _gap_derivatives(self, y):
        rho, e, curvature = radial_frame(self._radial(y - self.point), self._projector)
        return self.sign * (rho - self.radius), self.sign * e, self.sign * curvature

    def _crossing_polynomial(self, y, q):
        w = self._radial(y - self.point)
        dw = self._radial(q)
        rho = np.linalg.norm(w, axis=1)
        c0 = self.sign * (rho - self.radius) * (rho + self.radius)
        c1 = self.sign * 2.0 * np.einsum("ij,ij->i", w, dw)
        c2 = self.sign * np.einsum("ij,ij->i", dw, dw)
        return c0, c1, c2

    def __repr__(self) -> str:
        return (
            f"Cylinder(point={self.point.tolist()}, axis={self.axis.tolist()}, "
            f"radius={self.radius!r}, inside={self.inside!r}, motion={self.motion!r})"
        )
