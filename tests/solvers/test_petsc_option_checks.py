"""PETSc options checked before a run (bad values refused) and after it (unread ones named).

Real PETSc; the checks run on each rank alone, the report of unread options after a real solve
runs serially and under mpirun.
"""

from __future__ import annotations

import time

from mpi4py import MPI

import dolfinx
import numpy as np
import pytest
from petsc4py import PETSc

from dolfinx_invertible import C2, Material, NeoHookean, _compat, lame
from dolfinx_invertible.solvers.hyperelastic import HyperelasticProblem
from dolfinx_invertible.solvers.options import DEFAULT_OPTIONS_PREFIX
from dolfinx_invertible.solvers.petsc_options import (
    check_petsc_options,
    forget_read_options,
    options_in_database,
    unused_petsc_options,
)

MU, LAM = lame(1.0e3, 0.3)


@pytest.mark.mpi
@pytest.mark.parametrize(
    "name, value, said",
    [
        ("ksp_type", "notakrylov", "KSP type notakrylov"),
        ("pc_type", "nopc", "PC type nopc"),
        ("snes_type", "nosnes", "SNES type nosnes"),
        ("snes_linesearch_type", "nols", "Line Search type nols"),
        # Read by the multigrid levels' smoothers only when GAMG is set up.
        ("mg_levels_ksp_type", "nokrylov", "KSP type nokrylov"),
    ],
)
def test_an_unknown_type_is_refused_with_the_option_named(name, value, said):
    with pytest.raises(ValueError) as refused:
        check_petsc_options({"ksp_rtol": "1e-8", name: value})
    message = str(refused.value)
    assert message.startswith(f"--petsc-option {name}={value}: ")
    assert said in message
    assert "Traceback" not in message and "\n" not in message


@pytest.mark.parametrize(
    "name, value, said",
    [
        ("ksp_rtol", "abc", "no numeric value"),
        ("snes_max_it", "1.5", "no integer value"),
        ("pc_gamg_reuse_interpolation", "maybe", "logical value"),
        # Read only by GAMG, the smoothers of its levels and MUMPS, all set up in the solve.
        ("pc_gamg_threshold", "abc", "no numeric value"),
        ("mg_levels_ksp_chebyshev_esteig", "0,x,0,1.3", "no numeric value"),
        ("mat_mumps_icntl_14", "lots", "no integer value"),
    ],
)
def test_a_value_that_is_not_a_number_is_refused_with_the_option_named(name, value, said):
    with pytest.raises(ValueError) as refused:
        check_petsc_options({"snes_max_it": "20", name: value, "ksp_type": "cg"})
    message = str(refused.value)
    assert message.startswith(f"--petsc-option {name}={value}: ")
    assert said in message


GOOD = {
    "ksp_type": "cg",
    "ksp_rtol": "1e-8",
    "snes_max_it": "7",
    "snes_linesearch_type": "basic",
    "pc_type": "gamg",
    "pc_gamg_threshold": "0.02",
    "mg_levels_ksp_chebyshev_esteig": "0,0.2,0,1.3",
    "mat_mumps_icntl_24": "1",
    "snes_monitor": None,
    "ksp_rtoll": "1e-8",  # misspelt: not refused here, but reported unread after the run
}


def test_good_options_pass_and_leave_the_database_as_it_was(capfd, tmp_path):
    database = PETSc.Options()
    sentinel = f"{DEFAULT_OPTIONS_PREFIX}test_sentinel"
    database.setValue(sentinel, "1")
    try:
        before = database.getAll()
        check_petsc_options(GOOD)
        monitor = tmp_path / "monitor.txt"
        # A viewer's file is the solver's to create, not the check's.
        check_petsc_options({"ksp_monitor": f"ascii:{monitor}"})
        with pytest.raises(ValueError, match="ksp_type=nokrylov"):
            check_petsc_options({**GOOD, "ksp_type": "nokrylov"})
        assert database.getAll() == before
        # The option in the database was not read by the check's throwaway solvers.
        assert unused_petsc_options(["test_sentinel"]) == ["test_sentinel"]
        assert not monitor.exists()
    finally:
        database.delValue(sentinel)
    # PETSc printed no traceback of the refused option.
    assert "PETSC ERROR" not in capfd.readouterr().err


def test_the_check_is_quick():
    start = time.perf_counter()
    check_petsc_options(GOOD)
    with pytest.raises(ValueError):
        check_petsc_options({**GOOD, "pc_gamg_threshold": "abc"})
    assert time.perf_counter() - start < 0.5


