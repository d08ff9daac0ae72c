"""A user's mesh file (gmsh ``.msh`` or XDMF), checked on rank 0 and distributed by DOLFINx.

Every check runs before a scene computes anything and fails with a :class:`MeshFileError`
naming the file and, where one is at fault, the cell (its index among the file's cells of the
body's type, counted from 0, and its vertices):

- the file cannot be read, or holds no cells of the body's dimension (a surface mesh only);
- cells of more than one type in that dimension (tetrahedra and hexahedra, say), or curved
  (second-order) cells: the body must be straight tetrahedra in 3D, triangles in 2D;
- a cell of zero volume (below 10⁻¹⁰ of the mean) or an inverted one: a cell that overlaps a
  neighbour, its vertex opposite a shared face on the same side as the neighbour's (a test
  that does not depend on the order a mesher lists vertices in), or a face shared by more than
  two cells;
- several pieces (connected through shared faces) where the scene needs one body.

Vertices no cell uses are dropped. A scene then fits the body into the box its own body
occupies (:func:`fit_into_box`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from dolfinx_invertible.fem.mesh import mesh_from_cells

__all__ = [
    "SUFFIXES",
    "MeshFileError",
    "check_cells",
    "fit_into_box",
    "is_mesh_file",
    "read_cells",
    "read_mesh",
]

#: File name endings :func:`read_mesh` reads (case does not matter).
SUFFIXES = (".msh", ".xdmf")
#: A cell below this fraction of the mean cell volume has none.
ZERO_VOLUME = 1e-10
#: meshio's name, DOLFINx's name and the plural of the straight cell of each dimension.
_BODY_CELLS = {3: ("tetra", "tetrahedron", "tetrahedra"), 2: ("triangle", "triangle", "triangles")}
_CELL_DIMENSIONS = {
    "vertex": 0, "line": 1, "line3": 1, "triangle": 2, "triangle6": 2, "quad": 2, "quad8": 2,
    "quad9": 2, "polygon": 2, "tetra": 3, "tetra10": 3, "hexahedron": 3, "hexahedron20": 3,
    "hexahedron27": 3, "wedge": 3, "wedge15": 3, "pyramid": 3, "pyramid13": 3,
}  # fmt: skip


class MeshFileError(ValueError):
    """A mesh file a scene cannot use; the message names the file and what is wrong."""


def is_mesh_file(value: str | Path) -> bool:
    """Return whether ``value`` names a mesh file by its ending (``.msh``, ``.xdmf``)."""
    return Path(value).suffix.lower() in SUFFIXES


def read_cells(path: str | Path, dimension: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Return (points (n, 3), cells (m, dimension + 1)) of the body in a mesh file.

    Reads on the calling process only (meshio). Cells of lower dimension (a gmsh file's
    boundary triangles, lines and points) are ignored; vertices no body cell uses are dropped.

    Raises
    ------
    MeshFileError
        The file is missing, unreadable, or its body is not one type of straight simplex of
        the given dimension.
    """
    path = Path(path)
    if not is_mesh_file(path):
        raise MeshFileError(f"{path}: a mesh file must end in {' or '.join(SUFFIXES)}")
    if not path.is_file():
        raise MeshFileError(f"{path}: no such file")
    import meshio.gmsh
    import meshio.xdmf

    # meshio's own readers, not meshio.read: that one prints and exits the process on failure.
    reader = meshio.gmsh.read if path.suffix.lower() == ".msh" else meshio.xdmf.read
    try:
        data = reader(str(path))
    except Exception as error:  # meshio raises many types, all of them "unreadable"
        raise MeshFileError(
            f"{path}: cannot read the mesh ({type(error).__name__}: {error})"
        ) from error
    expected, _, plural = _BODY_CELLS[dimension]
    blocks: dict[str, list[np.ndarray]] = {}
    for block in data.cells:
        blocks.setdefault(block.type, []).append(np.asarray(block.data))
    top = max((_CELL_DIMENSIONS.get(name, -1) for name in blocks), default=-1)
    if top < dimension:
        found = ", ".join(f"{sum(len(b) for b in blocks[n])} {n}" for n in blocks) or "no cells"
        raise MeshFileError(
            f"{path}: the scene needs a {dimension}D body of {plural}; the file holds "
            f"{found} (mesh the volume, e.g. gmsh -{dimension})"
        )
    if top > dimension:
        raise MeshFileError(
            f"{path}: the mesh is {top}D; the scene needs a {dimension}D body of {plural}"
        )
    body_types = [name for name in blocks if _CELL_DIMENSIONS.get(name) == dimension]
    if body_types != [expected]:
        if len(body_types) > 1:
            raise MeshFileError(
                f"{path}: mixed cell types {', '.join(body_types)}; the scene needs {plural} only"
            )
        raise MeshFileError(
            f"{path}: the body's cells are {body_types[0]}; the scene needs straight (first-"
            f"order) {plural} (gmsh: -order 1; other cell types: split into simplices)"
        )
    cells = np.concatenate(blocks[expected]).astype(np.int64)
    points = np.asarray(data.points, dtype=np.float64)
    if points.shape[1] < 3:
        points = np.hstack([points, np.zeros((len(points), 3 - points.shape[1]))])
    used, cells = np.unique(cells, return_inverse=True)
    return points[used], cells.reshape(-1, dimension + 1)


