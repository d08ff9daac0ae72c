"""Meshes given by their vertices and cells, the same call on every supported DOLFINx.

Also :func:`reproducible_partitioning`: the same partition of a mesh on every run.
"""

from __future__ import annotations

import os

import dolfinx.mesh
import numpy as np

from dolfinx_invertible import _compat

__all__ = ["PARTITIONER_THREADS", "mesh_from_cells", "reproducible_partitioning"]

#: SCOTCH 7's setting of the threads it partitions with (read at every partition).
PARTITIONER_THREADS = "SCOTCH_PTHREAD_NUMBER"


def reproducible_partitioning() -> None:
    """Make DOLFINx partition a mesh the same way on every run with the same number of ranks.

    SCOTCH 7, DOLFINx's graph partitioner, partitions with several threads, and which thread
    gets there first changes the partition from one call to the next (measured: a 12³ × 6 box
    on 2 ranks split 5 188/5 180, 5 299/5 069, 5 222/5 146 cells in three runs). The order of
    every sum over a rank's cells changes with it, and a run whose Newton iterations amplify
    round-off (a tangled body crawling through its first step) then takes another path every
    time. One thread makes the partition a function of the mesh and the number of ranks only,
    and a run repeatable to the last bit. Call it before the mesh is created; a value of
    ``SCOTCH_PTHREAD_NUMBER`` already in the environment is left as it is.
    """
    os.environ.setdefault(PARTITIONER_THREADS, "1")


_CELL_TYPES = ("triangle", "tetrahedron")


def mesh_from_cells(
    comm, points: np.ndarray, cells: np.ndarray, cell_type: str
) -> dolfinx.mesh.Mesh:
    """Return a mesh of straight (degree-1) cells listed on rank 0, distributed over ``comm``.

    Parameters
    ----------
    comm
        The MPI communicator the mesh lives on.
    points
        Vertex coordinates, shape (vertices, geometric dimension). Read on rank 0; the other
        ranks pass an array of the same width, whose rows are ignored.
    cells
        The vertices of each cell as indices into ``points``, shape (cells, vertices per cell).
        Read on rank 0, like ``points``.
    cell_type
        ``"triangle"`` or ``"tetrahedron"``.

    Returns
    -------
    dolfinx.mesh.Mesh
        The mesh, partitioned by DOLFINx.
    """
    if cell_type not in _CELL_TYPES:
        raise ValueError(f"cell_type must be one of {', '.join(_CELL_TYPES)}, got {cell_type!r}")
    return _compat.create_mesh_from_cells(comm, np.asarray(points), np.asarray(cells), cell_type)
