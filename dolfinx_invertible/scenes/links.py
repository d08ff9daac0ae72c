"""Links: a chain of elastic rings hangs from its top ring and catches itself (Fig. 12).

``count`` rings (default 3) of outer diameter ``size`` (0.25 m; tube radius a tenth of it),
each a quarter turn from the last and passing through the next one's hole, start at rest with a
clearance of 0.8 tube radii between linked tubes (:mod:`~dolfinx_invertible.meshes.rings`).
The top of the first ring is held; gravity pulls the others down until each hangs on the one
above, and the chain swings and stretches. Rings meet only each other, through IPC Toolkit
(:class:`~dolfinx_invertible.contact.BodyContactTerm`): they stay linked, never pass through
each other, and every stored step records ``min_distance`` and ``intersections``.

Defaults, and why:

- ``resolution`` 1: cells of the tube's radius, 1 654 tetrahedra for three rings (the direct
  solver's size; ``--resolution 2`` gives 10 124, solved iteratively: 41.7 s on 2 ranks against
  about 9 s);
- E = 10⁶ Pa, ν = 0.4, ρ = 1000 kg/m³: a rubber; caught after a fall of 2 cm, the chain
  stretches by about 8 cm and bounces;
- dt = 0.005 s, 0.5 s: each ring falls 0.8 tube radii (2 cm) in about 0.06 s and is caught.
"""

from __future__ import annotations

import dolfinx
import dolfinx.fem
import numpy as np

from dolfinx_invertible.meshes import rings
from dolfinx_invertible.scenes.outcome import bounding_box
from dolfinx_invertible.scenes.scene import Scene

__all__ = ["Links"]

#: Tube radius relative to the ring's outer diameter.
TUBE = 0.1
#: Clearance between linked tubes at the start, in tube radii.
CLEARANCE = 0.8
#: Gravity [m/s²].
GRAVITY = (0.0, 0.0, -9.81)


class Links(Scene):
    """A hanging chain of rings held at its top."""

    name = "links"
    description = "a chain of elastic rings hangs from its top ring (contact between bodies, ipctk)"
    figure = "Fig. 12"
    defaults = {"E": 1.0e6, "nu": 0.4, "density": 1000.0, "dt": 0.005, "t_end": 0.5,
                "resolution": 1, "size": 0.25, "count": 3}  # fmt: skip
    several_bodies = True

    @property
    def radii(self) -> tuple[float, float]:
        """(R, r): the radius of a ring's centre line and its tube's radius."""
        minor = TUBE * self.parameters.size
        return 0.5 * self.parameters.size - minor, minor

    def create_mesh(self):
        """Return the chain: ring 0 centred at the origin, the others below it."""
        major, minor = self.radii
        return rings.mesh(
            self.comm,
            count=self.parameters.count,
            major=major,
            minor=minor,
            clearance=CLEARANCE * minor,
            resolution=self.parameters.resolution,
        )

    def boundary_conditions(self, space):
        """Hold the top of ring 0: its points above the centre line of its top arc."""
        major, _ = self.radii
        dofs = dolfinx.fem.locate_dofs_geometrical(space, lambda x: x[2] > major)
        held = dolfinx.fem.Function(space)
        return [dolfinx.fem.dirichletbc(held, dofs)], None

    def gravity(self):
        """Return (0, 0, −9.81) m/s²."""
        return GRAVITY

    def initial_lowest(self) -> float:
        """Height of the chain's lowest point at the start [m]."""
        major, minor = self.radii
        pitch = rings.ring_pitch(major, minor, CLEARANCE * minor)
        return -(self.parameters.count - 1) * pitch - major - minor

    def quantities(self, run):
        """Return the lowest point of the chain at the start and at the end (z, m)."""
        low, _ = bounding_box(
            run.u.function_space.tabulate_dof_coordinates() + _node_displacements(run.u),
            self.comm,
        )
        return {"initial_lowest": self.initial_lowest(), "final_lowest": float(low[2])}


def _node_displacements(u) -> np.ndarray:
    """U at the dof nodes, (nodes, 3), ghosts included."""
    return u.x.array.reshape(-1, 3)