def check_cells(
    path: str | Path, points: np.ndarray, cells: np.ndarray, *, one_body: bool = True
) -> None:
    """Raise :class:`MeshFileError` for a zero-volume, inverted or disconnected body.

    ``cells`` are straight simplices (triangles or tetrahedra) indexing ``points`` (n, 3).
    """
    dimension = cells.shape[1] - 1
    corners = points[cells][:, :, :dimension]
    volumes = _signed_volumes(corners[:, 1:] - corners[:, :1])
    mean = np.abs(volumes).mean()
    flat = np.flatnonzero(np.abs(volumes) <= ZERO_VOLUME * mean)
    if len(flat):
        raise MeshFileError(
            f"{path}: {len(flat)} cell(s) of zero volume, the first "
            f"{_describe(flat[0], cells, points)}"
        )
    faces, owners, opposite = _faces(cells)
    order = np.lexsort(faces.T[::-1])
    faces, owners, opposite = faces[order], owners[order], opposite[order]
    same = np.all(faces[1:] == faces[:-1], axis=1)
    if np.any(same[1:] & same[:-1]):
        first = np.flatnonzero(same[1:] & same[:-1])[0]
        raise MeshFileError(
            f"{path}: a face shared by more than two cells, one of them "
            f"{_describe(owners[first], cells, points)}"
        )
    pairs = np.flatnonzero(same)
    left, right = owners[pairs], owners[pairs + 1]
    base = points[faces[pairs]][:, :, :dimension]
    sides = [
        np.sign(_signed_volumes(base[:, 1:] - base[:, :1], points[tip][:, :dimension] - base[:, 0]))
        for tip in (opposite[pairs], opposite[pairs + 1])
    ]
    overlapping = np.flatnonzero(sides[0] == sides[1])
    if len(overlapping):
        first = overlapping[np.argmin(np.minimum(left, right)[overlapping])]
        cell, neighbour = sorted((left[first], right[first]))
        raise MeshFileError(
            f"{path}: inverted cells: {_describe(cell, cells, points)} overlaps its neighbour "
            f"{neighbour} (they lie on the same side of their shared face)"
        )
    if one_body:
        pieces, labels = _pieces(len(cells), left, right)
        if pieces > 1:
            stray = int(np.flatnonzero(labels != labels[0])[0])
            raise MeshFileError(
                f"{path}: {pieces} disconnected pieces where the scene needs one body "
                f"(cell 0 and {_describe(stray, cells, points)} are not connected through faces)"
            )


