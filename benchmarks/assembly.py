"""Assembly benchmark: our kernels against FFCx's UFL Neo-Hookean and a zero kernel.

``python -m dolfinx_invertible bench assembly [--cells 20] [--repeats 7] [--json PATH]`` times,
on one mesh in one process with interleaved repeats (medians reported), the cases of
:mod:`benchmarks.common`:

(a) UFL Neo-Hookean compiled by FFCx;
(b) our Neo-Hookean + C2 at a state where no point is near the threshold (J ≈ 1.03);
(r) the same near rest with random noise (J ≈ 1 ± 0.04), where many exact tangents are
    indefinite in their rotational modes;
(c) our Neo-Hookean + C2 at a state where every point is in the extension (J ≈ 0.86), so every
    point goes through the SVD and the C2 Taylor expansion;
(d) a kernel that writes nothing (DOLFINx's insertion floor).

Three operations: residual assembly, tangent assembly, and one Newton step, i.e. residual and
tangent assembly with the Dirichlet condition on x = 0 applied plus the conjugate-gradient/GAMG
solve to the solver's default tolerance, with the KSP of
:class:`~dolfinx_invertible.solvers.minimizer.EnergyMinimizer`
(:meth:`~dolfinx_invertible.solvers.minimizer.EnergyMinimizer.newton_direction`: same options,
rigid-body near-nullspace; ``linear_solver="iterative"``, since at these sizes the minimiser
would otherwise factorise directly). Case (d) has no Newton step: its tangent is the zero matrix,
whose "solve" means nothing, so (d) is reported for assembly only and c/d is undefined for
the Newton step. Our tangent is the SPD-projected one (the kernels' default).

Meshes: P1 tetrahedra (cells³ × 6) and P2 tetrahedra with about the same number of dofs
((cells/2)³ × 6). Ratios b/a, r/a, c/a, c/d.
"""

from __future__ import annotations

import argparse
import statistics

from benchmarks import common
from dolfinx_invertible.fem.forms import default_quadrature_degree

OPERATIONS = ("residual", "tangent", "newton_step")


def _assemble_residual(vector, form) -> None:
    import dolfinx.fem.petsc

    with vector.localForm() as local:
        local.set(0.0)
    dolfinx.fem.petsc.assemble_vector(vector, form)


def _assemble_tangent(matrix, form) -> None:
    import dolfinx.fem.petsc

    matrix.zeroEntries()
    dolfinx.fem.petsc.assemble_matrix(matrix, form)
    matrix.assemble()


def newton_solver(case: common.Case):
    """Return an energy minimiser with default options for a case, CG + AMG as its solver.

    ``linear_solver="iterative"``: the minimiser would factorise directly at these sizes
    (``"auto"``), which measures the sparse direct solver, not the kernels.
    """
    from dolfinx_invertible.solvers import EnergyMinimizer, EnergyProblem

    problem = EnergyProblem(case.u, case.energy, case.residual, case.jacobian, case.bcs)
    return EnergyMinimizer(problem, linear_solver="iterative")


def case_jobs(case: common.Case, newton_step: bool = True) -> tuple[dict, dict]:
    """Return timed callables of a case (residual, tangent, Newton step) and their Krylov counts.

    Each job has been run once, so compilation, sparsity and first-use costs are paid.
    """
    import functools

    from dolfinx_invertible import _compat

    vector = _compat.create_vector(case.residual[0])
    matrix = _compat.create_matrix(case.jacobian[0])
    jobs = {
        "residual": functools.partial(_assemble_residual, vector, case.residual[0]),
        "tangent": functools.partial(_assemble_tangent, matrix, case.jacobian[0]),
    }
    krylov: dict = {"iterations": [], "converged": True}
    if newton_step:
        solver = newton_solver(case)
        direction = solver.problem.create_vector()

        def step() -> None:
            krylov["iterations"].append(solver.newton_direction(direction))
            krylov["converged"] &= int(solver.krylov_solver.getConvergedReason()) > 0

        jobs["newton_step"] = step
    for job in jobs.values():
        job()
    return jobs, krylov


def _ratio(numerator: float | None, denominator: float | None) -> float | None:
    if numerator is None or denominator is None:
        return None
    return numerator / denominator


