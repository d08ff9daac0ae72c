"""The boundary vertices of a DOLFINx mesh that carry the contact barrier, and their weights.

Each vertex of the reference boundary gets the weight w = ∫_∂Ω₀ φ dA of its piecewise linear
(P1, or Q1 on quadrilateral and hexahedral cells) hat function φ over the exterior facets of the
reference mesh: every exterior facet gives 1/(number of its vertices) of its area to each of its
vertices (exactly so on simplices and parallelogram facets, where the hat integrates to that
share). The weights are assembled by DOLFINx with the ghost contributions summed into their
owners, so a vertex on a partition boundary gets the same weight on every rank; the contact
term then counts each vertex on the rank that owns its displacement dofs, once.
"""

from __future__ import annotations

from mpi4py import MPI

import dolfinx.fem
import dolfinx.fem.petsc
import numpy as np
import ufl
from petsc4py import PETSc

from dolfinx_invertible import _compat

__all__ = ["BoundaryVertices", "vertex_spacing"]

_FAMILIES = ("Lagrange", "Q", "CG")
_DEGREES = (1, 2)


def vertex_spacing(area: float, count: int, dimension: int) -> float:
    """Return h = (area / count)^(1/(d−1)): the spacing of ``count`` vertices on a boundary."""
    return (area / count) ** (1.0 / (dimension - 1))


class BoundaryVertices:
    """The owned boundary vertices of the displacement space ``space``.

    Works for vector Lagrange P1 and P2 displacements (on P2, the vertex dofs only: the
    barrier then does not see the edge and face nodes, see docs/contact.md).

    Parameters
    ----------
    space
        The vector function space of the displacement.

    Attributes
    ----------
    blocks
        Local block indices (into ``u.x.array`` divided by the block size) of the owned
        boundary vertices, (n,).
    dofs
        Their local dof indices, components interleaved, (n, d).
    reference
        Their reference coordinates, (n, d).
    weights
        Their shares of the reference boundary area (length in 2D), (n,).
    spacing
        The boundary vertex spacing h = (A / N)^(1/(d−1)) over all ranks: A the boundary area,
        N the number of boundary vertices; in 2D the mean boundary edge length.
    area
        A, the reference boundary area (length in 2D) over all ranks.
    count
        N, the number of boundary vertices over all ranks.
    """

    def __init__(self, space: dolfinx.fem.FunctionSpace) -> None:
        mesh = space.mesh
        dimension = mesh.geometry.dim
        family, degree = _compat.element_family_and_degree(space)
        if family not in _FAMILIES or degree not in _DEGREES:
            raise ValueError(
                f"contact needs vector Lagrange displacements of degree {_DEGREES}, got "
                f"{family} of degree {degree}"
            )
        block_size = space.dofmap.index_map_bs
        if block_size != dimension or mesh.topology.dim != dimension:
            raise ValueError(
                f"contact needs a displacement with {dimension} components on a "
                f"{dimension}D mesh, got {block_size} components on a {mesh.topology.dim}D mesh"
            )
        self.comm = mesh.comm
        self.dimension = dimension

        vertex_space = _compat.scalar_function_space(mesh, 1, "Lagrange")
        weight_form = dolfinx.fem.form(ufl.TestFunction(vertex_space) * ufl.ds(domain=mesh))
        vector = _compat.create_vector(weight_form)
        with vector.localForm() as local:
            local.set(0.0)
        dolfinx.fem.petsc.assemble_vector(vector, weight_form)
        vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with vector.localForm() as local:
            vertex_weights = local.array.copy()
        vector.destroy()

        # Vertex j of a cell holds the same vertex in both spaces: map P1 dofs to blocks.
        vertex_layout = vertex_space.dofmap.dof_layout
        layout = space.dofmap.dof_layout
        vertices = vertex_layout.num_dofs
        vertex_columns = [vertex_layout.entity_dofs(0, j)[0] for j in range(vertices)]
        columns = [layout.entity_dofs(0, j)[0] for j in range(vertices)]
        vertex_cells = _compat.cell_dofs(vertex_space)
        cells = _compat.cell_dofs(space)
        block_of_vertex = np.full(len(vertex_weights), -1, dtype=np.int64)
        block_of_vertex[vertex_cells[:, vertex_columns].ravel()] = cells[:, columns].ravel()

        owned_blocks = space.dofmap.index_map.size_local
        selected = np.flatnonzero(
            (vertex_weights > 0.0) & (block_of_vertex >= 0) & (block_of_vertex < owned_blocks)
        )
        self.blocks = block_of_vertex[selected].astype(np.int32)
        self.dofs = (self.blocks[:, None] * block_size + np.arange(dimension)[None, :]).astype(
            np.int32
        )
        coordinates = vertex_space.tabulate_dof_coordinates()
        self.reference = np.ascontiguousarray(coordinates[selected, :dimension])
        self.weights = vertex_weights[selected]
        self.area = float(self.comm.allreduce(float(np.sum(self.weights)), op=MPI.SUM))
        self.count = int(self.comm.allreduce(len(selected), op=MPI.SUM))
        if self.count == 0:
            raise ValueError("the mesh has no boundary vertices")
        self.spacing = vertex_spacing(self.area, self.count, dimension)

    def __len__(self) -> int:
        return len(self.blocks)

    def positions(self, displacement: np.ndarray) -> np.ndarray:
        """Return the positions X + u (n, d), u a local array laid out like ``u.x.array``."""
        return self.reference + displacement[self.dofs]
