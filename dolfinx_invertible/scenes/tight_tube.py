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
only pass a narrowest section into something wider: the obstacle here,
:class:`~dolfinx_invertible.contact.Funnel`, is the solid around the union of the inside of the
cone and the half-space beyond the throat.

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

import dolfinx
import numpy as np

from dolfinx_invertible.contact import Funnel, HalfSpace, RigidMotion
from dolfinx_invertible.scenes.contact_scene import ContactScene

__all__ = ["TightTube"]

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


class TightTube(ContactScene):
    """A plate pushes a slab through a funnel whose throat is a third of its width."""

    name = "tight-tube"
    description = "a plate pushes a body through a cone narrowing to a third of its width (contact)"
    figure = "Fig. 11"
    defaults = {"E": 1.0e5, "nu": 0.3, "density": 1000.0, "dt": 0.005, "t_end": 0.6,
                "resolution": 3, "size": 0.2, "damping": 0.2, "project": "no"}  # fmt: skip
    takes_mesh_file = True

    def create_mesh(self):
        """Return the slab [−ℓ, 0] × [−W/2, W/2]² (ℓ = LENGTH·W), its front at x = 0.

        ``resolution`` cells along its length, twice as many across. A body from ``--mesh
        PATH`` is fitted into the same box, its front at x = 0.
        """
        width, n = self.parameters.size, self.parameters.resolution
        half, length = 0.5 * width, LENGTH * width
        box = ([-length, -half, -half], [0.0, half, half])
        if self.mesh_file is not None:
            return self.read_mesh_file(box, anchor=(1, 0, 0))
        return dolfinx.mesh.create_box(self.comm, list(box), [n, 2 * n, 2 * n])

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
