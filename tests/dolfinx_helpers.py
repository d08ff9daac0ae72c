"""Helpers of the tests that run on DOLFINx meshes (fem, solvers, io, ...).

Independent of the package under test except the material factories.
"""

from mpi4py import MPI

import dolfinx.fem
import dolfinx.mesh
import numpy as np
import pytest

import dolfinx_invertible as di
from dolfinx_invertible import _compat

COMM = MPI.COMM_WORLD
# Deliberately different order-one values so that a mu/lambda mix-up cannot go unnoticed.
MU = 0.8
LAM = 1.7
EPS_C1 = 0.4
EPS_C2 = 0.9

# Upper triangular with shear, so that det A is set by the last diagonal entry.
SHEAR = {
    2: np.array([[1.2, 0.3], [0.0, 1.0]]),
    3: np.array([[1.1, 0.2, 0.1], [0.0, 0.9, 0.3], [0.0, 0.0, 1.0]]),
}
MATERIALS = {
    "plain": lambda: di.Material(di.NeoHookean(mu=MU, lam=LAM)),
    "C1": lambda: di.Material(di.NeoHookean(mu=MU, lam=LAM), extension=di.C1(eps=EPS_C1)),
    "C2": lambda: di.Material(di.NeoHookean(mu=MU, lam=LAM), extension=di.C2(eps=EPS_C2)),
    "IFE": lambda: di.Material(di.NeoHookean(mu=MU, lam=LAM), extension=di.IFE()),
}


def deformation(d, det):
    A = SHEAR[d].copy()
    A[-1, -1] = det / np.prod(np.diag(A)[:-1])
    return A


def unit_mesh(d):
    if d == 2:
        return dolfinx.mesh.create_unit_square(COMM, 4, 4)
    return dolfinx.mesh.create_unit_cube(COMM, 2, 2, 2)


def affine_displacement(mesh, A, degree=1, scale=1.0):
    """u = scale·(A − I)x, exact in any Lagrange space."""
    d = mesh.geometry.dim
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, degree))
    u.interpolate(lambda x: scale * (A - np.eye(d)) @ x[:d])
    return u


def read_series(path):
    """(points, cells, [(t, point_data, cell_data), ...]) of an XDMF time series, via meshio."""
    try:
        import h5py  # noqa: F401
    except ImportError:
        pytest.fail("meshio needs h5py to read XDMF/HDF5 files: install python3-h5py")
    import meshio

    with meshio.xdmf.TimeSeriesReader(str(path)) as reader:
        points, cells = reader.read_points_cells()
        steps = [reader.read_data(k) for k in range(reader.num_steps)]
    return points, cells, steps


def values_at_points(function: dolfinx.fem.Function, points: np.ndarray) -> np.ndarray:
    """Values at points (n, 3) on every rank, gathered from the ranks owning a cell there."""
    mesh = function.function_space.mesh
    cells = _compat.locate_points(mesh, points)
    found = cells >= 0
    local = np.full((len(points), 3), np.nan)
    if found.any():
        local[found] = function.eval(points[found], cells[found])
    # The lowest rank that found a point wins, so every rank returns identical values even for a
    # point on a face between cells of different ranks.
    gathered = np.full_like(local, np.nan)
    for values in mesh.comm.allgather(local):
        missing = np.isnan(gathered[:, 0])
        gathered[missing] = values[missing]
    assert not np.isnan(gathered).any(), "a probe point lies in no cell"
    return gathered
