"""An independent check that no two surface triangles of a tetrahedral mesh cross.

Plain NumPy, no IPC Toolkit: the boundary triangles are the faces of one tetrahedron only; a
pair of triangles crosses where an edge of one passes through the other (Möller–Trumbore, with
the triangle's and the edge's closed ranges). Pairs that share a vertex are not tested.
"""

import numpy as np


def boundary_triangles(cells: np.ndarray) -> np.ndarray:
    """The faces that belong to one tetrahedron of ``cells`` (n, 4), (m, 3)."""
    faces = np.concatenate([cells[:, [1, 2, 3]], cells[:, [0, 2, 3]], cells[:, [0, 1, 3]],
                            cells[:, [0, 1, 2]]])  # fmt: skip
    key = np.sort(faces, axis=1)
    _, index, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
    return faces[index[counts == 1]]


def crossing_pairs(points: np.ndarray, triangles: np.ndarray, chunk: int = 4096) -> int:
    """The number of (edge, triangle) pairs of the surface that cross, edges of the triangles."""
    edges = np.unique(
        np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]),
                axis=1),
        axis=0,
    )  # fmt: skip
    a, b, c = (points[triangles[:, k]] for k in range(3))
    low = np.minimum(np.minimum(a, b), c)
    high = np.maximum(np.maximum(a, b), c)
    found = 0
    for start in range(0, len(edges), chunk):
        block = edges[start : start + chunk]
        p, q = points[block[:, 0]], points[block[:, 1]]
        # Bounding boxes first: only overlapping (edge, triangle) boxes are tested exactly.
        overlap = np.all(
            (np.minimum(p, q)[:, None, :] <= high[None])
            & (np.maximum(p, q)[:, None, :] >= low[None]),
            axis=2,
        )
        shares = (block[:, None, :, None] == triangles[None, :, None, :]).any(axis=(2, 3))
        edge_index, triangle_index = np.nonzero(overlap & ~shares)
        if len(edge_index) == 0:
            continue
        origin, direction = p[edge_index], q[edge_index] - p[edge_index]
        t0 = a[triangle_index]
        e1, e2 = b[triangle_index] - t0, c[triangle_index] - t0
        h = np.cross(direction, e2)
        det = np.einsum("ij,ij->i", e1, h)
        scale = (
            np.linalg.norm(e1, axis=1)
            * np.linalg.norm(e2, axis=1)
            * np.linalg.norm(direction, axis=1)
        )
        regular = np.abs(det) > 1e-12 * scale
        inverse = np.where(regular, 1.0 / np.where(regular, det, 1.0), 0.0)
        s = origin - t0
        u = inverse * np.einsum("ij,ij->i", s, h)
        qv = np.cross(s, e1)
        v = inverse * np.einsum("ij,ij->i", direction, qv)
        t = inverse * np.einsum("ij,ij->i", e2, qv)
        hit = regular & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= 1)
        found += int(np.count_nonzero(hit))
    return found
