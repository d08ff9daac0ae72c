"""Square, inversion-free: the classical route — a barrier energy kept feasible by the solver.

Dynamic, plane strain. A square stands on a fixed base; a frictionless rigid plate on its whole
top edge squashes it to 10 % of its height, holds it, and releases it. The default material is
plain Neo-Hookean (+∞ at J ≤ 0) with the inversion-free step limit (no Newton step may take a
point's volume below 10 % of its current value); run the same scene with ``--extension c2
--inversion-free`` unset to compare it with the invertible extension on the same mesh.
"""

from __future__ import annotations

import dolfinx
import numpy as np

from dolfinx_invertible.fem.checks import mean_cell_size
from dolfinx_invertible.scenes.loading import PressingPlate, smooth_ramp
from dolfinx_invertible.scenes.scene import Scene

__all__ = ["SquareInversionFree"]

DEPTH = 0.9
PRESS = 0.3
RELEASE = 0.45


class SquareInversionFree(Scene):
    """A square squashed and released; plain Neo-Hookean with the inversion-free cap."""

    name = "square-inv-free"
    description = "2D square squashed to 10 % and released: plain Neo-Hookean, inversion-free steps"
    figure = "the inversion-free line search (classical alternative)"
    dynamic = True
    timed_by_end = True
    relaxation = True
    defaults = {"E": 1.0e3, "nu": 0.3, "density": 1.0, "dt": 0.005, "t_end": 0.6,
                "resolution": 8, "extension": "none", "inversion_free": 0.1,
                "damping": 0.5}  # fmt: skip

    def create_mesh(self):
        """Return the square [0, L]² of 2 n² triangles."""
        n, size = self.parameters.resolution, self.parameters.size
        return dolfinx.mesh.create_rectangle(self.comm, [[0.0, 0.0], [size, size]], [n, n])

    def boundary_conditions(self, space):
        """Fix the base; the plate moves with time."""
        base = dolfinx.mesh.locate_entities_boundary(space.mesh, 1, lambda x: np.isclose(x[1], 0))
        bcs = [
            dolfinx.fem.dirichletbc(
                np.zeros(2), dolfinx.fem.locate_dofs_topological(space, 1, base), space
            )
        ]
        t_end, size = self.parameters.t_end, self.parameters.size

        def update(t: float) -> None:
            fraction = smooth_ramp(t, PRESS * t_end)
            self._plate.set(DEPTH * size * fraction, released=t > RELEASE * t_end)

        return bcs, update

    def external_energy(self, u):
        """Return the plate's penalty potential on the top edge."""
        mesh, size = u.function_space.mesh, self.parameters.size
        top = dolfinx.mesh.locate_entities_boundary(mesh, 1, lambda x: np.isclose(x[1], size))
        self._plate = PressingPlate(mesh, top, (0.0, -1.0), self.parameters.E, mean_cell_size(mesh))
        return self._plate.energy(u)
