"""Triangles: three free triangles relax from different deformations (Fig. 2).

Three separate triangles, unsupported and at rest, start deformed by three different
deformation gradients (one inverted, one stretched, one sheared and compressed) and relax by
implicit dynamics. Their singular-value trajectories (``trajectories.npy``: 3 × steps × 2) show
how each model leads them home: the corotated model takes one through inversion. The summary
reports, per triangle, the smallest J on the way (``min_J_per_triangle``) and whether one that
started uninverted passed through inversion (``inverted_on_the_way``).
"""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.fem import CellSingularValues, mesh_from_cells
from dolfinx_invertible.scenes.scene import Scene

__all__ = ["Triangles2D"]

#: Initial deformation gradients of the three triangles.
DEFORMATIONS = (
    np.array([[-0.6, 0.0], [0.0, 1.3]]),  # inverted
    # Stretched and thinned, σ = (2.6, 0.2): the corotated primary contour σ₁ + σ₂ = 2 is
    # reached in the inverted half, so that model drives this triangle through inversion.
    np.array([[2.6, 0.0], [0.0, 0.2]]),
    np.array([[0.4, 0.9], [0.0, 0.3]]),  # sheared and compressed
)
_TRIANGLE = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, np.sqrt(3.0) / 2.0]])
#: Spacing of the triangles along x (they never touch: there is no contact between them).
SPACING = 4.0


class Triangles2D(Scene):
    """Three triangles relaxing from inverted, stretched and sheared starts."""

    name = "triangles-2d"
    description = "three free triangles relax from an inverted, a stretched and a sheared start"
    figure = "Fig. 2"
    dynamic = True
    # ν = 0.49: the volume term dominates, and the corotated contour σ₁ + σ₂ = 2 leads the
    # stretched triangle through inversion.
    defaults = {"E": 1.0e3, "nu": 0.49, "density": 1.0, "dt": 0.002, "t_end": 0.4,
                "resolution": 1}  # fmt: skip

    def create_mesh(self):
        """Return the three triangles, side by side."""
        size = self.parameters.size
        points = np.concatenate([size * (_TRIANGLE + [SPACING * k, 0.0]) for k in range(3)])
        cells = np.arange(9).reshape(3, 3)
        return mesh_from_cells(self.comm, points, cells, "triangle")

    def initial_displacement(self):
        """Return u₀ = (F_k − I)(x − centroid_k) on triangle k."""
        size = self.parameters.size
        centroids = [size * (_TRIANGLE.mean(axis=0) + [SPACING * k, 0.0]) for k in range(3)]

        def displacement(x):
            result = np.zeros((2, x.shape[1]))
            which = np.clip(np.round((x[0] / size - 0.5) / SPACING).astype(int), 0, 2)
            for k, F in enumerate(DEFORMATIONS):
                here = which == k
                offset = x[:2, here] - centroids[k][:, None]
                result[:, here] = (F - np.eye(2)) @ offset
            return result

        return displacement

    def record(self, run) -> None:
        """Sample the three triangles' singular values."""
        if not hasattr(self, "_sampler"):
            self._sampler = CellSingularValues(run.u)
            self.trajectories: list[np.ndarray] = []
        self.trajectories.append(self._sampler())

    def quantities(self, run) -> dict:
        """Return per triangle the smallest J on the way and whether it passed inversion."""
        sigma = self.files(run)["trajectories.npy"]
        J = np.prod(sigma, axis=2)
        smallest = J.min(axis=1)
        return {
            "min_J_per_triangle": smallest.tolist(),
            "inverted_on_the_way": ((J[:, 0] > 0.0) & (smallest <= 0.0)).tolist(),
        }

    def files(self, run) -> dict:
        """Return the trajectories, 3 × steps × 2, in the order of DEFORMATIONS."""
        order = np.argsort(self._sampler.midpoints[:, 0])
        return {"trajectories.npy": np.stack(self.trajectories, axis=1)[order]}
