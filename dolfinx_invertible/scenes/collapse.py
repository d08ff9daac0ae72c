"""Collapse: a unit cube with every vertex moved to its centre recovers its shape (Fig. 5 left).

Every vertex starts at 5 % of its distance from the centre (F = 0.05 I, 0.0125 % of the rest
volume), at rest and unsupported; implicit dynamics lets the body spring back. ``--mesh PATH``
collapses the body in a gmsh or XDMF file instead, towards its bounding box's centre.
"""

from __future__ import annotations

import dolfinx

from dolfinx_invertible.scenes.outcome import bounding_box
from dolfinx_invertible.scenes.scene import Scene

__all__ = ["Collapse"]

#: Initial deformation gradient F = SCALE · I.
SCALE = 0.05


class Collapse(Scene):
    """Cube collapsed to a point (F = 0.05 I) relaxing to rest."""

    name = "collapse"
    description = "cube with every vertex moved to its centre (F = 0.05 I) springs back"
    figure = "Fig. 5 (left)"
    dynamic = True
    takes_self_contact = True
    relaxation = True
    defaults = {"E": 1.0e3, "nu": 0.45, "density": 1.0, "dt": 0.01, "t_end": 0.4, "resolution": 4}
    takes_mesh_file = True

    def create_mesh(self):
        """Return the cube [0, L]³ with ``resolution`` cells per edge (6 tetrahedra each)."""
        n, size = self.parameters.resolution, self.parameters.size
        box = ([0.0] * 3, [size] * 3)
        if self.mesh_file is not None:
            return self.read_mesh_file(box, anchor=(-1, -1, -1))
        return dolfinx.mesh.create_box(self.comm, list(box), [n, n, n])

    def initial_displacement(self):
        """Return u₀ = (SCALE − 1)(x − centre), centre that of the body's bounding box."""
        low, high = bounding_box(self.mesh.geometry.x, self.comm)
        centre = (0.5 * (low + high))[:, None]

        def displacement(x):
            return (SCALE - 1.0) * (x - centre)

        return displacement
