"""Mattress: a 2D square held at two opposite sides and stretched (Fig. 1).

Quasi-static, plane strain: the left and right edges are clamped and pulled apart to three
times the width. Every element's singular values are saved after every load step
(``trajectories.npy``: elements × steps × 2, sorted, the sign on the smallest) for the
primary-contour report: the trajectories follow the model's primary contour, and the corotated
elements invert at large stretch where its contour crosses into the inverted region.
"""

from __future__ import annotations

import dolfinx
import numpy as np

from dolfinx_invertible.fem import CellSingularValues
from dolfinx_invertible.scenes.scene import Scene

__all__ = ["Mattress2D"]

#: Final width over rest width.
STRETCH = 3.0


class Mattress2D(Scene):
    """A square stretched by two sides, recording element trajectories in σ-space."""

    name = "mattress-2d"
    description = "2D square held at two sides and stretched to 3× its width; σ trajectories"
    figure = "Fig. 1"
    dynamic = False
    defaults = {"E": 1.0e3, "nu": 0.3, "steps": 20, "resolution": 8}

    def create_mesh(self):
        """Return the square [0, L]² of 2 n² triangles."""
        n, size = self.parameters.resolution, self.parameters.size
        return dolfinx.mesh.create_rectangle(self.comm, [[0.0, 0.0], [size, size]], [n, n])

    def boundary_conditions(self, space):
        """Clamp the left and right edges; they move apart along x."""
        mesh, size = space.mesh, self.parameters.size
        self._sides = []
        bcs = []
        for edge, sign in ((0.0, -1.0), (size, 1.0)):
            facets = dolfinx.mesh.locate_entities_boundary(
                mesh, 1, lambda x, edge=edge: np.isclose(x[0], edge)
            )
            value = dolfinx.fem.Function(space)
            bcs.append(
                dolfinx.fem.dirichletbc(
                    value, dolfinx.fem.locate_dofs_topological(space, 1, facets)
                )
            )
            self._sides.append((value, sign))
        return bcs, None

    def set_load(self, t: float) -> None:
        """Move the clamped sides apart: width STRETCH·L at t = 1."""
        shift = 0.5 * (STRETCH - 1.0) * self.parameters.size * t
        for value, sign in self._sides:
            value.x.array[0::2] = sign * shift
            value.x.array[1::2] = 0.0

    def record(self, run) -> None:
        """Sample every element's singular values."""
        if not hasattr(self, "_sampler"):
            self._sampler = CellSingularValues(run.u)
            self.trajectories: list[np.ndarray] = []
        self.trajectories.append(self._sampler())

    def files(self, run) -> dict:
        """Return the trajectories, elements × steps × 2."""
        return {"trajectories.npy": np.stack(self.trajectories, axis=1)}
