"""The kernels see the displacement: assembled forms match values computed without the kernels.

From DOLFINx 0.9 on a custom integral receives only the coefficients listed as active for it; any
other arrives as zeros, silently, and every form would then be evaluated at u = 0. Here the energy,
residual and tangent of :class:`HyperelasticForms` are assembled at a non-trivial displacement on
a P1 mesh, where F is constant per cell, and compared with sums over cells of the batch API
(``Material.energy``, ``stress``, ``tangent``) at F computed by hand from the dof coordinates.
Residual and tangent are compared through v · R and v · K v for a random v, which keeps the
comparison a sum of cell contributions (so it holds on any number of ranks).
"""

from __future__ import annotations

import math

from mpi4py import MPI

import dolfinx
import dolfinx.fem.petsc
import numpy as np
import pytest
from petsc4py import PETSc

from dolfinx_invertible import C2, HyperelasticForms, Material, NeoHookean, _compat, lame

pytestmark = pytest.mark.mpi


def unit_mesh(dimension: int):
    if dimension == 2:
        return dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, 4, 3)
    return dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 3, 2, 2)


def displacement(x: np.ndarray, dimension: int) -> np.ndarray:
    """A smooth, non-affine field small enough to keep every cell uninverted."""
    values = [
        0.12 * np.sin(2.0 * x[0] + x[1]),
        0.10 * x[0] * x[1] - 0.05 * x[1] ** 2,
        0.08 * np.cos(x[0] + 2.0 * x[2]),
    ]
    return np.vstack(values[:dimension])


def cell_gradients(space, values: np.ndarray, num_cells: int) -> tuple[np.ndarray, np.ndarray]:
    """Per owned P1 cell: the gradient of a nodal field (cells, d, d) and the cell volume.

    Built from the dof coordinates only, independently of the kernels' reference tables.
    """
    dimension = space.mesh.geometry.dim
    dofs = _compat.cell_dofs(space)[:num_cells]
    coordinates = space.tabulate_dof_coordinates()[:, :dimension][dofs]
    nodal = values.reshape(-1, dimension)[dofs]
    # Edge vectors from node 0: dX (cells, d, d) with edges as columns, the same for the field.
    edges = np.swapaxes(coordinates[:, 1:] - coordinates[:, :1], 1, 2)
    field_edges = np.swapaxes(nodal[:, 1:] - nodal[:, :1], 1, 2)
    gradients = field_edges @ np.linalg.inv(edges)
    volumes = np.abs(np.linalg.det(edges)) / math.factorial(dimension)
    return gradients, volumes


def independent_values(material: Material, u, v) -> np.ndarray:
    """[Π, v · R, v · K v] summed over all ranks, from the batch API on each cell's F."""
    space = u.function_space
    mesh = space.mesh
    dimension = mesh.geometry.dim
    num_cells = mesh.topology.index_map(mesh.topology.dim).size_local
    grad_u, volumes = cell_gradients(space, u.x.array, num_cells)
    grad_v, _ = cell_gradients(space, v.x.array, num_cells)
    F = np.eye(dimension) + grad_u
    energy = np.sum(volumes * material.energy(F))
    stress = material.stress(F)
    first = np.sum(volumes * np.einsum("cij,cij->c", stress, grad_v))
    tangent = material.tangent(F, project=True)
    flat_v = grad_v.reshape(num_cells, dimension * dimension)
    second = np.sum(volumes * np.einsum("ca,cab,cb->c", flat_v, tangent, flat_v))
    return mesh.comm.allreduce(np.array([energy, first, second]), op=MPI.SUM)


def assembled_values(forms: HyperelasticForms, v) -> np.ndarray:
    """[Π, v · R, v · K v] from the custom-kernel forms."""
    comm = forms.u.function_space.mesh.comm
    energy = comm.allreduce(dolfinx.fem.assemble_scalar(forms.energy), op=MPI.SUM)
    residual = dolfinx.fem.petsc.assemble_vector(forms.residual)
    residual.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    matrix = dolfinx.fem.petsc.assemble_matrix(forms.jacobian)
    matrix.assemble()
    v_vector = _compat.petsc_vector(v)
    product = v_vector.duplicate()
    matrix.mult(v_vector, product)
    return np.array([energy, residual.dot(v_vector), v_vector.dot(product)])


@pytest.mark.parametrize("dimension", [2, 3])
def test_forms_see_the_displacement(dimension):
    mesh = unit_mesh(dimension)
    space = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(space)
    v = dolfinx.fem.Function(space)
    v.interpolate(lambda x: np.vstack([np.cos(3.0 * x[0] + k * x[1]) for k in range(dimension)]))
    v.x.scatter_forward()
    mu, lam = lame(E=1.0e3, nu=0.3)
    material = Material(NeoHookean(mu=mu, lam=lam), extension=C2(eps=0.9))
    forms = HyperelasticForms(u, material)

    at_rest = assembled_values(forms, v)
    u.interpolate(lambda x: displacement(x, dimension))
    u.x.scatter_forward()
    deformed = assembled_values(forms, v)
    expected = independent_values(material, u, v)

    np.testing.assert_allclose(deformed, expected, rtol=1e-10, atol=1e-12 * np.abs(expected).max())
    # The same comparison at u = 0 would pass if u arrived as zeros: the deformed values must be
    # far from the values at rest (energy 0 and residual 0 there).
    assert np.isclose(at_rest[0], 0.0, atol=1e-12) and np.isclose(at_rest[1], 0.0, atol=1e-9)
    assert abs(deformed[0]) > 1e-3 * mu and abs(deformed[1]) > 1e-3 * mu
    assert abs(deformed[2] - at_rest[2]) > 1e-3 * abs(at_rest[2])