def test_a_nested_push_of_the_options_does_not_count_as_a_read():
    forget_read_options()
    options = {"test_nested_misspelt": "1"}
    with options_in_database(DEFAULT_OPTIONS_PREFIX, options):
        with options_in_database(DEFAULT_OPTIONS_PREFIX, options):
            pass
    assert unused_petsc_options(options) == ["test_nested_misspelt"]
    with options_in_database(DEFAULT_OPTIONS_PREFIX, options):
        assert PETSc.Options(DEFAULT_OPTIONS_PREFIX).getInt("test_nested_misspelt") == 1
    # Read once, removed from the database since, and still known as read.
    assert not PETSc.Options(DEFAULT_OPTIONS_PREFIX).hasName("test_nested_misspelt")
    assert unused_petsc_options(options) == []


def test_an_option_without_the_prefix_counts_as_read_once_read_in_the_database():
    database = PETSc.Options()
    database.setValue("test_global_option", "3")
    try:
        assert unused_petsc_options(["test_global_option"], prefix="") == ["test_global_option"]
        database.getInt("test_global_option")
        assert unused_petsc_options(["-test_global_option"], prefix="") == []
    finally:
        database.delValue("test_global_option")


def _stretched_cube(petsc_options, linear_solver):
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2)
    V = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(V)
    left = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 0.0))
    right = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 1.0))
    bcs = [
        dolfinx.fem.dirichletbc(np.zeros(3), dolfinx.fem.locate_dofs_topological(V, 2, left), V),
        dolfinx.fem.dirichletbc(
            np.array([0.3, 0.0, 0.0]), dolfinx.fem.locate_dofs_topological(V, 2, right), V
        ),
    ]
    return HyperelasticProblem(
        u,
        Material(NeoHookean(mu=MU, lam=LAM), C2()),
        bcs,
        petsc_options=petsc_options,
        linear_solver=linear_solver,
    )


MISSPELT = {"ksp_rtoll": "1e-8"}
#: Options of a preconditioner the solver does not use.
WRONG_PC = {"pc_hypre_boomeramg_strong_threshold": "0.5"}


@pytest.mark.mpi
@pytest.mark.parametrize(
    "linear_solver, read, unread",
    [
        # Read when the SNES is configured; GAMG's threshold once the PC is GAMG.
        (
            "iterative",
            {"ksp_rtol": "1e-10", "snes_max_it": "30", "pc_gamg_threshold": "0.01"},
            {**MISSPELT, **WRONG_PC},
        ),
        # MUMPS's control is read only when the solve factorises. A direct solve (KSP preonly)
        # has no Krylov tolerance: PETSc does not read ksp_rtol for it.
        (
            "direct",
            {"snes_max_it": "30", "mat_mumps_icntl_14": "40"},
            {"ksp_rtol": "1e-10", **MISSPELT, **WRONG_PC},
        ),
    ],
)
def test_the_options_no_solver_read_are_reported_after_a_solve(linear_solver, read, unread):
    if linear_solver == "direct" and not PETSc.Sys.hasExternalPackage("mumps"):
        pytest.skip("the option read only in the solve is MUMPS's")
    options = {**read, **unread}
    check_petsc_options(options)
    forget_read_options()
    problem = _stretched_cube(options, linear_solver)
    assert problem.solver.linear_solver == linear_solver
    result = problem.solve()
    assert result.converged and result.newton_iterations >= 2
    assert unused_petsc_options(options, comm=MPI.COMM_WORLD) == list(unread)
    # The solver's options are out of the database between solves: the marks were kept.
    assert not PETSc.Options(DEFAULT_OPTIONS_PREFIX).hasName("snes_max_it")


@pytest.mark.mpi
def test_an_option_read_on_one_rank_counts_as_read_on_every_rank():
    """Read on rank 0 only: unread on the others by themselves, read for all with ``comm``.

    In serial the one rank read it, and asking with the communicator changes nothing.
    """
    comm = MPI.COMM_WORLD
    database = PETSc.Options()
    database.setValue("test_rank_option", "1")
    try:
        assert unused_petsc_options(["test_rank_option"], prefix="", comm=comm) == [
            "test_rank_option"
        ]
        if comm.rank == 0:
            database.getInt("test_rank_option")
        here = unused_petsc_options(["test_rank_option"], prefix="")
        assert here == ([] if comm.rank == 0 else ["test_rank_option"])
        assert unused_petsc_options(["test_rank_option"], prefix="", comm=comm) == []
    finally:
        database.delValue("test_rank_option")
