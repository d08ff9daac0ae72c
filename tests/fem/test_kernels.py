"""The numba cell kernels against FFCx-compiled UFL forms, and a patch test.

Runs serially and under MPI: assembly is distributed, and the comparisons are of global
(reduced) quantities.
"""

from __future__ import annotations

from mpi4py import MPI

import dolfinx
import dolfinx.fem.petsc
import numpy as np
import pytest
import ufl
from petsc4py import PETSc

from dolfinx_invertible import C1, C2, HyperelasticForms, Material, NeoHookean, _compat, lame
from dolfinx_invertible.fem.forms import default_quadrature_degree

pytestmark = pytest.mark.mpi

MU, LAM = lame(10.0, 0.3)


def make_mesh(cell: str):
    comm = MPI.COMM_WORLD
    if cell == "triangle":
        return dolfinx.mesh.create_unit_square(comm, 4, 3)
    if cell == "quadrilateral":
        return dolfinx.mesh.create_unit_square(
            comm, 3, 3, cell_type=dolfinx.mesh.CellType.quadrilateral
        )
    if cell == "hexahedron":
        return dolfinx.mesh.create_unit_cube(
            comm, 2, 2, 2, cell_type=dolfinx.mesh.CellType.hexahedron
        )
    return dolfinx.mesh.create_unit_cube(comm, 2, 2, 2)


def perturbed_displacement(mesh, degree: int, amplitude: float, seed: int = 0):
    """A smooth, uninverted displacement (identical on any number of ranks)."""
    V = _compat.vector_function_space(mesh, degree)
    u = dolfinx.fem.Function(V)
    d = mesh.geometry.dim
    rng = np.random.default_rng(seed)
    coefficients = rng.normal(size=(d, d + 1))

    def field(x):
        values = np.zeros((d, x.shape[1]))
        for i in range(d):
            values[i] = amplitude * (
                np.sin(2.0 * x[0] + coefficients[i, 0])
                + coefficients[i, 1] * x[1] ** 2
                + coefficients[i, d] * x[0] * x[d - 1]
            )
        return values

    u.interpolate(field)
    u.x.scatter_forward()
    return u


def neo_hookean_ufl(u, quadrature_degree: int):
    d = u.function_space.mesh.geometry.dim
    F = ufl.Identity(d) + ufl.grad(u)
    J = ufl.det(F)
    psi = MU / 2 * (ufl.tr(F.T * F) - d) - MU * ufl.ln(J) + LAM / 2 * ufl.ln(J) ** 2
    energy = psi * ufl.dx(metadata={"quadrature_degree": quadrature_degree})
    residual = ufl.derivative(energy, u)
    return energy, residual, ufl.derivative(residual, u)


def assemble(energy, residual, jacobian):
    value = MPI.COMM_WORLD.allreduce(dolfinx.fem.assemble_scalar(energy), op=MPI.SUM)
    vector = dolfinx.fem.petsc.assemble_vector(residual)
    vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    matrix = dolfinx.fem.petsc.assemble_matrix(jacobian)
    matrix.assemble()
    return value, vector, matrix


@pytest.mark.parametrize(
    "cell, degree",
    [("triangle", 1), ("triangle", 2), ("tetrahedron", 1), ("tetrahedron", 2),
     ("quadrilateral", 1), ("quadrilateral", 2), ("hexahedron", 1), ("hexahedron", 2)],
)  # fmt: skip
def test_kernels_match_ffcx_neo_hookean(cell, degree):
    """Uninverted state: energy, residual and exact tangent equal FFCx's to 1e-10 relative."""
    mesh = make_mesh(cell)
    u = perturbed_displacement(mesh, degree, amplitude=0.05)
    quadrature_degree = 2 * degree
    forms = HyperelasticForms(
        u, Material(NeoHookean(mu=MU, lam=LAM)), quadrature_degree=quadrature_degree, project=False
    )
    reference = [dolfinx.fem.form(form) for form in neo_hookean_ufl(u, quadrature_degree)]
    energy_ufl, b_ufl, A_ufl = assemble(*reference)
    energy, b, A = assemble(forms.energy, forms.residual, forms.jacobian)
    assert abs(energy - energy_ufl) <= 1e-10 * abs(energy_ufl)
    b.axpy(-1.0, b_ufl)
    assert b.norm() <= 1e-10 * b_ufl.norm()
    A.axpy(-1.0, A_ufl)
    assert A.norm() <= 1e-10 * A_ufl.norm()


