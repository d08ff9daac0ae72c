"""A rigid wall with a conical hole: the inside of a narrowing cone, open beyond its throat.

A cone alone (:class:`~dolfinx_invertible.contact.cone.Cone`) closes at its apex, so a body
pushed into it can never pass its narrowest section. :class:`Funnel` is the solid around the
union of the inside of the cone and the half-space beyond the throat, so a body can be pushed
through the throat into free space (the ``tight-tube`` scene).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from dolfinx_invertible.contact.cone import Cone
from dolfinx_invertible.contact.motion import RigidMotion, as_unit_vector, as_vector
from dolfinx_invertible.contact.obstacle import Obstacle, radial_frame

__all__ = ["Funnel"]


class Funnel(Obstacle):
    """A rigid wall with a conical hole that narrows along ``axis`` to ``radius`` at ``throat``.

    The body may be inside the cone of radius r(s) = r_t − k s (s = a·(x − c) the position
    along the unit axis a from the throat c, k > 0 the slope) or anywhere beyond the throat
    (s > 0): the obstacle is the solid S = {outside the cone, s ≤ 0}, a wall whose face s = 0
    has a hole of radius r_t. In the plane through the axis, with σ = s, η = ρ − r_t (ρ the
    distance to the axis) and L = √(1 + k²), the gap is the distance to S:

    - σ > 0 and η > 0 (beyond the wall's face): d = σ;
    - η ≤ 0 and σ ≥ k η (nearest to the hole's rim, a circle): d = √(σ² + η²);
    - otherwise outside S (inside the cone, nearest to its wall): d = (r_t − k σ − ρ)/L;
    - inside S: d = max((r_t − k σ − ρ)/L, σ) < 0.

    The regions meet where the formulas agree, so d is continuous with a continuous gradient
    outside S. A straight path enters S either through the cone's wall (the cone's own
    crossing, taken where it lies at s ≤ 0) or through the wall's face (the plane s = 0 crossed
    backwards away from the hole): :meth:`path_crossing` follows the path through these two
    events exactly.

    Parameters
    ----------
    throat
        c, the centre of the throat (2 or 3 entries).
    axis
        a, the direction in which the funnel narrows and the body passes.
    radius
        r_t > 0, the radius of the throat.
    slope
        k > 0.
    motion
        Optional :class:`~dolfinx_invertible.contact.RigidMotion`.
    """

    def __init__(
        self,
        throat: Sequence[float],
        axis: Sequence[float],
        radius: float,
        slope: float,
        *,
        motion: RigidMotion | None = None,
    ) -> None:
        self.throat = as_vector("throat", throat)
        self.dimension = len(self.throat)
        self.axis = as_unit_vector("axis", axis, self.dimension)
        radius, slope = float(radius), float(slope)
        if not (math.isfinite(radius) and radius > 0.0):
            raise ValueError(f"radius must be a finite number > 0, got {radius!r}")
        if not (math.isfinite(slope) and slope > 0.0):
            raise ValueError(f"slope must be a finite number > 0, got {slope!r}")
        self.radius, self.slope = radius, slope
        self._length = math.sqrt(1.0 + slope * slope)
        self._projector = np.eye(self.dimension) - np.outer(self.axis, self.axis)
        self._cone = Cone(self.throat, self.axis, radius, -slope)
        super().__init__(motion)

    def _coordinates(self, y):
        v = y - self.throat
        return v @ self.axis, v @ self._projector

    def _regions(self, sigma, rho):
        """Return the cone gap, and the masks: inside S, beyond the face, near the rim."""
        eta = rho - self.radius
        cone = (self.radius - self.slope * sigma - rho) / self._length
        solid = (cone <= 0.0) & (sigma <= 0.0)
        face = ~solid & (sigma > 0.0) & (eta > 0.0)
        rim = ~solid & (eta <= 0.0) & (sigma >= self.slope * eta)
        return cone, solid, face, rim

    def _gap(self, y):
        sigma, w = self._coordinates(y)
        rho = np.linalg.norm(w, axis=1)
        cone, solid, face, rim = self._regions(sigma, rho)
        gap = cone.copy()
        gap[solid] = np.maximum(cone[solid], sigma[solid])
        gap[face] = sigma[face]
        gap[rim] = np.hypot(sigma[rim], rho[rim] - self.radius)
        return gap

    def _gap_derivatives(self, y):
        sigma, w = self._coordinates(y)
        rho, e, curvature = radial_frame(w, self._projector)
        cone, solid, face, rim = self._regions(sigma, rho)
        a = self.axis
        # The cone's wall everywhere, then the other regions over it.
        gap = cone.copy()
        gradient = (-self.slope * a[None, :] - e) / self._length
        hessian = -curvature / self._length
        plane = face | (solid & (sigma > cone))
        gap[plane] = sigma[plane]
        gradient[plane] = a
        hessian[plane] = 0.0
        eta = rho[rim] - self.radius
        distance = np.hypot(sigma[rim], eta)
        safe = np.where(distance > 0.0, distance, 1.0)
        rim_gradient = (sigma[rim, None] * a[None, :] + eta[:, None] * e[rim]) / safe[:, None]
        # ∇²(D²/2) = aaᵀ + eeᵀ + η (P − eeᵀ)/ρ, and ∇²D = (∇²(D²/2) − ∇D∇Dᵀ)/D.
        half_square = (
            np.outer(a, a)[None]
            + e[rim, :, None] * e[rim, None, :]
            + eta[:, None, None] * curvature[rim]
        )
        outer = rim_gradient[:, :, None] * rim_gradient[:, None, :]
        rim_hessian = (half_square - outer) / safe[:, None, None]
        on_rim = distance == 0.0
        rim_gradient[on_rim] = 0.0
        rim_hessian[on_rim] = 0.0
        gap[rim] = distance
        gradient[rim] = rim_gradient
        hessian[rim] = rim_hessian
        return gap, gradient, hessian

    def path_crossing(self, x, direction, t: float = 0.0) -> np.ndarray:
        """First α > 0 at which ``x + α · direction`` reaches the funnel, at time ``t``.

        Inside the cone, the path leaves it at the cone's crossing α_c; that is the answer if
        it lies at s ≤ 0 (the wall), otherwise the path is beyond the face and meets the
        funnel where it crosses the plane s = 0 backwards (if it does). Outside the cone (then
        s > 0), the path meets the face where it crosses s = 0 backwards, unless it goes
        through the hole there, in which case it meets the cone's wall where it leaves the
        cone from that point on.
        """
        y, q = self._path_in_body(x, direction, t)
        sigma, _ = self._coordinates(y)
        along = q @ self.axis
        crossing = np.full(len(y), math.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            to_face = np.where(along < 0.0, -sigma / np.where(along < 0.0, along, 1.0), math.inf)
        inside = self._cone.gap(y) > 0.0
        if inside.any():
            leave = self._cone.path_crossing(y[inside], q[inside])
            finite = np.isfinite(leave)
            at_leave = sigma[inside] + np.where(finite, leave, 0.0) * along[inside]
            crossing[inside] = np.where(
                finite & (at_leave <= 0.0), leave, np.where(finite, to_face[inside], math.inf)
            )
        outside = ~inside & np.isfinite(to_face)
        if outside.any():
            meet = to_face[outside]
            on_face = y[outside] + meet[:, None] * q[outside]
            through = self._cone.gap(on_face) > 0.0
            beyond = np.zeros(len(meet))
            if through.any():
                beyond[through] = self._cone.path_crossing(on_face[through], q[outside][through])
            crossing[outside] = meet + beyond
        crossing[~(self._gap(y) > 0.0)] = 0.0
        return crossing

    def __repr__(self) -> str:
        return (
            f"Funnel(throat={self.throat.tolist()}, axis={self.axis.tolist()}, "
            f"radius={self.radius!r}, slope={self.slope!r}, motion={self.motion!r})"
        )
