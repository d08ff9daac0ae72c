"""Tet stretch: one tetrahedron, base held to a plane, top vertex pulled up (Figs. 3 and 4).

The base vertices may slide in their plane (one is pinned, one slides along a line, so that the
in-plane rigid motions are gone but the base may deform freely); the top vertex is pulled to
five times the height. The corotated model's primary contour draws the cross-section towards
the energy kink σ₂ + σ₃ = 0, where the stress jumps: the singular values oscillate from step to
step. The summary reports ``oscillation_amplitude``: the largest second difference of the
singular values between steps, divided by 4 (the amplitude of a step-to-step zigzag; smooth
motion gives a value of order dt²); ``singular_values.npy`` holds σ over the steps.
"""

from __future__ import annotations

import dolfinx
import numpy as np

from dolfinx_invertible.fem import CellSingularValues, mesh_from_cells
from dolfinx_invertible.scenes.loading import smooth_ramp
from dolfinx_invertible.scenes.scene import Scene

__all__ = ["TetStretch"]

#: Final height of the top vertex over its rest height.
STRETCH = 5.0
_HEIGHT = np.sqrt(2.0 / 3.0)
#: A regular tetrahedron of edge 1 (before scaling by ``size``): base in z = 0.
VERTICES = np.array(
    [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, np.sqrt(3.0) / 2.0, 0.0],
     [0.5, np.sqrt(3.0) / 6.0, _HEIGHT]]
)  # fmt: skip


class TetStretch(Scene):
    """One tetrahedron stretched through the corotated model's kink."""

    name = "tet-stretch"
    description = "one tetrahedron, base held to its plane, top vertex pulled to 5× its height"
    figure = "Figs. 3 and 4"
    dynamic = True
    timed_by_end = True
    defaults = {"E": 1.0e3, "nu": 0.3, "density": 1.0, "dt": 0.01, "t_end": 2.0,
                "resolution": 1}  # fmt: skip

    def create_mesh(self):
        """Return the single tetrahedron."""
        return mesh_from_cells(
            self.comm, self.parameters.size * VERTICES, np.array([[0, 1, 2, 3]]), "tetrahedron"
        )

    def boundary_conditions(self, space):
        """Hold the base in its plane (z = 0): one vertex pinned, one sliding along x."""
        mesh, size = space.mesh, self.parameters.size
        vertices = VERTICES * size
        # DOLFINx 0.9 and later locate dofs of vertices only once this is there.
        mesh.topology.create_connectivity(0, mesh.topology.dim)

        def at(index):
            return dolfinx.mesh.locate_entities(
                mesh, 0, lambda x: np.isclose(np.linalg.norm(x.T - vertices[index], axis=1), 0.0)
            )

        zero = np.float64(0.0)
        constraints = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2), (3, 0), (3, 1)]
        bcs = [
            dolfinx.fem.dirichletbc(
                zero, dolfinx.fem.locate_dofs_topological(space.sub(c), 0, at(v)), space.sub(c)
            )
            for v, c in constraints
        ]
        self._lift = dolfinx.fem.Constant(mesh, 0.0)
        top = dolfinx.fem.locate_dofs_topological(space.sub(2), 0, at(3))
        bcs.append(dolfinx.fem.dirichletbc(self._lift, top, space.sub(2)))

        def update(t: float) -> None:
            ramp = smooth_ramp(t, self.parameters.t_end)
            self._lift.value = (STRETCH - 1.0) * _HEIGHT * size * ramp

        return bcs, update

    def record(self, run) -> None:
        """Sample the singular values of the tetrahedron."""
        if not hasattr(self, "_sampler"):
            self._sampler = CellSingularValues(run.u)
            self.history: list[np.ndarray] = []
        self.history.append(self._sampler()[0])

    def quantities(self, run) -> dict:
        """Return the oscillation amplitude of the singular values."""
        sigma = np.array(self.history)
        if len(sigma) < 3:
            return {"oscillation_amplitude": 0.0}
        second = np.abs(sigma[2:] - 2.0 * sigma[1:-1] + sigma[:-2])
        return {"oscillation_amplitude": float(second.max() / 4.0)}

    def files(self, run) -> dict:
        """Return σ over the steps."""
        return {"singular_values.npy": np.array(self.history)}
