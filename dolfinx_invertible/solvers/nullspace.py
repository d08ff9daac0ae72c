"""Rigid-body modes of a vector space, the near-nullspace algebraic multigrid builds from."""

from __future__ import annotations

from mpi4py import MPI

import dolfinx.fem
import numpy as np
from petsc4py import PETSc

__all__ = ["rigid_body_near_nullspace"]


def rigid_body_near_nullspace(space: dolfinx.fem.FunctionSpace) -> PETSc.NullSpace:
    """Orthonormal rigid-body modes of a vector space: translations and infinitesimal rotations.

    Three translations and three rotations in 3D, two and one in 2D; algebraic multigrid (GAMG)
    builds its coarse spaces from them. Values come from the dof coordinates, so any nodal
    (Lagrange) vector space works.

    Parameters
    ----------
    space
        Vector function space with one component per geometric dimension.

    Returns
    -------
    PETSc.NullSpace
        Near-nullspace for ``Mat.setNearNullSpace`` on matrices of ``space``.
    """
    dimension = space.mesh.geometry.dim
    block_size = space.dofmap.index_map_bs
    if block_size != dimension:
        raise ValueError(
            f"space: expected {dimension} components per node (a vector space), got {block_size}"
        )
    comm = space.mesh.comm
    owned = space.dofmap.index_map.size_local
    coordinates = space.tabulate_dof_coordinates()[:owned, :dimension]
    # Centring keeps rotations far from translations on meshes placed far from the origin, where
    # Gram–Schmidt would otherwise cancel most digits.
    total = comm.allreduce(owned, op=MPI.SUM)
    centre = comm.allreduce(coordinates.sum(axis=0), op=MPI.SUM) / max(total, 1)
    coordinates = coordinates - centre

    modes: list[np.ndarray] = []
    for component in range(dimension):
        mode = np.zeros((owned, dimension))
        mode[:, component] = 1.0
        modes.append(mode)
    # Rotation about axis k moves component i by -x_j and component j by +x_i.
    planes = [(0, 1)] if dimension == 2 else [(0, 1), (1, 2), (2, 0)]
    for i, j in planes:
        mode = np.zeros((owned, dimension))
        mode[:, i] = -coordinates[:, j]
        mode[:, j] = coordinates[:, i]
        modes.append(mode)

    vectors = []
    for mode in modes:
        vector = PETSc.Vec().createMPI(
            (owned * block_size, PETSc.DECIDE), bsize=block_size, comm=comm
        )
        vector.setArray(mode.reshape(-1))
        vectors.append(vector)
    # Modified Gram–Schmidt: PETSc requires an orthonormal basis.
    for index, vector in enumerate(vectors):
        for previous in vectors[:index]:
            vector.axpy(-vector.dot(previous), previous)
        vector.normalize()
    return PETSc.NullSpace().create(vectors=vectors, comm=comm)
