"""Sampling a displacement for records: singular values per cell, values at points.

The scenes record these at every step, and the reports compare runs by them.
"""

from __future__ import annotations

from mpi4py import MPI

import dolfinx
import numpy as np
import ufl

from dolfinx_invertible import _compat
from dolfinx_invertible.constitutive import polar_svd

__all__ = ["CellSingularValues", "PointValues"]


class CellSingularValues:
    """Signed singular values of F at each cell's midpoint, gathered by global cell index.

    Built once per displacement (the expression compiles collectively); :meth:`__call__` returns
    on every rank the array (cells, d) over all cells of the mesh, in global cell order.

    Parameters
    ----------
    u
        The displacement, in a vector Lagrange space; F = I + ∇u.
    """

    def __init__(self, u: dolfinx.fem.Function):
        mesh = u.function_space.mesh
        d = mesh.topology.dim
        cell_type = _compat.basix_element(u.function_space).cell_type
        import basix

        midpoint = basix.geometry(cell_type).mean(axis=0, keepdims=True)
        self._u = u
        self._expression = dolfinx.fem.Expression(ufl.Identity(d) + ufl.grad(u), midpoint)
        index_map = mesh.topology.index_map(d)
        self._owned = np.arange(index_map.size_local, dtype=np.int32)
        self._global = index_map.local_range[0] + self._owned
        self._count = index_map.size_global
        self._dimension = d
        # Reference midpoints, to identify cells independently of DOLFINx's cell order.
        geometry = mesh.geometry.x[:, : mesh.geometry.dim]
        nodes = _compat.geometry_dofmap(mesh)[self._owned]
        local = geometry[nodes].mean(axis=1) if len(self._owned) else np.zeros((0, d))
        midpoints = np.zeros((self._count, mesh.geometry.dim))
        midpoints[self._global] = local
        #: Reference midpoint of every cell, in global cell order (the same on every rank).
        self.midpoints = mesh.comm.allreduce(midpoints, op=MPI.SUM)

    def __call__(self) -> np.ndarray:
        """Return σ of every cell, sorted by magnitude with the sign on the smallest."""
        mesh = self._u.function_space.mesh
        d = self._dimension
        local = np.zeros((0, d))
        if len(self._owned):
            F = _compat.evaluate_expression(self._expression, mesh, self._owned)
            _, local, _ = polar_svd(F.reshape(-1, d, d))
        values = np.zeros((self._count, d))
        values[self._global] = local
        return mesh.comm.allreduce(values, op=MPI.SUM)


class PointValues:
    """Values of a Function at fixed reference points, the same on every rank.

    Parameters
    ----------
    function
        The Function to evaluate.
    points
        Reference points, shape (points, geometric dimension); each must lie in the mesh.
    """

    def __init__(self, function: dolfinx.fem.Function, points: np.ndarray):
        mesh = function.function_space.mesh
        self._function = function
        self._points = np.zeros((len(points), 3))
        self._points[:, : points.shape[1]] = points
        self._cells = _compat.locate_points(mesh, self._points)
        self._comm = mesh.comm

    def __call__(self) -> np.ndarray:
        """Return the values (points, value size); the lowest rank owning a point wins."""
        size = int(np.prod(self._function.ufl_shape)) or 1
        local = np.full((len(self._points), size), np.nan)
        found = self._cells >= 0
        if found.any():
            local[found] = self._function.eval(self._points[found], self._cells[found])
        gathered = np.full_like(local, np.nan)
        for values in self._comm.allgather(local):
            missing = np.isnan(gathered[:, 0])
            gathered[missing] = values[missing]
        if np.isnan(gathered).any():
            raise ValueError("a probe point lies outside the mesh")
        return gathered
