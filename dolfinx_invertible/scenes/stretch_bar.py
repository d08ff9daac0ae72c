"""Stretch bar: a bar pulled at both ends to a large stretch (Fig. 6).

Corotated elasticity drives elements into inversion and oscillates; fixed corotated does not
invert but its cross-section turns into an X; Neo-Hookean + C2 keeps a square section. The
summary reports the inverted cells and the shape of the mid cross-section:
``cross_section_ratio`` is (mean distance of the section's edge midpoints from its centre) /
(mean distance of its corners), divided by the square's 1/√2 — 1 for a square, below 1 for an
X-shaped section, about 1.41 for a round one.
"""

from __future__ import annotations

from mpi4py import MPI

import dolfinx
import numpy as np

from dolfinx_invertible.scenes.loading import smooth_ramp
from dolfinx_invertible.scenes.scene import Scene

__all__ = ["StretchBar"]

#: Final length over rest length: beyond 3 the corotated primary contour, Σ(σᵢ − 1) = 0, leaves
#: σ₂ + σ₃ = 3 − σ₁ < 0 for the cross-section: inverted.
STRETCH = 4.0
#: Cross-section edge over length.
SLENDERNESS = 0.2


class StretchBar(Scene):
    """A square bar pulled apart at its clamped ends."""

    name = "stretch-bar"
    description = "a bar pulled at both ends to 4 times its length; shape of its cross-section"
    figure = "Fig. 6"
    dynamic = True
    timed_by_end = True
    takes_self_contact = True
    defaults = {"E": 1.0e5, "nu": 0.45, "density": 1000.0, "dt": 0.01, "t_end": 1.2,
                "resolution": 4}  # fmt: skip

    @property
    def pull_time(self) -> float:
        """The ends move apart over the first 5/6 of the run, then hold."""
        return 5.0 / 6.0 * self.parameters.t_end

    def create_mesh(self):
        """Return the bar [0, L] × [0, L/5]²: ``resolution`` cells across, 5× as many along."""
        n, length = self.parameters.resolution, self.parameters.size
        width = SLENDERNESS * length
        return dolfinx.mesh.create_box(
            self.comm, [[0.0, 0.0, 0.0], [length, width, width]], [5 * n, n, n]
        )

    def boundary_conditions(self, space):
        """Clamp both ends; they move apart along x."""
        mesh, length = space.mesh, self.parameters.size
        self._pull = dolfinx.fem.Constant(mesh, 0.0)
        bcs = []
        for end, sign in ((0.0, -1.0), (length, 1.0)):
            facets = dolfinx.mesh.locate_entities_boundary(
                mesh, 2, lambda x, end=end: np.isclose(x[0], end)
            )
            dofs = dolfinx.fem.locate_dofs_topological(space, 2, facets)
            value = dolfinx.fem.Function(space)
            bcs.append((dolfinx.fem.dirichletbc(value, dofs), value, sign))

        def update(t: float) -> None:
            shift = 0.5 * (STRETCH - 1.0) * length * smooth_ramp(t, self.pull_time)
            for _, value, sign in bcs:
                value.x.array[0::3] = sign * shift
                value.x.array[1::3] = 0.0
                value.x.array[2::3] = 0.0

        return [bc for bc, _, _ in bcs], update

    def quantities(self, run) -> dict:
        """Return the mid cross-section's shape ratio at the end."""
        return {"cross_section_ratio": cross_section_ratio(run.u, self.parameters.size)}


def cross_section_ratio(u, length: float) -> float:
    """Edge-midpoint over corner distance of the section nearest x = L/2, over 1/√2."""
    space = u.function_space
    owned = space.dofmap.index_map.size_local
    X = space.tabulate_dof_coordinates()[:owned]
    x = X + u.x.array[: owned * 3].reshape(owned, 3)
    comm = space.mesh.comm
    candidates = np.abs(X[:, 0] - 0.5 * length)
    nearest = comm.allreduce(candidates.min() if owned else np.inf, op=MPI.MIN)
    section = np.isclose(candidates, nearest)
    width = SLENDERNESS * length
    offset = X[section, 1:] - 0.5 * width
    on_edge = np.isclose(np.abs(offset), 0.5 * width)
    corner = on_edge.all(axis=1)
    midpoint = on_edge.any(axis=1) & np.isclose(np.abs(offset), 0.0).any(axis=1)
    points = np.concatenate(comm.allgather(x[section, 1:]))
    centre = points.mean(axis=0)
    corners = np.concatenate(comm.allgather(x[section][corner, 1:]))
    midpoints = np.concatenate(comm.allgather(x[section][midpoint, 1:]))
    if len(corners) == 0 or len(midpoints) == 0:
        return float("nan")  # an odd resolution has no edge midpoints
    ratio = (
        np.linalg.norm(midpoints - centre, axis=1).mean()
        / np.linalg.norm(corners - centre, axis=1).mean()
    )
    return float(ratio * np.sqrt(2.0))
