"""Bowl drop: a soft cube falls into a bowl, hits the bottom, rocks and settles (Fig. 13).

A cube of side 0.4 m (``--size``) centred at the origin, at rest, inside the bowl |x| ≤ 1 m
(the inside of the unit sphere about the origin), falls under gravity (0, 0, −9.81) m/s²;
frictionless contact through the IPC barrier, continuous collision detection on every Newton
step. The bowl is fixed: no vertex is ever swept, the barrier and the collision-free step alone
keep the cube inside. ``--mesh PATH`` drops the body in a gmsh or XDMF file instead, centred at
the origin, scaled to fit the cube.

Defaults, and why:

- ``resolution`` 4 (4³ × 6 tetrahedra): enough cells for the cube to flex as it lands, small
  enough for a run of a few seconds;
- E = 5·10⁴ Pa, ν = 0.4, ρ = 1000 kg/m³: a soft gel; it hits the bottom at about 3.3 m/s
  (a fall of 0.56 m) and visibly squashes (the wave speed √(E/ρ) is 7 m/s);
- dt = 0.01 s, 2 s: the impact at t ≈ 0.4 s takes a few steps, and by 2 s backward Euler's
  dissipation and the damping have brought the bounce to rest;
- damping 0.01 of critical (about 1/s mass-proportional): a drag on the fall of under 1 %
  that lets the rocking die out within the run.
"""

from __future__ import annotations

from mpi4py import MPI

import dolfinx
import numpy as np

from dolfinx_invertible.contact import Sphere
from dolfinx_invertible.scenes.contact_scene import ContactScene

__all__ = ["BowlDrop"]

#: Radius of the bowl [m]; its centre is the cube's initial centre, the origin.
BOWL_RADIUS = 1.0
#: Gravity [m/s²].
GRAVITY = (0.0, 0.0, -9.81)


class BowlDrop(ContactScene):
    """A cube at rest in the middle of a bowl falls and settles at its bottom."""

    name = "bowl-drop"
    description = "a soft cube falls into a bowl, bounces and settles at the bottom (contact)"
    figure = "Fig. 13"
    defaults = {"E": 5.0e4, "nu": 0.4, "density": 1000.0, "dt": 0.01, "t_end": 2.0,
                "resolution": 4, "size": 0.4, "damping": 0.01}  # fmt: skip
    takes_mesh_file = True

    def create_mesh(self):
        """Return the cube of side ``size`` centred at the origin, ``resolution`` cells a side."""
        side, n = self.parameters.size, self.parameters.resolution
        half = 0.5 * side
        box = ([-half] * 3, [half] * 3)
        if self.mesh_file is not None:
            mesh = self.read_mesh_file(box, anchor=(0, 0, 0))
            radius = np.linalg.norm(mesh.geometry.x, axis=1).max(initial=0.0)
            if not self.comm.allreduce(radius, op=MPI.MAX) < BOWL_RADIUS:
                raise ValueError(
                    f"--size {side:g}: the body in {self.mesh_file} does not fit into the bowl "
                    f"of radius {BOWL_RADIUS:g} m"
                )
            return mesh
        # Its corners are √3 side/2 from the centre: the cube must fit into the bowl.
        if not 3**0.5 * side / 2 < BOWL_RADIUS:
            raise ValueError(
                f"--size {side:g}: the cube does not fit into the bowl of radius "
                f"{BOWL_RADIUS:g} m (its half-diagonal must be smaller)"
            )
        return dolfinx.mesh.create_box(self.comm, list(box), [n, n, n])

    def obstacles(self):
        """Return the bowl: the inside of the sphere of radius 1 m about the origin."""
        return [Sphere((0.0, 0.0, 0.0), BOWL_RADIUS, inside=True)]

    def gravity(self):
        """Return (0, 0, −9.81) m/s²."""
        return GRAVITY

    def rest_height(self) -> float | None:
        """Return the height of the centre of a rigid cube resting flat at the bowl's bottom.

        The corners of its bottom face touch the sphere, at a distance √2 side/2 from the axis.
        None for a body from a mesh file.
        """
        if self.mesh_file is not None:
            return None
        half = 0.5 * self.parameters.size
        return -((BOWL_RADIUS**2 - 2.0 * half**2) ** 0.5) + half

    def quantities(self, run):
        """Add the rigid resting height of the centre to the contact figures."""
        return {**super().quantities(run), "rest_centre_height": self.rest_height()}