def run_mesh(comm, cells: int, degree: int, repeats: int, newton_step: bool = True) -> dict:
    """All cases on one mesh; JSON-ready medians, ratios and Krylov iteration counts."""
    space = common.unit_cube_space(comm, cells, degree)
    cases = {name: common.build_case(name, space) for name in common.CASES}
    jobs, krylov = {}, {}
    for name, case in cases.items():
        jobs[name], krylov[name] = case_jobs(case, newton_step and name != "d_zero")
    flat = {
        (name, operation): job for name, kinds in jobs.items() for operation, job in kinds.items()
    }
    samples = common.interleaved(flat, repeats, comm)
    median = {name: {operation: None for operation in OPERATIONS} for name in common.CASES}
    for (name, operation), values in samples.items():
        median[name][operation] = statistics.median(values)
    ratios = {
        operation: {
            "b/a": _ratio(median["b_fast"][operation], median["a_ufl"][operation]),
            "r/a": _ratio(median["b_random"][operation], median["a_ufl"][operation]),
            "c/a": _ratio(median["c_svd"][operation], median["a_ufl"][operation]),
            "c/d": _ratio(median["c_svd"][operation], median["d_zero"][operation]),
        }
        for operation in OPERATIONS
        if median["a_ufl"][operation] is not None
    }
    index_map = space.dofmap.index_map
    return {
        "cells": space.mesh.topology.index_map(3).size_global,
        "dofs": index_map.size_global * space.dofmap.index_map_bs,
        "quadrature_degree": default_quadrature_degree(degree, space.mesh.topology.cell_type),
        "extension_share": {name: common.extension_share(name) for name in cases},
        "median_seconds": median,
        "ratios": ratios,
        "krylov_iterations": {
            name: {
                "per_step": value["iterations"],
                "converged": value["converged"],
            }
            for name, value in krylov.items()
            if value["iterations"]
        },
    }


def run(cells: int, repeats: int, newton_step: bool = True) -> dict:
    """Return the assembly benchmark on the P1 and the P2 mesh; a JSON-ready report.

    Parameters
    ----------
    cells
        P1 cells per edge of the unit cube (the P2 mesh has half as many).
    repeats
        Timed repeats of every operation (interleaved).
    newton_step
        Also time one Newton step per case (not for the zero kernel).
    """
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    report = {
        "benchmark": "assembly",
        "repeats": repeats,
        "ranks": comm.size,
        "tangent": "SPD-projected (ours), exact (UFL)",
        "notes": "d_zero has no Newton step: its tangent is the zero matrix",
        "machine": common.machine(),
        "meshes": {},
    }
    for degree, mesh_cells in ((1, cells), (2, max(1, cells // 2))):
        report["meshes"][f"P{degree}"] = run_mesh(comm, mesh_cells, degree, repeats, newton_step)
    common.record_load_after(report)
    return report


def table(report: dict) -> str:
    """Return the report as a human-readable table."""
    short = {"a_ufl": "a", "b_fast": "b", "b_random": "r", "c_svd": "c", "d_zero": "d"}
    lines = [
        f"assembly benchmark: {report['ranks']} rank(s), medians of {report['repeats']} "
        f"interleaved repeats, {common.load_text(report)}",
        "a UFL/FFCx, b ours fast path, r ours near rest with random noise, c ours SVD + C2 path, "
        "d zero kernel; "
        "Newton step = assembly with BCs + CG/GAMG solve (none for d)",
    ]
    header = f"{'mesh':<5}{'operation':<12}" + "".join(f"{short[n] + ' [s]':>10}" for n in short)
    header += f"{'b/a':>7}{'r/a':>7}{'c/a':>7}{'c/d':>7}{'KSP its a/b/r/c':>18}"
    lines.append(header)
    for mesh_name, mesh in report["meshes"].items():
        lines.append(f"{mesh_name}: {mesh['cells']} cells, {mesh['dofs']} dofs")
        for operation, ratios in mesh["ratios"].items():
            times = "".join(
                f"{'—':>10}" if value is None else f"{value:>10.4f}"
                for value in (mesh["median_seconds"][name][operation] for name in short)
            )
            its = ""
            if operation == "newton_step":
                its = "/".join(
                    str(mesh["krylov_iterations"][name]["per_step"][-1])
                    for name in ("a_ufl", "b_fast", "b_random", "c_svd")
                )
            lines.append(
                f"{'':<5}{operation:<12}{times}"
                + "".join(
                    f"{common.ratio_text(ratios[key]):>7}" for key in ("b/a", "r/a", "c/a", "c/d")
                )
                + f"{its:>18}"
            )
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``bench assembly``."""
    parser.add_argument("--cells", type=int, default=20, help="P1 cells per edge (default 20)")
    parser.add_argument("--repeats", type=int, default=7, help="timed repeats (default 7)")
    parser.add_argument(
        "--no-newton", action="store_true", help="assembly only, skip the Newton step"
    )
    parser.add_argument("--json", help="write the JSON report here (default: stdout)")


def command(arguments: argparse.Namespace) -> int:
    """Run ``bench assembly``; returns the exit code."""
    from mpi4py import MPI

    report = run(arguments.cells, arguments.repeats, not arguments.no_newton)
    if MPI.COMM_WORLD.rank == 0:
        common.emit(report, table(report), arguments.json)
    return 0
