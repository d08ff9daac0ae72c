"""The public mesh and sampling helpers: a mesh from its cells, values gathered over ranks."""

import os

from mpi4py import MPI

import dolfinx
import numpy as np
import pytest

from dolfinx_invertible.fem import (
    CellSingularValues,
    PointValues,
    mesh_from_cells,
    reproducible_partitioning,
    vector_function_space,
)
from dolfinx_invertible.fem.mesh import PARTITIONER_THREADS

pytestmark = pytest.mark.mpi

_SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
_HALVES = np.array([[0, 1, 2], [0, 2, 3]])


def _count(mesh, dimension: int) -> int:
    return mesh.topology.index_map(dimension).size_global


@pytest.mark.parametrize("cell_type, points, cells", [
    ("triangle", _SQUARE, _HALVES),
    ("tetrahedron", np.vstack([np.eye(3), np.zeros(3)]), np.array([[3, 0, 1, 2]])),
])  # fmt: skip
def test_mesh_from_cells_has_the_cells_given_on_rank_zero(cell_type, points, cells):
    mesh = mesh_from_cells(MPI.COMM_WORLD, points, cells, cell_type)
    assert _count(mesh, mesh.topology.dim) == len(cells)
    assert _count(mesh, 0) == len(points)
    assert mesh.geometry.dim == points.shape[1]


def test_mesh_from_cells_names_the_cell_types_it_builds():
    with pytest.raises(ValueError, match="triangle, tetrahedron"):
        mesh_from_cells(MPI.COMM_WORLD, _SQUARE, np.array([[0, 1, 2, 3]]), "quadrilateral")


def _owned_cells_of_a_box() -> np.ndarray:
    """The midpoints of this rank's cells of a box, in the rank's order."""
    mesh = dolfinx.mesh.create_box(MPI.COMM_WORLD, [[0.0] * 3, [1.0] * 3], [10, 10, 10])
    owned = np.arange(mesh.topology.index_map(3).size_local, dtype=np.int32)
    return dolfinx.mesh.compute_midpoints(mesh, 3, owned)


def test_reproducible_partitioning_partitions_a_mesh_the_same_way_every_time(monkeypatch):
    """Four partitions of one box: each rank owns the same cells, in the same order.

    Without it SCOTCH's threads split the same box differently from one call to the next on
    2 and 3 ranks (measured on the Debian build with the box's vertices: 646/685 and 669/662
    owned).
    """
    monkeypatch.setenv(PARTITIONER_THREADS, "")  # restored to the run's own value afterwards
    monkeypatch.delenv(PARTITIONER_THREADS)
    reproducible_partitioning()
    assert os.environ[PARTITIONER_THREADS] == "1"
    first = _owned_cells_of_a_box()
    for _ in range(3):
        again = _owned_cells_of_a_box()
        assert again.shape == first.shape and np.array_equal(again, first)
    assert MPI.COMM_WORLD.allreduce(len(first)) == 6 * 10**3


def test_reproducible_partitioning_keeps_a_thread_count_the_user_set(monkeypatch):
    monkeypatch.setenv(PARTITIONER_THREADS, "2")
    reproducible_partitioning()
    assert os.environ[PARTITIONER_THREADS] == "2"


def test_samples_of_an_affine_displacement_are_the_same_on_every_rank():
    mesh = mesh_from_cells(MPI.COMM_WORLD, _SQUARE, _HALVES, "triangle")
    u = dolfinx.fem.Function(vector_function_space(mesh, 1))
    A = np.array([[-1.5, 0.0], [0.0, 0.2]])  # F = I + A = diag(-0.5, 1.2): inverted
    u.interpolate(lambda x: A @ x[:2])
    singular_values = CellSingularValues(u)()
    np.testing.assert_allclose(singular_values, [[1.2, -0.5]] * 2, atol=1e-12)
    points = np.array([[0.25, 0.5], [1.0, 1.0]])
    np.testing.assert_allclose(PointValues(u, points)(), points @ A.T, atol=1e-12)
    with pytest.raises(ValueError, match="outside the mesh"):
        PointValues(u, np.array([[2.0, 0.5]]))()
