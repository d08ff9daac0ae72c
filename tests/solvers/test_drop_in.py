"""The drop-ins for DOLFINx's own nonlinear classes: kernels + the user's UFL loads.

DOLFINx's NewtonSolver on our problem must take exactly the iterates it takes on the same
Neo-Hookean energy written in UFL (exact tangent, plain Newton): same iteration counts, same
solution, and the loads must act.
"""

from __future__ import annotations

from mpi4py import MPI

import dolfinx
import dolfinx.fem.petsc
import dolfinx.nls.petsc
import numpy as np
import pytest
import ufl
from dolfinx_helpers import values_at_points

from dolfinx_invertible import (
    C2,
    Material,
    NeoHookean,
    NewtonSolverNonlinearProblem,
    NonlinearProblem,
    SNESNonlinearProblem,
    _compat,
    lame,
    vector_function_space,
)
from dolfinx_invertible.fem.ufl_forms import ufl_neo_hookean_energy
from dolfinx_invertible.solvers.options import linear_solver_options

pytestmark = pytest.mark.mpi

MU, LAM = lame(1.0e4, 0.3)
# Meshes made one after the other may be partitioned differently: compare at points.
PROBES = np.array([[10.0, 0.5, 0.5], [5.0, 0.0, 1.0], [2.5, 1.0, 0.0], [7.5, 0.5, 1.0]])
LOADS = (-1.5, -3.0, -4.5)


def cantilever():
    mesh = dolfinx.mesh.create_box(MPI.COMM_WORLD, [[0, 0, 0], [10.0, 1, 1]], [10, 2, 2])
    V = vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(V)
    left = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 0.0))
    right = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 10.0))
    tags = dolfinx.mesh.meshtags(mesh, 2, right, np.full(len(right), 2, dtype=np.int32))
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags)
    bc = dolfinx.fem.dirichletbc(np.zeros(3), dolfinx.fem.locate_dofs_topological(V, 2, left), V)
    traction = dolfinx.fem.Constant(mesh, np.zeros(3))
    v = ufl.TestFunction(V)
    loads = -ufl.inner(v, traction) * ds(2)
    return u, bc, traction, loads


def newton_solve(problem, u, traction):
    solver = dolfinx.nls.petsc.NewtonSolver(MPI.COMM_WORLD, problem)
    solver.atol, solver.rtol = 1e-9, 1e-9
    counts = []
    for value in LOADS:
        traction.value[2] = value
        iterations, converged = solver.solve(u)
        assert converged
        counts.append(iterations)
    return counts


def ufl_reference():
    u, bc, traction, loads = cantilever()
    elastic = ufl.derivative(ufl_neo_hookean_energy(u, MU, LAM, 2), u)
    if _compat.NONLINEAR_PROBLEM_IS_SNES:
        problem = dolfinx.fem.petsc.NewtonSolverNonlinearProblem(elastic + loads, u, [bc])
    else:
        problem = dolfinx.fem.petsc.NonlinearProblem(elastic + loads, u, [bc])
    return u, newton_solve(problem, u, traction)


def test_newton_solver_on_kernels_plus_ufl_loads_takes_the_ufl_iterates():
    reference, reference_counts = ufl_reference()
    u, bc, traction, loads = cantilever()
    material = Material(NeoHookean(mu=MU, lam=LAM), C2())  # J stays above ε: C2 inactive
    problem = NewtonSolverNonlinearProblem(loads, u, [bc], material=material, quadrature_degree=2)
    counts = newton_solve(problem, u, traction)
    assert counts == reference_counts
    assert np.abs(u.x.array).max() > 0.1  # the loads act
    expected = values_at_points(reference, PROBES)
    np.testing.assert_allclose(
        values_at_points(u, PROBES), expected, atol=1e-8 * abs(expected).max()
    )


def test_projected_tangent_is_an_explicit_choice():
    u, bc, traction, loads = cantilever()
    material = Material(NeoHookean(mu=MU, lam=LAM), C2())
    exact = NewtonSolverNonlinearProblem(loads, u, [bc], material=material)
    assert exact.forms.project is False
    projected = NewtonSolverNonlinearProblem(loads, u, [bc], material=material, tangent="projected")
    assert projected.forms.project is True
    with pytest.raises(ValueError, match="tangent must be"):
        NewtonSolverNonlinearProblem(loads, u, [bc], material=material, tangent="yes")
    with pytest.raises(TypeError, match="material must be"):
        NewtonSolverNonlinearProblem(loads, u, [bc], material=NeoHookean(mu=MU, lam=LAM))


def test_snes_problem_solves_like_the_newton_solver_route():
    reference, _ = ufl_reference()
    u, bc, traction, loads = cantilever()
    material = Material(NeoHookean(mu=MU, lam=LAM))
    direct = linear_solver_options("auto", "gamg", 1, 3, MPI.COMM_WORLD.size)
    problem = SNESNonlinearProblem(
        loads, u, bcs=[bc], material=material, quadrature_degree=2,
        petsc_options_prefix="drop_in_test_",
        petsc_options={"snes_rtol": 1e-10, "snes_atol": 1e-10, **direct},
    )  # fmt: skip
    for value in LOADS:
        traction.value[2] = value
        problem.solve()
        assert problem.solver.getConvergedReason() > 0
    expected = values_at_points(reference, PROBES)
    np.testing.assert_allclose(
        values_at_points(u, PROBES), expected, atol=1e-7 * abs(expected).max()
    )


def test_nonlinear_problem_is_the_flavour_of_this_dolfinx():
    expected = (
        SNESNonlinearProblem if _compat.NONLINEAR_PROBLEM_IS_SNES else NewtonSolverNonlinearProblem
    )
    assert NonlinearProblem is expected
