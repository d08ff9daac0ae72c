"""A sphere (a circle in 2D): solid to hit with (a ball), or hollow to be inside of (a bowl)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dolfinx_invertible.constitutive.validation import check_positive
from dolfinx_invertible.contact.motion import RigidMotion, as_vector
from dolfinx_invertible.contact.obstacle import Obstacle, radial_frame

__all__ = ["Sphere"]


class Sphere(Obstacle):
    """A sphere of centre c and radius r; the body stays outside it, or inside with ``inside``.

    With ρ = |x − c| and e = (x − c)/ρ: outside (a solid ball) d = ρ − r, ∇d = e,
    ∇²d = (I − eeᵀ)/ρ; inside (a hollow sphere, a bowl) d = r − ρ and the derivatives change
    sign. Along x + αp, ρ² = |x − c|² + 2α (x − c)·p + α²|p|² is quadratic, so the crossing is
    the first positive root of ±(ρ² − r²), whose value at α = 0 is computed as ±(ρ − r)(ρ + r)
    for accuracy at small gaps.

    Parameters
    ----------
    center
        c (2 or 3 entries).
    radius
        r > 0.
    inside
        ``False`` (default): the body is outside the sphere; ``True``: inside it.
    motion
        Optional :class:`~dolfinx_invertible.contact.motion.RigidMotion`.
    """

    def __init__(
        self,
        center: Sequence[float],
        radius: float,
        *,
        inside: bool = False,
        motion: RigidMotion | None = None,
    ) -> None:
        self.center = as_vector("center", center)
        self.radius = check_positive("radius", radius)
        if not isinstance(inside, (bool, np.bool_)):
            raise ValueError(f"inside must be True or False, got {inside!r}")
        self.inside = bool(inside)
        self.sign = -1.0 if self.inside else 1.0
        self.dimension = len(self.center)
        super().__init__(motion)

    def _gap(self, y):
        return self.sign * (np.linalg.norm(y - self.center, axis=1) - self.radius)

    def _gap_derivatives(self, y):
        rho, e, curvature = radial_frame(y - self.center)
        return self.sign * (rho - self.radius), self.sign * e, self.sign * curvature

    def _crossing_polynomial(self, y, q):
        v = y - self.center
        rho = np.linalg.norm(v, axis=1)
        c0 = self.sign * (rho - self.radius) * (rho + self.radius)
        c1 = self.sign * 2.0 * np.einsum("ij,ij->i", v, q)
        c2 = self.sign * np.einsum("ij,ij->i", q, q)
        return c0, c1, c2

    def __repr__(self) -> str:
        return (
            f"Sphere(center={self.center.tolist()}, radius={self.radius!r}, "
            f"inside={self.inside!r}, motion={self.motion!r})"
        )
