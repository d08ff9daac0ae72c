"""The kernels take the SVD path exactly where they must, and say so.

Under a uniform stretch s·I every quadrature point is in the same state, so the path counts of
:meth:`HyperelasticForms.path_counts` are known in advance: Neo-Hookean + C2 (ε = 0.9) needs no
SVD at J = s³ ≥ ε; below ε every point is in the extension; at s = 0.97 (J ≈ 0.913 ≥ ε) the exact
tangent has negative twist eigenvalues, which the fast path projects without the SVD.
"""

from __future__ import annotations

from mpi4py import MPI

import dolfinx
import dolfinx.fem.petsc
import numpy as np
import pytest

import dolfinx_invertible as di
from dolfinx_invertible import (
    C2,
    HyperelasticForms,
    HyperelasticProblem,
    Material,
    NeoHookean,
    _compat,
    lame,
)

pytestmark = pytest.mark.mpi


def stretched(stretch: float):
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2)
    space = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(space)
    u.interpolate(lambda x: (stretch - 1.0) * x)
    u.x.scatter_forward()
    return u


def material() -> Material:
    mu, lam = lame(E=1.0e3, nu=0.3)
    return Material(NeoHookean(mu=mu, lam=lam), extension=C2(eps=0.9))


def assembled_counts(forms: HyperelasticForms) -> dict:
    forms.reset_path_counts()
    dolfinx.fem.assemble_scalar(forms.energy)
    dolfinx.fem.petsc.assemble_vector(forms.residual)
    matrix = dolfinx.fem.petsc.assemble_matrix(forms.jacobian)
    matrix.assemble()
    return forms.path_counts()


@pytest.mark.parametrize(
    ("stretch", "project", "through_svd"),
    [
        (1.05, True, {"energy": False, "residual": False, "tangent": False}),
        (0.95, True, {"energy": True, "residual": True, "tangent": True}),
        # Uniform compression above the threshold: the exact tangent is indefinite only in its
        # rotational (twist) modes, which the fast path projects without an SVD.
        (0.97, True, {"energy": False, "residual": False, "tangent": False}),
        (0.97, False, {"energy": False, "residual": False, "tangent": False}),
    ],
)
def test_path_counts_follow_the_state(stretch, project, through_svd):
    forms = HyperelasticForms(stretched(stretch), material(), project=project)
    counts = assembled_counts(forms)
    cells = forms.u.function_space.mesh.topology.index_map(3).size_local
    for kind, (points, svd_points) in counts.items():
        assert points >= cells > 0, kind
        assert svd_points == (points if through_svd[kind] else 0), (kind, counts)


def test_counts_reset_and_accumulate():
    forms = HyperelasticForms(stretched(0.95), material())
    first = assembled_counts(forms)
    dolfinx.fem.petsc.assemble_vector(forms.residual)
    points, svd_points = forms.path_counts()["residual"]
    assert (points, svd_points) == (2 * first["residual"][0], 2 * first["residual"][1])
    forms.reset_path_counts()
    assert all(counts == (0, 0) for counts in forms.path_counts().values())


def test_solve_reports_svd_share():
    u = stretched(1.0)
    mesh = u.function_space.mesh
    facets = dolfinx.mesh.locate_entities_boundary(
        mesh, 2, lambda x: np.isclose(x[0], 0.0) | np.isclose(x[0], 1.0)
    )
    dofs = dolfinx.fem.locate_dofs_topological(u.function_space, 2, facets)
    boundary = dolfinx.fem.Function(u.function_space)
    boundary.interpolate(lambda x: np.vstack([-0.3 * x[0], 0.0 * x[1], 0.0 * x[2]]))
    bc = dolfinx.fem.dirichletbc(boundary, dofs)
    problem = HyperelasticProblem(u, material(), [bc], project=True)
    result = problem.solve()
    assert result.converged
    assert set(result.svd_share) == {"energy", "residual", "tangent"}
    # The first residual is at rest (no SVD); the 30 % compression along x then takes cells
    # below J = 0.9.
    assert 0.0 < result.svd_share["residual"] < 1.0
    assert 0.0 < result.svd_share["tangent"] <= 1.0
    # Solving again from the solution, every iterate stays at J ≈ 0.7 in every cell.
    again = problem.solve()
    assert again.converged
    assert again.svd_share == {"energy": 1.0, "residual": 1.0, "tangent": 1.0}


def test_kernel_requests_are_checked():
    from dolfinx_invertible.fem import kernels

    nh, c2 = di.NeoHookean.model_id, di.C2.extension_id
    with pytest.raises(ValueError, match="kind must be one of"):
        kernels.kernel_address("mass", 3, nh, c2)
    with pytest.raises(ValueError, match="dimension 1"):
        kernels.kernel_address("residual", 1, nh, c2)
    with pytest.raises(ValueError, match="unknown model id"):
        kernels.kernel_address("residual", 3, 99, c2)
    # Compiled once per (kind, dimension, model, extension): the same address every time.
    assert kernels.kernel_address("residual", 3, nh, c2) == kernels.kernel_address(
        "residual", 3, nh, c2
    )


def test_default_materials_are_listed_once_next_to_the_compilation():
    from dolfinx_invertible.fem import kernels

    materials = kernels.default_materials()
    assert len(materials) == len(kernels.DEFAULT_MATERIALS)
    described = {
        (type(m.model).__name__, m.extension and type(m.extension).__name__) for m in materials
    }
    assert ("NeoHookean", "C2") in described and ("StableNeoHookean", None) in described
    assert len(described) == len(materials)
