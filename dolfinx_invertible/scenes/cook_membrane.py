"""Cook's membrane: a tapered panel, clamped on one side, sheared by a dead load (benchmark).

Quasi-static. The panel (0, 0)-(48, 44)-(48, 60)-(0, 44) is clamped on its left edge and carries
a uniform vertical dead traction of 100/16 per unit length on its right edge (a total force of
100); Neo-Hookean Ψ = μ/2 (I₁ − 3) − μ ln J + λ/2 (ln J)² with E = 240.565 and ν = 0.4999 —
nearly incompressible, so plain linear elements lock and P2 is the default. Plane strain in 2D;
``--dimension 3`` extrudes the panel to a thickness of 10 with the faces z = const free. The
summary reports ``tip_displacement``, the vertical displacement of the corner (48, 60), beside
the published converged value 6.9083 (Elguedj et al. 2008, 128×128 elements).
"""

from __future__ import annotations

import dolfinx
import numpy as np
import ufl

from dolfinx_invertible.fem import PointValues
from dolfinx_invertible.scenes.scene import Scene

__all__ = ["REFERENCE_TIP_DISPLACEMENT", "CookMembrane", "cook_mesh"]

LENGTH = 48.0
LEFT_HEIGHT = 44.0
RIGHT_BOTTOM = 44.0
RIGHT_TOP = 60.0
THICKNESS = 10.0
#: Total vertical force on the right edge (per unit thickness in 2D).
FORCE = 100.0
#: Published converged tip displacement (Elguedj et al. 2008).
REFERENCE_TIP_DISPLACEMENT = 6.9083


def cook_mesh(comm, cells: int, dimension: int = 2, thickness_cells: int = 2):
    """Return the panel as a mapped unit square (triangles) or unit box (tetrahedra)."""
    if dimension == 2:
        mesh = dolfinx.mesh.create_unit_square(comm, cells, cells)
    else:
        mesh = dolfinx.mesh.create_box(
            comm, [np.zeros(3), np.ones(3)], [cells, cells, thickness_cells]
        )
    x = mesh.geometry.x
    xi, eta = x[:, 0].copy(), x[:, 1].copy()
    bottom = RIGHT_BOTTOM * xi
    top = LEFT_HEIGHT + (RIGHT_TOP - LEFT_HEIGHT) * xi
    x[:, 0] = LENGTH * xi
    x[:, 1] = bottom + eta * (top - bottom)
    if dimension == 3:
        x[:, 2] *= THICKNESS
    return mesh


class CookMembrane(Scene):
    """Cook's membrane, nearly incompressible Neo-Hookean, against the published tip value."""

    name = "cook-membrane"
    description = "tapered panel sheared by a dead load, ν = 0.4999; tip displacement vs 6.9083"
    figure = "benchmark (Cook; Elguedj et al. 2008)"
    dynamic = False
    defaults = {"E": 240.565, "nu": 0.4999, "extension": "none", "steps": 2, "resolution": 16,
                "degree": 2, "dimension": 2}  # fmt: skip
    choices = {"dimension": (2, 3)}

    def create_mesh(self):
        """Return the panel with ``resolution`` cells per side."""
        p = self.parameters
        return cook_mesh(self.comm, p.resolution, p.dimension, max(1, p.resolution // 8))

    def boundary_conditions(self, space):
        """Clamp the left edge."""
        mesh = space.mesh
        tdim = mesh.topology.dim
        facets = dolfinx.mesh.locate_entities_boundary(
            mesh, tdim - 1, lambda x: np.isclose(x[0], 0.0)
        )
        dofs = dolfinx.fem.locate_dofs_topological(space, tdim - 1, facets)
        return [dolfinx.fem.dirichletbc(np.zeros(tdim), dofs, space)], None

    def external_energy(self, u):
        """Return −∫ t·u ds on the right edge, t = (0, 100/16 per unit length) · load."""
        mesh = u.function_space.mesh
        tdim = mesh.topology.dim
        facets = dolfinx.mesh.locate_entities_boundary(
            mesh, tdim - 1, lambda x: np.isclose(x[0], LENGTH)
        )
        tags = dolfinx.mesh.meshtags(mesh, tdim - 1, facets, np.full(len(facets), 1, np.int32))
        ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags)
        self._traction = dolfinx.fem.Constant(mesh, np.zeros(tdim))
        self._full = np.zeros(tdim)
        # 100/16 per unit length of the edge (per unit area of the face in 3D).
        self._full[1] = FORCE / (RIGHT_TOP - RIGHT_BOTTOM)
        return -ufl.dot(self._traction, u) * ds(1)

    def set_load(self, t: float) -> None:
        """Scale the traction by the pseudo-time t."""
        self._traction.value[:] = t * self._full

    def quantities(self, run) -> dict:
        """Return the vertical tip displacement and the published value."""
        corner = [LENGTH, RIGHT_TOP] + ([0.5 * THICKNESS] if run.u.ufl_shape == (3,) else [])
        tip = PointValues(run.u, np.array([corner]))()[0, 1]
        return {
            "tip_displacement": float(tip),
            "reference_tip_displacement": REFERENCE_TIP_DISPLACEMENT,
            "relative_difference": float(tip / REFERENCE_TIP_DISPLACEMENT - 1.0),
        }
