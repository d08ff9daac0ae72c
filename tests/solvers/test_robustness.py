"""Solver robustness: options that replace the defaults must not break the solve."""

from __future__ import annotations

from mpi4py import MPI

import dolfinx
import pytest

from dolfinx_invertible import C2, Material, NeoHookean, _compat, lame
from dolfinx_invertible.solvers import ImplicitDynamics


@pytest.mark.parametrize("pc_type", ["jacobi", "gamg"])
def test_krylov_solver_chosen_in_petsc_options_replaces_the_direct_default(pc_type):
    """The inertia test of the exact tangent asks the preconditioner in effect for a factor.

    The default solve of a small problem is a MUMPS factorisation; a KSP and PC given in
    ``petsc_options`` replace it, and a PC without a factor must not be asked for one.
    """
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_SELF, 2, 2, 2)
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, "Lagrange", 1))
    u.interpolate(lambda x: -0.95 * (x - 0.5))
    mu, lam = lame(1.0e3, 0.45)
    dynamics = ImplicitDynamics(
        u,
        Material(NeoHookean(mu=mu, lam=lam), C2()),
        density=1.0,
        dt=0.02,
        petsc_options={"ksp_type": "cg", "pc_type": pc_type, "ksp_rtol": 1.0e-12},
    )
    assert dynamics.problem.solver.linear_solver == "direct"  # what the default chose
    for _ in range(3):
        result = dynamics.step()
        assert result.converged and result.linear_iterations > result.newton_iterations
    assert dynamics.problem.solver.snes.getKSP().getPC().getType() == pc_type
