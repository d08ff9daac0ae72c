"""How a run ended: the distance to the rest shape, and the outcome of a relaxation.

Outcomes of a relaxation run (a body released from a deformed, possibly tangled state):

- ``recovered``: every step converged, no cell is inverted at the end and the rest distance is
  below :data:`REST_TOLERANCE`;
- ``stalled_inverted``: every step converged but cells are still inverted at the end: the body
  sits in (or moves through) an inverted, tangled configuration;
- ``not_at_rest``: every step converged and nothing is inverted, but the body is still away
  from its rest shape (still moving, or an end time too early);
- ``failed``: a step could not be solved after the allowed cuts (the summary says at which
  stage: linear solve, line search, iteration cap);
- ``nan``: a residual or energy became NaN.

Other scenes end ``completed`` or ``failed``/``nan``.
"""

from __future__ import annotations

from mpi4py import MPI

import numpy as np

__all__ = [
    "OUTCOMES",
    "REST_TOLERANCE",
    "body_diameter",
    "bounding_box",
    "relaxation_outcome",
    "rest_distance",
]

#: Rest distance below which a relaxed body counts as back at rest.
REST_TOLERANCE = 1.0e-3
OUTCOMES = ("recovered", "stalled_inverted", "not_at_rest", "completed", "failed", "nan")


def _owned_nodes(u) -> tuple[np.ndarray, np.ndarray]:
    """Return the reference coordinates and displacements of the owned dofs' nodes of ``u``."""
    space = u.function_space
    owned = space.dofmap.index_map.size_local
    d = space.mesh.geometry.dim
    coordinates = space.tabulate_dof_coordinates()[:owned, :d]
    displacement = u.x.array[: owned * d].reshape(owned, d)
    return coordinates, displacement


def body_diameter(u) -> float:
    """Return the diagonal of the reference body's bounding box, over all ranks."""
    coordinates, _ = _owned_nodes(u)
    comm = u.function_space.mesh.comm
    low, high = bounding_box(coordinates, comm)
    return float(np.linalg.norm(high - low))


def bounding_box(points: np.ndarray, comm) -> tuple[np.ndarray, np.ndarray]:
    """Return the lowest and highest corner of the points of all ranks (points: (n, d))."""
    d = points.shape[1]
    low = np.full(d, np.inf) if len(points) == 0 else points.min(axis=0)
    high = np.full(d, -np.inf) if len(points) == 0 else points.max(axis=0)
    # Element-wise over ranks (the object allreduce would compare whole arrays).
    return np.min(comm.allgather(low), axis=0), np.max(comm.allgather(high), axis=0)


def rest_distance(u) -> float:
    """Return the largest node distance to the rest shape after the best rigid alignment.

    Kabsch: the rotation R and translation that best map the reference nodes X onto the current
    x = X + u (least squares), then max |R (X − X̄) − (x − x̄)| over all nodes, divided by the
    body's diameter. Collective; the same value on every rank.
    """
    reference, displacement = _owned_nodes(u)
    current = reference + displacement
    comm = u.function_space.mesh.comm
    d = reference.shape[1]
    count = comm.allreduce(len(reference), op=MPI.SUM)
    reference_centre = comm.allreduce(reference.sum(axis=0), op=MPI.SUM) / count
    current_centre = comm.allreduce(current.sum(axis=0), op=MPI.SUM) / count
    X = reference - reference_centre
    x = current - current_centre
    covariance = comm.allreduce(X.T @ x, op=MPI.SUM)
    left, _, right_t = np.linalg.svd(covariance)
    # R maps X to x: R = V diag(1, …, det) Uᵀ of the covariance Xᵀx = U Σ Vᵀ.
    correction = np.eye(d)
    correction[-1, -1] = np.sign(np.linalg.det(right_t.T @ left.T)) or 1.0
    rotation = right_t.T @ correction @ left.T
    local = float(np.max(np.linalg.norm(X @ rotation.T - x, axis=1))) if len(X) else 0.0
    return comm.allreduce(local, op=MPI.MAX) / body_diameter(u)


def relaxation_outcome(completed: bool, stage: str | None, final_inverted: int, distance: float):
    """Return the outcome name of a relaxation run (see the module description)."""
    if not completed:
        return "nan" if stage == "NaN" else "failed"
    if final_inverted > 0:
        return "stalled_inverted"
    return "recovered" if distance < REST_TOLERANCE else "not_at_rest"