def read_mesh(
    comm,
    path: str | Path,
    *,
    box: tuple[Sequence[float], Sequence[float]] | None = None,
    anchor: Sequence[int] | None = None,
    dimension: int = 3,
    one_body: bool = True,
):
    """Return the body in a mesh file, checked, fitted into a box, distributed over ``comm``.

    Parameters
    ----------
    comm
        The communicator; rank 0 reads and checks the file, DOLFINx partitions the mesh.
    path
        A gmsh ``.msh`` (any version meshio reads, physical groups or not) or an XDMF mesh.
    box
        (low, high) corners: the body is scaled, the same in every direction, to the largest
        size that fits into the box, and placed in it by ``anchor``; ``None`` keeps the file's
        coordinates.
    anchor
        Per direction, where the body sits in the box: −1 against its low side, 0 centred, +1
        against its high side (default: centred in every direction).
    dimension
        3 for tetrahedra, 2 for triangles (their z coordinates must be 0).
    one_body
        Refuse a mesh of several disconnected pieces.

    Raises
    ------
    MeshFileError
        On every rank, before any mesh is built (see the module description).
    """
    points = np.zeros((0, 3))
    cells = np.zeros((0, dimension + 1), dtype=np.int64)
    message = None
    if comm.rank == 0:
        try:
            points, cells = read_cells(path, dimension)
            if dimension == 2 and np.any(points[:, 2] != 0.0):
                raise MeshFileError(f"{path}: a 2D mesh must lie in the plane z = 0")
            check_cells(path, points, cells, one_body=one_body)
        except MeshFileError as error:
            message = str(error)
    message = comm.bcast(message, root=0)
    if message is not None:
        raise MeshFileError(message)
    points = points[:, :dimension]
    if box is not None:
        points = fit_into_box(points, box, (0,) * dimension if anchor is None else anchor)
    return mesh_from_cells(comm, points, cells, _BODY_CELLS[dimension][1])


def fit_into_box(
    points: np.ndarray, box: tuple[Sequence[float], Sequence[float]], anchor: Sequence[int]
) -> np.ndarray:
    """Return the points scaled uniformly to the largest size that fits the box, and placed.

    ``anchor`` per direction: −1 the points' low side on the box's, 0 centred, +1 high sides.
    """
    if len(points) == 0:
        return points
    low, high = points.min(axis=0), points.max(axis=0)
    box_low, box_high = (np.asarray(corner, dtype=float) for corner in box)
    extent, room = high - low, box_high - box_low
    scale = np.min(room[extent > 0] / extent[extent > 0])
    side = np.asarray(anchor, dtype=float)
    # The point of the body at relative position (side + 1)/2 goes to the same one of the box.
    weight = 0.5 * (side + 1.0)
    source = low + weight * extent
    target = box_low + weight * room
    return (points - source) * scale + target


def _signed_volumes(edges: np.ndarray, last: np.ndarray | None = None) -> np.ndarray:
    """Return the determinants of edges (cells, d, d), or of (d − 1 edges, last) with ``last``."""
    if last is not None:
        edges = np.concatenate([edges, last[:, None, :]], axis=1)
    return np.linalg.det(edges)


def _faces(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (cell, local face) as sorted vertices, its cell and the vertex opposite it."""
    count, corners = cells.shape
    faces = np.concatenate([np.delete(cells, local, axis=1) for local in range(corners)])
    owners = np.tile(np.arange(count), corners)
    opposite = cells.T.reshape(-1)
    return np.sort(faces, axis=1), owners, opposite


def _pieces(count: int, left: np.ndarray, right: np.ndarray) -> tuple[int, np.ndarray]:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    graph = coo_matrix((np.ones(len(left)), (left, right)), shape=(count, count))
    return connected_components(graph, directed=False)


def _describe(cell: int, cells: np.ndarray, points: np.ndarray) -> str:
    centre = points[cells[cell]].mean(axis=0)
    return f"cell {int(cell)} (centroid {', '.join(f'{value:.6g}' for value in centre)})"
