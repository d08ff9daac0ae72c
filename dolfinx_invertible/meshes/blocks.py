"""Several disjoint cubes in one mesh: the bodies of the multi-body scenes.

Each cube is a grid of n³ hexahedra split into 6 tetrahedra each (the Kuhn split, conforming
across hexahedra, as DOLFINx's ``create_box``), turned by its own rotation and moved to its
centre. The cubes share no vertex: each is one connected component of the mesh, one body for
:class:`~dolfinx_invertible.contact.BodyContactTerm`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dolfinx_invertible import _compat

__all__ = ["cube_cells", "cubes_mesh", "rotation"]

# The Kuhn split of the hexahedron with corners numbered a + 2b + 4c (offsets along x, y, z).
_KUHN = ((0, 1, 3, 7), (0, 1, 5, 7), (0, 2, 3, 7), (0, 2, 6, 7), (0, 4, 5, 7), (0, 4, 6, 7))


def cube_cells(resolution: int) -> tuple[np.ndarray, np.ndarray]:
    """Return the points, (n+1)³ × 3 in [−½, ½]³, and tetrahedra, 6n³ × 4, of a unit cube."""
    n = int(resolution)
    if n < 1:
        raise ValueError(f"resolution must be an integer >= 1, got {resolution!r}")
    line = np.linspace(-0.5, 0.5, n + 1)
    points = np.stack(np.meshgrid(line, line, line, indexing="ij"), axis=-1).reshape(-1, 3)
    i, j, k = (axis.ravel() for axis in np.meshgrid(*(np.arange(n),) * 3, indexing="ij"))
    corners = np.stack(
        [((i + a) * (n + 1) + (j + b)) * (n + 1) + (k + c) for c in (0, 1) for b in (0, 1)
         for a in (0, 1)],
        axis=1,
    )  # fmt: skip
    cells = np.concatenate([corners[:, list(tetrahedron)] for tetrahedron in _KUHN])
    return points, cells.astype(np.int64)


def rotation(angles: Sequence[float]) -> np.ndarray:
    """Return the rotation by ``angles`` (radians) about x, then y, then z, a 3 × 3 matrix."""
    rx, ry, rz = (float(angle) for angle in angles)
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    about_x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    about_y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    about_z = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return about_z @ about_y @ about_x


def cubes_mesh(
    comm,
    centres: np.ndarray,
    side: float,
    resolution: int,
    rotations: Sequence[np.ndarray] | None = None,
):
    """Return one mesh of ``len(centres)`` disjoint cubes of side ``side``.

    Parameters
    ----------
    comm
        The communicator; the mesh is built on rank 0 and distributed.
    centres
        The cubes' centres, (count, 3).
    side
        Their edge length.
    resolution
        Cells along each cube's edge.
    rotations
        One 3 × 3 rotation per cube (about its centre), or None for none.
    """
    centres = np.asarray(centres, dtype=np.float64).reshape(-1, 3)
    points, cells = cube_cells(resolution)
    if rotations is None:
        rotations = [np.eye(3)] * len(centres)
    all_points = np.concatenate(
        [centre + side * points @ turn.T for centre, turn in zip(centres, rotations, strict=True)]
    )
    all_cells = np.concatenate([cells + index * len(points) for index in range(len(centres))])
    return _compat.create_mesh_from_cells(comm, all_points, all_cells, "tetrahedron")
