"""Checks of a user's mesh and boundary conditions, made before any solve."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from mpi4py import MPI

import numpy as np

from dolfinx_invertible import _compat

__all__ = ["check_boundary_conditions", "check_mesh", "mean_cell_size", "reference_cell_volumes"]

# A cell whose |volume| is below this fraction of the mean cell volume counts as degenerate.
_DEGENERATE_VOLUME = 1e-12


def reference_cell_volumes(mesh) -> np.ndarray:
    """Return a volume measure of every owned cell of the reference mesh.

    The determinant of the edges from the cell's first vertex: the volume of a simplex times d!,
    of a parallelogram or parallelepiped exactly. Enough to compare cells and to find a length
    scale, not an integral.
    """
    tdim = mesh.topology.dim
    cells = np.arange(mesh.topology.index_map(tdim).size_local, dtype=np.int32)
    geometry = mesh.geometry.x[:, :tdim]
    nodes = _compat.geometry_dofmap(mesh)[cells]
    # Simplices: the first tdim edges from vertex 0; quadrilaterals/hexahedra: the edges from
    # vertex 0 to its neighbours 1, 2 (and 4) in DOLFINx's tensor-product numbering.
    simplex = nodes.shape[1] == tdim + 1
    corners = (1, 2) if tdim == 2 else ((1, 2, 3) if simplex else (1, 2, 4))
    edges = np.stack([geometry[nodes[:, c]] - geometry[nodes[:, 0]] for c in corners], axis=1)
    return np.abs(np.linalg.det(edges))


def mean_cell_size(mesh) -> float:
    """Return the edge length of a cube (square) of the mean cell volume, over all ranks."""
    volumes = reference_cell_volumes(mesh)
    total = mesh.comm.allreduce(float(volumes.sum()), op=MPI.SUM)
    count = mesh.comm.allreduce(len(volumes), op=MPI.SUM)
    simplex_factor = 6.0 if mesh.topology.dim == 3 else 2.0
    if _compat.geometry_dofmap(mesh).shape[1] == mesh.topology.dim + 1:
        total /= simplex_factor
    return (total / max(count, 1)) ** (1.0 / mesh.topology.dim)


def check_mesh(mesh) -> None:
    """Refuse a reference mesh with degenerate (zero-volume) cells, naming them.

    DOLFINx does not orient cells, so the sign of a cell's volume carries no meaning there and
    the kernels integrate with |det J|; a cell of (near) zero volume has no valid reference
    configuration, and every quantity per unit reference volume is undefined on it.
    """
    tdim = mesh.topology.dim
    volumes = reference_cell_volumes(mesh)
    total = mesh.comm.allreduce(float(volumes.sum()), op=MPI.SUM)
    count = mesh.comm.allreduce(len(volumes), op=MPI.SUM)
    threshold = _DEGENERATE_VOLUME * total / max(count, 1)
    local_bad = np.flatnonzero(volumes <= threshold)
    global_ids = mesh.topology.index_map(tdim).local_range[0] + local_bad
    bad = mesh.comm.allgather(global_ids[:5].tolist())
    bad_count = mesh.comm.allreduce(len(local_bad), op=MPI.SUM)
    if bad_count:
        first = sorted(i for ids in bad for i in ids)[:5]
        raise ValueError(
            f"the reference mesh has {bad_count} degenerate (zero-volume) cells, first global "
            f"cell ids {first}; fix the mesh before solving"
        )


def check_boundary_conditions(bcs: Sequence[Any], comm) -> None:
    """Refuse Dirichlet conditions whose markers select no dof anywhere."""
    for index, bc in enumerate(bcs):
        owned = _compat.boundary_condition_dof_count(bc)
        if comm.allreduce(owned, op=MPI.SUM) == 0:
            raise ValueError(
                f"Dirichlet condition {index} constrains no degree of freedom: its marker or "
                "facet/dof selection matched nothing on the mesh"
            )
