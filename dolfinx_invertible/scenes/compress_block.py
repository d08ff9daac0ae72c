"""Compress block: a rigid plate presses a block far enough to invert elements, then lets go.

Dynamic. A block of 1 × 1 × ½ (times ``size``) stands on a fixed base; a frictionless rigid
plate (a stiff penalty on the normal displacement) presses the middle quarter of its top face
down by 80 % of the block's height over the first half of the loading time, holds it, and is
released at 40 % of the run; the block then relaxes. Under the plate's edges elements are
sheared through inversion; the invertible extension holds them there under load, and the
summary says whether the block recovered its shape after the release.
"""

from __future__ import annotations

import dolfinx
import numpy as np

from dolfinx_invertible.fem.checks import mean_cell_size
from dolfinx_invertible.scenes.loading import PressingPlate, smooth_ramp
from dolfinx_invertible.scenes.scene import Scene

__all__ = ["CompressBlock"]

#: Plate travel over the block height.
DEPTH = 0.8
#: Fractions of the run: the plate goes down until PRESS, holds until RELEASE.
PRESS = 0.25
RELEASE = 0.4


class CompressBlock(Scene):
    """A block squashed by a plate on part of its top, then released."""

    name = "compress-block"
    description = "a plate presses a block to 20 % of its height, inverting cells, then releases"
    figure = "engineering (inversion under load, recovery)"
    dynamic = True
    timed_by_end = True
    takes_self_contact = True
    relaxation = True
    defaults = {"E": 1.0e5, "nu": 0.45, "density": 1000.0, "dt": 0.01, "t_end": 1.0,
                "resolution": 4, "damping": 0.5}  # fmt: skip

    def create_mesh(self):
        """Return [0, L]² × [0, L/2] with ``resolution`` cells across the height."""
        n, size = self.parameters.resolution, self.parameters.size
        return dolfinx.mesh.create_box(
            self.comm, [[0.0, 0.0, 0.0], [size, size, 0.5 * size]], [2 * n, 2 * n, n]
        )

    def boundary_conditions(self, space):
        """Fix the base; the plate moves with time."""
        mesh = space.mesh
        base = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[2], 0.0))
        bcs = [
            dolfinx.fem.dirichletbc(
                np.zeros(3), dolfinx.fem.locate_dofs_topological(space, 2, base), space
            )
        ]
        t_end = self.parameters.t_end

        def update(t: float) -> None:
            self._plate.set(self.plate_depth(t), released=t > RELEASE * t_end)

        return bcs, update

    def plate_depth(self, t: float) -> float:
        """Return how far the plate has pressed the top face down at time t."""
        fraction = smooth_ramp(t, PRESS * self.parameters.t_end)
        return DEPTH * 0.5 * self.parameters.size * fraction

    def drawn_obstacles(self) -> list:
        """Return the plate as pictures draw it: a slab over the pressed square."""
        return [_DrawnPlate(self)]

    def external_energy(self, u):
        """Return the plate's penalty potential on the middle of the top face."""
        mesh, size = u.function_space.mesh, self.parameters.size

        def under_plate(x):
            return (
                np.isclose(x[2], 0.5 * size)
                & (np.abs(x[0] - 0.5 * size) <= 0.25 * size + 1e-12)
                & (np.abs(x[1] - 0.5 * size) <= 0.25 * size + 1e-12)
            )

        facets = dolfinx.mesh.locate_entities_boundary(mesh, 2, under_plate)
        self._plate = PressingPlate(
            mesh, facets, (0.0, 0.0, -1.0), self.parameters.E, mean_cell_size(mesh)
        )
        return self._plate.energy(u)


class _DrawnPlate:
    """The plate for pictures: a slab of a tenth of the block's size on the pressed square.

    Its bottom is where the plate holds the top face; once released it is drawn lifted clear
    of the block (the penalty is off: nothing presses). ``gap`` is the slab's signed distance.
    """

    #: It moves: an animation samples it at every frame.
    motion = True

    def __init__(self, scene: CompressBlock):
        self.scene = scene

    def gap(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        size, t_end = self.scene.parameters.size, self.scene.parameters.t_end
        thickness = 0.1 * size
        bottom = 0.5 * size - self.scene.plate_depth(t)
        if t > RELEASE * t_end:
            bottom = 0.5 * size + thickness
        centre = np.array([0.5 * size, 0.5 * size, bottom + 0.5 * thickness])
        half = np.array([0.25 * size, 0.25 * size, 0.5 * thickness])
        q = np.abs(np.asarray(x) - centre) - half
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        return outside + np.minimum(q.max(axis=1), 0.0)
