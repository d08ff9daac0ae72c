"""Gap squeeze: a body thrown between two cylinders a third of its thickness apart (Fig. 10).

A cube of thickness T (``--size``, default 0.2 m) is thrown straight down at
:data:`THROW_SPEED` between two fixed rigid cylinders of radius :data:`ROLLER_RADIUS` × T whose
axes lie along y in the plane z = 0, T/3 apart at the nip. The cylinders turn like a pair of
rollers, their surfaces moving down through the nip at the throw's speed. Contact is
frictionless by default, and then their turning does nothing: the body's momentum and gravity
alone must squeeze it to a third of its thickness, which slows it. With ``--friction MU`` the
rollers grip the body and pull it through, as the paper's gears do. Cells in the nip, along the
faces the cylinders press on, are crushed and invert. Past the cylinders the inverted cells
recover and the body falls on, ringing.

Defaults, and why:

- ``resolution`` 6 (6³ × 6 tetrahedra): the gap (T/3) is two cells across, and a run takes
  seconds;
- E = 2·10⁴ Pa, ν = 0.4, ρ = 1000 kg/m³: a soft gel that the throw gets through with speed to
  spare: the squeeze takes about a quarter of the throw's 256 J (8 kg at 8 m/s);
- dt = 2 ms: the body moves 16 mm, half a cell, a step; 0.15 s: the body reaches the
  cylinders after 3 ms, is past them by 0.08 s, its inverted cells have recovered by 0.1 s, and
  it has some time to spring back;
- ``friction_velocity`` 0.1 m/s with ``--friction``: about 1 % of the rollers' surface speed,
  below which slip sticks; at 10⁻³ m/s the friction force flips between the body's vertices
  from one Newton iteration to the next in the nip and the time step is cut to 10⁻⁶ s;
- no damping: mass-proportional damping is also a drag on the flight, which would slow the
  throw (at 0.05 of critical, 7/s, the body leaves the cylinders with less than half the
  kinetic energy).
"""

from __future__ import annotations

import dolfinx

from dolfinx_invertible.contact import Cylinder, RigidMotion
from dolfinx_invertible.scenes.contact_scene import ContactScene

__all__ = ["GapSqueeze"]

#: Gap between the cylinders over the body's thickness.
GAP = 1.0 / 3.0
#: Radius of the cylinders over the body's thickness.
ROLLER_RADIUS = 1.0
#: Height of the body's bottom above the cylinders' axes at t = 0, over its thickness: clear of
#: the cylinders (which reach 0.75 T high below its edges).
START = 0.9
#: Speed of the throw [m/s], downwards.
THROW_SPEED = 8.0
#: Gravity [m/s²].
GRAVITY = (0.0, 0.0, -9.81)


class GapSqueeze(ContactScene):
    """A cube thrown down between two cylinders a third of its thickness apart."""

    name = "gap-squeeze"
    description = "a body thrown through a gap a third of its thickness between two cylinders"
    figure = "Fig. 10"
    defaults = {"E": 2.0e4, "nu": 0.4, "density": 1000.0, "dt": 0.002, "t_end": 0.15,
                "resolution": 6, "size": 0.2, "damping": 0.0,
                "friction_velocity": 0.1}  # fmt: skip
    takes_mesh_file = True

    def create_mesh(self):
        """Return the cube [−T/2, T/2]² × [z₀, z₀ + T] above the cylinders.

        A body from ``--mesh PATH`` is fitted into the same box, its bottom at z₀.
        """
        size, n = self.parameters.size, self.parameters.resolution
        half, bottom = 0.5 * size, START * size
        box = ([-half, -half, bottom], [half, half, bottom + size])
        if self.mesh_file is not None:
            return self.read_mesh_file(box, anchor=(0, 0, -1))
        return dolfinx.mesh.create_box(self.comm, list(box), [n, n, n])

    def roller_offset(self) -> float:
        """Return the distance of each cylinder's axis from the plane x = 0."""
        size = self.parameters.size
        return 0.5 * GAP * size + ROLLER_RADIUS * size

    def obstacles(self):
        """Return the two cylinders along y at x = ±(T/6 + R), z = 0, turning as rollers.

        Each turns about its axis at ω = THROW_SPEED / R, the left one positively about y, the
        right one negatively, so that both surfaces move down through the nip.
        """
        radius, offset = ROLLER_RADIUS * self.parameters.size, self.roller_offset()
        rate = THROW_SPEED / radius
        return [
            Cylinder(
                (side * offset, 0.0, 0.0),
                (0.0, 1.0, 0.0),
                radius,
                motion=RigidMotion(
                    3,
                    angle=lambda t, sense=-side: sense * rate * t,
                    axis=(0.0, 1.0, 0.0),
                    pivot=(side * offset, 0.0, 0.0),
                ),
            )
            for side in (-1.0, 1.0)
        ]

    def initial_velocity(self):
        """Return the throw: (0, 0, −THROW_SPEED) everywhere."""

        def velocity(x):
            value = 0.0 * x
            value[2] = -THROW_SPEED
            return value

        return velocity

    def gravity(self):
        """Return (0, 0, −9.81) m/s²."""
        return GRAVITY

    def quantities(self, run):
        """Add the gap between the cylinders."""
        return {**super().quantities(run), "gap": GAP * self.parameters.size}
