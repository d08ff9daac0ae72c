"""Meshes given by their vertices and cells, the same call on every supported DOLFINx."""

from __future__ import annotations

import dolfinx.mesh
import numpy as np

from dolfinx_invertible import _compat

__all__ = ["mesh_from_cells"]

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