@pytest.mark.parametrize(
    "cell, degree", [("tetrahedron", 1), ("quadrilateral", 2), ("hexahedron", 1), ("hexahedron", 2)]
)
def test_default_quadrature_matches_ffcx(cell, degree):
    """With the default rule (one per cell type) the kernels equal FFCx at that degree, and the
    tangent of a tensor-product cell is not singular (no hourglass modes)."""
    mesh = make_mesh(cell)
    u = perturbed_displacement(mesh, degree, amplitude=0.05)
    forms = HyperelasticForms(u, Material(NeoHookean(mu=MU, lam=LAM)), project=False)
    assert forms.quadrature_degree == default_quadrature_degree(degree, cell)
    reference = [dolfinx.fem.form(form) for form in neo_hookean_ufl(u, forms.quadrature_degree)]
    energy_ufl, b_ufl, A_ufl = assemble(*reference)
    energy, b, A = assemble(forms.energy, forms.residual, forms.jacobian)
    assert abs(energy - energy_ufl) <= 1e-10 * abs(energy_ufl)
    A.axpy(-1.0, A_ufl)
    assert A.norm() <= 1e-10 * A_ufl.norm()


def test_default_quadrature_degree_per_cell_type():
    assert [default_quadrature_degree(k, "tetrahedron") for k in (1, 2)] == [1, 2]
    assert [default_quadrature_degree(k, "triangle") for k in (1, 2)] == [1, 2]
    assert [default_quadrature_degree(k, "quadrilateral") for k in (1, 2)] == [2, 4]
    assert [default_quadrature_degree(k, "hexahedron") for k in (1, 2)] == [2, 4]
    assert default_quadrature_degree(1, dolfinx.mesh.CellType.hexahedron) == 2
    with pytest.raises(ValueError, match="prism"):
        default_quadrature_degree(1, "prism")


def test_p1_hexahedron_tangent_is_not_singular():
    """One point per P1 hexahedron leaves hourglass modes: with the default rule the clamped
    tangent is positive definite (its smallest eigenvalue is clearly > 0). Each rank checks a
    mesh of its own (dense eigenvalues of a serial matrix)."""
    mesh = dolfinx.mesh.create_unit_cube(
        MPI.COMM_SELF, 2, 2, 2, cell_type=dolfinx.mesh.CellType.hexahedron
    )
    V = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(V)
    forms = HyperelasticForms(u, Material(NeoHookean(mu=MU, lam=LAM)))
    matrix = dolfinx.fem.petsc.assemble_matrix(forms.jacobian)
    matrix.assemble()
    dense = matrix.convert("dense").getDenseArray()
    x = mesh.geometry.x
    fixed = np.flatnonzero(np.isclose(x[:, 0], 0.0))
    keep = np.setdiff1d(
        np.arange(dense.shape[0]), np.concatenate([3 * fixed + i for i in range(3)])
    )
    eigenvalues = np.linalg.eigvalsh(dense[np.ix_(keep, keep)])
    assert eigenvalues[0] > 1e-6 * eigenvalues[-1]


