"""The tetrahedra of the model gmsh has meshed, as arrays (the generated meshes' last step)."""

from __future__ import annotations

import numpy as np

__all__ = ["meshed_tetrahedra"]


def meshed_tetrahedra() -> tuple[np.ndarray, np.ndarray]:
    """Return (points (n, 3), tetrahedra (m, 4)) of gmsh's current model after ``generate(3)``.

    The nodes no tetrahedron uses (those of lower-dimensional entities only) are dropped and
    the rest numbered from 0.
    """
    import gmsh

    tags, coordinates, _ = gmsh.model.mesh.getNodes()
    points = coordinates.reshape(-1, 3)
    element_types, _, element_nodes = gmsh.model.mesh.getElements(3)
    tetrahedra = element_nodes[list(element_types).index(4)].reshape(-1, 4)
    index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    cells = index[tetrahedra.astype(np.int64)]
    used = np.unique(cells)
    renumber = np.zeros(len(points), dtype=np.int64)
    renumber[used] = np.arange(len(used))
    return points[used], renumber[cells]
