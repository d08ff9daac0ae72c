"""Tight tube: a plate pushes a body through a cone narrowing to a third of its width (Fig. 11).

A slab of width W (``--size``, default 0.2 m) and length W/2 sits in the wide part of a
funnel: a rigid wall with a conical hole about the x axis whose radius narrows by
:data:`SLOPE` per unit length (a half-angle of 45°) to W/6 at its throat, a passage a third of
the body's width, beyond which the space is free. A rigid plate (a half-space behind the body,
normal +x) moves along +x at :data:`PLATE_SPEED`, pushes the body into the cone, through the
throat and out, and stops just past the throat. At the throat the body is squeezed to a third
of its width and stretched along the axis, and tens of cells in and before the throat invert.
Once out, the body springs back to its shape. No gravity (a horizontal, frictionless tube:
gravity would only rest the body on the tube's wall).

A cone alone (:class:`~dolfinx_invertible.contact.Cone`) closes at its apex, and a body can
only pass a narrowest section into something wider: the obstacle here, :class:`Funnel`, is the
solid around the union of the inside of the cone and the half-space beyond the throat, built on
the public :class:`~dolfinx_invertible.contact.Obstacle` base.

Defaults, and why:

- ``resolution`` 3 (cells along the length; 6 across, 3 × 6² × 6 tetrahedra): the throat is
  two cells across. With fewer, the squeezed body tangles (its nodes pass each other, which
  nothing prevents without self-contact) and does not find its shape again;
- E = 10⁵ Pa, ν = 0.3, ρ = 1000 kg/m³: a rubber-like solid, compressible enough to take the
  threefold squeeze without the axial stretch of a nearly incompressible one (about elevenfold);
- plate speed 0.5 m/s: the material leaves the throat up to about eleven times faster (the
  ratio of the areas), still below the wave speed √(E/ρ) = 10 m/s; dt = 5 ms moves the plate
  under a tenth of a cell per step; 0.6 s: the push (0.47 s) and the recovery after it;
- damping 0.2 of critical (mass-proportional, 63/s): heavy, so that the push is close to
  quasi-static and the body comes to rest past the throat instead of flying off;
- ``project`` no (the exact tangent throughout): in the squeeze the SPD-projected tangent that
  ``auto`` falls back on converges only linearly and runs into the iteration cap, which costs
  more than cutting the step when the exact tangent gives no descent.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import dolfinx
import numpy as np

from dolfinx_invertible.contact import Cone, HalfSpace, Obstacle, RigidMotion
from dolfinx_invertible.contact.motion import as_unit_vector, as_vector
from dolfinx_invertible.contact.obstacle import radial_frame
from dolfinx_invertible.scenes.contact_scene import ContactScene

__all__ = ["Funnel", "TightTube"]

#: Throat diameter over the body's width.
THROAT = 1.0 / 3.0
#: Growth of the funnel's radius per unit length from the throat backwards (tan of its
#: half-angle, 45°).
SLOPE = 1.0
#: Distance from the body's front to the throat, over its width: the cone's radius at the
#: front, W/6 + 0.6 W = 0.77 W, clears the slab's corners (0.71 W off the axis).
THROAT_DISTANCE = 0.6
#: Length of the body along the axis over its width.
LENGTH = 0.5
#: Plate speed along the axis [m/s].
PLATE_SPEED = 0.5
#: How far the plate goes past the throat, over the body's width.
OVERSHOOT = 0.05


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
    backwards away from the hole): :meth:`first_crossing` follows the path through these two
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

    def first_crossing(self, x, direction, t: float = 0.0) -> np.ndarray:
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
            leave = self._cone.first_crossing(y[inside], q[inside])
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
                beyond[through] = self._cone.first_crossing(on_face[through], q[outside][through])
            crossing[outside] = meet + beyond
        crossing[~(self._gap(y) > 0.0)] = 0.0
        return crossing

    def __repr__(self) -> str:
        return (
            f"Funnel(throat={self.throat.tolist()}, axis={self.axis.tolist()}, "
            f"radius={self.radius!r}, slope={self.slope!r}, motion={self.motion!r})"
        )


class TightTube(ContactScene):
    """A plate pushes a slab through a funnel whose throat is a third of its width."""

    name = "tight-tube"
    description = "a plate pushes a body through a cone narrowing to a third of its width (contact)"
    figure = "Fig. 11"
    defaults = {"E": 1.0e5, "nu": 0.3, "density": 1000.0, "dt": 0.005, "t_end": 0.6,
                "resolution": 3, "size": 0.2, "damping": 0.2, "project": "no"}  # fmt: skip

    def create_mesh(self):
        """Return the slab [−ℓ, 0] × [−W/2, W/2]² (ℓ = LENGTH·W), its front at x = 0.

        ``resolution`` cells along its length, twice as many across.
        """
        width, n = self.parameters.size, self.parameters.resolution
        half, length = 0.5 * width, LENGTH * width
        return dolfinx.mesh.create_box(
            self.comm, [[-length, -half, -half], [0.0, half, half]], [n, 2 * n, 2 * n]
        )

    def throat_position(self) -> float:
        """Return x of the throat."""
        return THROAT_DISTANCE * self.parameters.size

    def plate_position(self, t: float) -> float:
        """Return x of the plate at time t: behind the body, moving on until past the throat."""
        width, n = self.parameters.size, self.parameters.resolution
        start = -LENGTH * width - 0.1 * LENGTH * width / n
        stop = self.throat_position() + OVERSHOOT * width
        return min(start + PLATE_SPEED * t, stop)

    def push_time(self) -> float:
        """Return the time at which the plate stops."""
        return (self.plate_position(math.inf) - self.plate_position(0.0)) / PLATE_SPEED

    def obstacles(self):
        """Return the funnel about the x axis and the plate behind the body."""
        width = self.parameters.size
        along = np.array([1.0, 0.0, 0.0])
        funnel = Funnel(self.throat_position() * along, along, 0.5 * THROAT * width, SLOPE)
        start = self.plate_position(0.0)
        motion = RigidMotion(3, translation=lambda t: (self.plate_position(t) - start) * along)
        plate = HalfSpace(along, start, motion=motion)
        return [funnel, plate]

    def quantities(self, run):
        """Add where the throat is and when the plate stopped."""
        return {
            **super().quantities(run),
            "throat_x": self.throat_position(),
            "throat_radius": 0.5 * THROAT * self.parameters.size,
            "push_time": self.push_time(),
        }