def test_overflowing_state_writes_no_nan():
    """u = 1e200 x: the energy is +inf, the residual and tangent finite (zero contributions)."""
    mesh = make_mesh("tetrahedron")
    V = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(V)
    u.interpolate(lambda x: 1e200 * x)
    forms = HyperelasticForms(u, Material(NeoHookean(mu=MU, lam=LAM), C2()))
    energy, b, A = assemble(forms.energy, forms.residual, forms.jacobian)
    assert np.isposinf(energy)
    assert np.all(np.isfinite(b.array)) and np.isfinite(A.norm())


def test_parameter_change_needs_no_recompilation():
    mesh = make_mesh("triangle")
    u = perturbed_displacement(mesh, 1, amplitude=0.05)
    forms = HyperelasticForms(u, Material(NeoHookean(mu=MU, lam=LAM), C2()))
    constants = forms.constants
    before = dolfinx.fem.assemble_scalar(forms.energy)
    forms.set_material(Material(NeoHookean(mu=2 * MU, lam=2 * LAM), C2()))
    after = dolfinx.fem.assemble_scalar(forms.energy)
    assert forms.constants is constants
    # Both Lamé parameters doubled: Neo-Hookean energy is linear in (μ, λ).
    assert after == pytest.approx(2.0 * before, rel=1e-12)
    with pytest.raises(ValueError, match="same kind"):
        forms.set_material(Material(NeoHookean(mu=MU, lam=LAM), C1()))


@pytest.mark.parametrize("cell", ["triangle", "tetrahedron"])
@pytest.mark.parametrize("determinant_sign", [1.0, -1.0])
def test_patch_test_affine_map(cell, determinant_sign):
    """An affine deformation is an equilibrium: the interior residual vanishes to round-off.

    Includes an affine map with det < 0 under the C2 extension (every element inverted).
    """
    mesh = make_mesh(cell)
    d = mesh.geometry.dim
    rng = np.random.default_rng(3)
    A = np.eye(d) + 0.2 * rng.normal(size=(d, d))
    if np.sign(np.linalg.det(A)) != determinant_sign:
        A[:, 0] *= -1.0
    V = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(V)
    u.interpolate(lambda x: (A - np.eye(d)) @ x[:d])
    u.x.scatter_forward()
    forms = HyperelasticForms(u, Material(NeoHookean(mu=MU, lam=LAM), C2(eps=0.9)))
    b = dolfinx.fem.petsc.assemble_vector(forms.residual)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    boundary_facets = dolfinx.mesh.locate_entities_boundary(
        mesh, d - 1, lambda x: np.full(x.shape[1], True)
    )
    boundary_dofs = dolfinx.fem.locate_dofs_topological(V, d - 1, boundary_facets)
    values = b.array.reshape(-1, d)
    owned = V.dofmap.index_map.size_local
    interior = np.setdiff1d(np.arange(owned), boundary_dofs)
    boundary_scale = np.abs(values[np.intersect1d(boundary_dofs, np.arange(owned))])
    scale = MPI.COMM_WORLD.allreduce(boundary_scale.max(initial=0.0), op=MPI.MAX)
    interior_max = MPI.COMM_WORLD.allreduce(np.abs(values[interior]).max(initial=0.0), op=MPI.MAX)
    # Boundary nodes carry the traction of the constant stress: a nonzero scale to compare with.
    assert scale > 1e-3 * MU
    assert interior_max <= 1e-12 * scale


def test_bad_spaces_are_rejected():
    mesh = make_mesh("triangle")
    scalar = dolfinx.fem.Function(_compat.scalar_function_space(mesh, 1, "Lagrange"))
    with pytest.raises(ValueError, match="components"):
        HyperelasticForms(scalar, Material(NeoHookean(mu=MU, lam=LAM)))
    cubic = dolfinx.fem.Function(_compat.vector_function_space(mesh, 3))
    with pytest.raises(ValueError, match="degree 3 is not supported"):
        HyperelasticForms(cubic, Material(NeoHookean(mu=MU, lam=LAM)))
    with pytest.raises(TypeError, match="Material"):
        HyperelasticForms(cubic, NeoHookean(mu=MU, lam=LAM))
