"""The boundary surface of a distributed mesh, gathered whole onto every rank.

IPC Toolkit works on one shared-memory surface. The surface of a volume mesh has O(n^(2/3)) of
its n vertices, so :class:`GatheredSurface` gives every rank the whole surface once (its
triangles, or edges in 2D, by global vertex number) and, at each evaluation, every rank's owned
surface vertex positions (one ``Allgatherv`` of 3 numbers a surface vertex). Every rank then
computes the same contact terms on the same surface, and adds the rows of the vertices it owns:
no scatter back is needed, and the result does not depend on the number of ranks. The surface is
numbered by position, not by the partition's dof numbers, so that ipctk sees the same vertex and
facet order (which its collision sets and sums follow) on any number of ranks.

The bodies are the connected components of the surface: several disjoint bodies in one mesh
(several meshes merged, as in the cubes-in-bowl scene) are several components.
"""

from __future__ import annotations

import math

from mpi4py import MPI

import dolfinx
import dolfinx.fem
import numpy as np
import scipy.sparse
import scipy.sparse.csgraph

from dolfinx_invertible import _compat
from dolfinx_invertible.contact.boundary import vertex_spacing

__all__ = ["GatheredSurface"]


class GatheredSurface:
    """The whole boundary surface of the displacement space's mesh, on every rank.

    Works for vector Lagrange P1 and P2 displacements (on P2 the surface is made of the
    vertex dofs; the edge and face nodes do not take part in contact).

    Parameters
    ----------
    space
        The vector function space of the displacement.

    Attributes
    ----------
    dimension
        The mesh's geometric dimension, 2 or 3.
    reference
        Reference positions of all surface vertices, (N, d), the same on every rank; the
        surface vertices are numbered in the lexicographic order of these rows (x, then y,
        then z, on a grid of 2⁻³⁰ of the largest coordinate), so that the surface is the same
        on any number of ranks.
    facets
        The surface facets (triangles in 3D, segments in 2D) as rows of surface vertex
        numbers, (M, d), each row ascending, the rows in lexicographic order.
    global_blocks
        The global displacement block (vertex) number of each surface vertex, (N,).
    owned
        Surface vertex numbers whose displacement this rank owns, (n,).
    owned_dofs
        Their local dof indices into ``u.x.array``, components interleaved, (n, d).
    bodies
        The connected component of the surface each surface vertex belongs to, (N,).
    body_count
        The number of components.
    area
        The reference surface area (length in 2D).
    spacing
        h = (area / N)^(1/(d−1)): the surface vertex spacing, as for the obstacles' barrier.
    """

    def __init__(self, space: dolfinx.fem.FunctionSpace) -> None:
        mesh = space.mesh
        self.comm = mesh.comm
        dimension = mesh.geometry.dim
        family, degree = _compat.element_family_and_degree(space)
        block_size = space.dofmap.index_map_bs
        if family not in ("Lagrange", "CG", "P") or degree not in (1, 2):
            raise ValueError(
                f"contact between surfaces needs vector Lagrange displacements of degree 1 or 2, "
                f"got {family} of degree {degree}"
            )
        if mesh.topology.dim != dimension or block_size != dimension or dimension not in (2, 3):
            raise ValueError(
                "contact between surfaces needs a 2D or 3D mesh of simplices with a displacement "
                f"of as many components, got a {mesh.topology.dim}D mesh in {dimension}D with "
                f"{block_size} components"
            )
        self.dimension = dimension
        topology = mesh.topology
        tdim = topology.dim
        topology.create_connectivity(tdim - 1, tdim)
        topology.create_connectivity(tdim - 1, 0)
        topology.create_connectivity(tdim, 0)
        exterior = np.asarray(dolfinx.mesh.exterior_facet_indices(topology), dtype=np.int32)
        exterior = exterior[exterior < topology.index_map(tdim - 1).size_local]

        # Topology vertex → displacement block, through the cells (vertex j of a cell is the
        # dof layout's vertex j).
        layout = space.dofmap.dof_layout
        columns = [layout.entity_dofs(0, j)[0] for j in range(tdim + 1)]
        cell_blocks = _compat.cell_dofs(space)[:, columns]
        cell_vertices = _compat.connectivity_array(topology.connectivity(tdim, 0), tdim + 1)
        vertex_count = topology.index_map(0).size_local + topology.index_map(0).num_ghosts
        block_of_vertex = np.full(vertex_count, -1, dtype=np.int64)
        block_of_vertex[cell_vertices.ravel()] = cell_blocks.ravel()
        facet_vertices = _compat.connectivity_array(topology.connectivity(tdim - 1, 0), tdim)
        index_map = space.dofmap.index_map
        local_facets = block_of_vertex[facet_vertices[exterior]]
        global_facets = np.asarray(
            index_map.local_to_global(local_facets.ravel().astype(np.int32)), dtype=np.int64
        ).reshape(-1, tdim)

        everything = np.concatenate(self.comm.allgather(global_facets)).reshape(-1, tdim)
        blocks = np.unique(everything)
        self._block_size = block_size
        self._owned_range = (index_map.local_range[0], index_map.local_range[1])
        self._number(blocks)
        reference = self.gather(space.tabulate_dof_coordinates()[self._local_blocks, :dimension])
        # The surface in an order of its own, whatever the partition: vertices by their reference
        # coordinates, each facet's vertices ascending, the facets in ascending order (a facet on
        # a partition boundary, listed by two ranks, once). ipctk's collision sets and sums then
        # see the same surface on any number of ranks. The coordinates are compared on a grid of
        # 2^-30 of the largest one: a mesh made on several ranks can differ in the last bits of
        # a coordinate from the serial one (0 came out as 3e-17 on one partition and -1e-16 on
        # another), and vertices that close are not distinct.
        magnitude = float(np.abs(reference).max(initial=0.0)) or 1.0
        quantum = 2.0 ** (math.floor(math.log2(magnitude)) - 30)
        order = np.lexsort(np.round(reference / quantum).T[::-1])
        renumber = np.empty_like(order)
        renumber[order] = np.arange(len(order))
        self.facets = np.unique(
            np.sort(renumber[np.searchsorted(blocks, everything)], axis=1), axis=0
        ).astype(np.int32)
        self._number(blocks[order])
        self.reference = reference[order]

        adjacency = self._adjacency()
        self.body_count, self.bodies = scipy.sparse.csgraph.connected_components(
            adjacency, directed=False
        )
        self.area = float(np.sum(self.facet_measures(self.reference)))
        self.spacing = self.spacing_at(self.reference)

    def __len__(self) -> int:
        return len(self.global_blocks)

    def _number(self, global_blocks: np.ndarray) -> None:
        """Take ``global_blocks`` as the surface vertices, in that order: what each rank owns."""
        self.global_blocks = global_blocks
        start, stop = self._owned_range
        mine = (global_blocks >= start) & (global_blocks < stop)
        self.owned = np.flatnonzero(mine).astype(np.int32)
        self._local_blocks = (global_blocks[mine] - start).astype(np.int64)
        self.owned_dofs = (
            self._local_blocks[:, None] * self._block_size + np.arange(self.dimension)
        ).astype(np.int32)
        counts = np.asarray(self.comm.allgather(len(self.owned)), dtype=np.int64)
        self._counts = counts * self.dimension
        self._displacements = np.concatenate([[0], np.cumsum(self._counts)[:-1]])
        self._order = np.concatenate(self.comm.allgather(self.owned))
        if len(self._order) != len(global_blocks):
            raise RuntimeError("the surface vertices are not owned exactly once over the ranks")

    def _adjacency(self) -> scipy.sparse.csr_matrix:
        rows = np.repeat(self.facets, self.facets.shape[1], axis=1).ravel()
        columns = np.tile(self.facets, (1, self.facets.shape[1])).ravel()
        size = len(self.global_blocks)
        return scipy.sparse.csr_matrix(
            (np.ones(len(rows), dtype=np.int8), (rows, columns)), shape=(size, size)
        )

    def spacing_at(self, positions: np.ndarray) -> float:
        """Return the vertex spacing (area / N)^(1/(d−1)) of the surface at ``positions``."""
        area = float(np.sum(self.facet_measures(positions)))
        return vertex_spacing(area, len(self.global_blocks), self.dimension)

    def facet_measures(self, positions: np.ndarray) -> np.ndarray:
        """Areas (3D) or lengths (2D) of the surface facets at ``positions``, (M,)."""
        corners = positions[self.facets]
        if self.dimension == 2:
            return np.linalg.norm(corners[:, 1] - corners[:, 0], axis=1)
        normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        return 0.5 * np.linalg.norm(normal, axis=1)

    # -- per evaluation ---------------------------------------------------------------------
    def gather(self, owned_values: np.ndarray) -> np.ndarray:
        """Assemble the owned surface vertices' rows of every rank into one (N, d) array.

        ``owned_values`` has one row of d numbers per entry of :attr:`owned` (collective).
        """
        send = np.ascontiguousarray(owned_values, dtype=np.float64).reshape(-1)
        received = np.empty(int(self._counts.sum()), dtype=np.float64)
        self.comm.Allgatherv(send, [received, self._counts, self._displacements, MPI.DOUBLE])
        result = np.empty((len(self.global_blocks), self.dimension))
        result[self._order] = received.reshape(-1, self.dimension)
        return result

    def positions(self, displacement: np.ndarray) -> np.ndarray:
        """Return the current positions X + u of all surface vertices (collective), (N, d).

        ``displacement`` is a local array laid out like ``u.x.array``.
        """
        return self.reference + self.gather(displacement[self.owned_dofs])

    def motion(self, direction: np.ndarray) -> np.ndarray:
        """Return the surface vertices' rows of a local vector laid out like ``u.x.array``."""
        return self.gather(direction[self.owned_dofs])

    def global_dofs(self) -> np.ndarray:
        """Global dof numbers of the surface's unknowns, (N·d,), components interleaved."""
        return (self.global_blocks[:, None] * self.dimension + np.arange(self.dimension)).ravel()
