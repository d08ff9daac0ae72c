"""DOLFINx pieces of the contact tests: boxes, their boundary, symmetry conditions, a matrix."""

from mpi4py import MPI

import dolfinx
import dolfinx.fem
import dolfinx.mesh
import numpy as np
import ufl

import dolfinx_invertible as di
from dolfinx_invertible import _compat

CELL_TYPES = {
    "triangle": dolfinx.mesh.CellType.triangle,
    "quadrilateral": dolfinx.mesh.CellType.quadrilateral,
    "tetrahedron": dolfinx.mesh.CellType.tetrahedron,
    "hexahedron": dolfinx.mesh.CellType.hexahedron,
}


def box(comm, lower, upper, cells, cell="tetrahedron"):
    if len(lower) == 2:
        return dolfinx.mesh.create_rectangle(comm, [lower, upper], cells, CELL_TYPES[cell])
    return dolfinx.mesh.create_box(comm, [lower, upper], cells, CELL_TYPES[cell])


def displacement(mesh, degree=1):
    return dolfinx.fem.Function(di.vector_function_space(mesh, degree))


def symmetry_conditions(space, planes):
    """u_k = 0 on the plane x_k = value, for each (k, value): removes rigid modes in-plane."""
    mesh = space.mesh
    mesh.topology.create_connectivity(0, mesh.topology.dim)
    conditions = []
    for component, value in planes:
        vertices = dolfinx.mesh.locate_entities(
            mesh, 0, lambda x, k=component, v=value: np.isclose(x[k], v)
        )
        dofs = dolfinx.fem.locate_dofs_topological(space.sub(component), 0, vertices)
        conditions.append(dolfinx.fem.dirichletbc(np.float64(0.0), dofs, space.sub(component)))
    return conditions


def tangent_matrix(space):
    """An assembled-to-zero matrix with the sparsity pattern of the space's cell couplings."""
    u, v = ufl.TrialFunction(space), ufl.TestFunction(space)
    form = dolfinx.fem.form(ufl.inner(u, v) * ufl.dx)
    matrix = _compat.create_matrix(form)
    matrix.zeroEntries()
    return matrix


def allsum(comm, value):
    return comm.allreduce(value, op=MPI.SUM)
