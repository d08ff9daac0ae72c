"""Memory benchmark: peak resident memory of building and one Newton step of a P1 problem.

``python -m dolfinx_invertible bench memory [--cells 20] [--ranks 1] [--json PATH]`` runs, in a
child process (``mpirun -n ranks``) so that nothing else is in its memory, our Neo-Hookean + C2
kernels (fast-path state, ``b_fast`` of :mod:`benchmarks.common`) on the unit cube
of cells³ × 6 P1 tetrahedra: build the mesh, the space, the forms, problem and Newton solver,
then one Newton step (residual and tangent assembly with the Dirichlet condition + CG/GAMG solve
with the solver's default options). Reported: the peak resident set size
(``getrusage(RUSAGE_SELF).ru_maxrss``) after each stage, per rank and summed over the ranks,
and the time of each stage. The quick default has 27 783 dofs; the full size
(≈ 1 M dofs, target ≤ 4 GB) is ``--cells 70`` (1 073 733 dofs).
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time

from benchmarks import common

TARGET_BYTES = 4 * 1024**3
STAGES = ("imported", "mesh_and_space", "forms_and_solver", "newton_step")


def measure(cells: int) -> dict:
    """Build and take one Newton step on ``MPI.COMM_WORLD``; peak RSS after every stage.

    Collective. Peaks are in bytes, per rank (list in rank order) and summed.
    """
    start = time.perf_counter()
    from mpi4py import MPI

    import dolfinx  # noqa: F401

    from benchmarks.assembly import newton_solver

    comm = MPI.COMM_WORLD
    peaks: dict = {}
    seconds: dict = {}

    def stage(name: str) -> None:
        seconds[name] = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
        peaks[name] = comm.gather(common.peak_rss_bytes(), root=0)

    stage("imported")
    space = common.unit_cube_space(comm, cells, 1)
    stage("mesh_and_space")
    case = common.build_case("b_fast", space)
    solver = newton_solver(case)
    direction = solver.problem.create_vector()
    stage("forms_and_solver")
    krylov_iterations = solver.newton_direction(direction)
    converged = int(solver.krylov_solver.getConvergedReason()) > 0
    stage("newton_step")
    report = {
        "ranks": comm.size,
        "cells": space.mesh.topology.index_map(3).size_global,
        "dofs": space.dofmap.index_map.size_global * space.dofmap.index_map_bs,
        "krylov_iterations": krylov_iterations,
        "krylov_converged": converged,
        "seconds_since_start": seconds,
    }
    if comm.rank == 0:
        report["peak_rss_bytes_per_rank"] = peaks
        report["peak_rss_bytes_total"] = {name: sum(values) for name, values in peaks.items()}
    return report


def run(cells: int, ranks: int = 1, timeout: float = 7200.0) -> dict:
    """:func:`measure` in a fresh ``mpirun -n ranks`` child; a JSON-ready report."""
    report: dict = {"benchmark": "memory", "machine": common.machine()}
    with tempfile.TemporaryDirectory(prefix="bench_memory_") as directory:
        path = os.path.join(directory, "memory.json")
        arguments = ["--worker", "--cells", str(cells), "--json", path]
        command = common.bench_command("memory", arguments, ranks)
        wall = common.run_child(command, common.child_environment(), timeout)
        with open(path, encoding="utf-8") as file:
            report.update(json.load(file))
    report["process_wall_seconds"] = wall
    report["target_bytes"] = TARGET_BYTES
    report["peak_rss_bytes"] = report["peak_rss_bytes_total"]["newton_step"]
    report["within_target"] = report["peak_rss_bytes"] <= TARGET_BYTES
    common.record_load_after(report)
    return report


def table(report: dict) -> str:
    """Return the report as a human-readable table."""
    lines = [
        f"memory benchmark: unit cube P1, {report['cells']} tets, {report['dofs']} dofs, "
        f"{report['ranks']} rank(s), {report['krylov_iterations']} CG iterations; "
        f"{common.load_text(report)}",
        f"{'after stage':<20}{'peak RSS, all ranks [MiB]':>28}{'per rank [MiB]':>24}{'t [s]':>9}",
    ]
    for name in STAGES:
        per_rank = " ".join(
            f"{value / 2**20:.0f}" for value in report["peak_rss_bytes_per_rank"][name]
        )
        lines.append(
            f"{name:<20}{report['peak_rss_bytes_total'][name] / 2**20:>28.0f}{per_rank:>24}"
            f"{report['seconds_since_start'][name]:>9.1f}"
        )
    verdict = "within" if report["within_target"] else "ABOVE"
    lines.append(
        f"peak {report['peak_rss_bytes'] / 2**30:.2f} GiB, {verdict} the target of "
        f"{report['target_bytes'] / 2**30:.0f} GiB"
    )
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``bench memory``."""
    parser.add_argument(
        "--cells", type=int, default=20, help="cells per edge (default 20; 70 gives ~1.07 M dofs)"
    )
    parser.add_argument("--ranks", type=int, default=1, help="MPI ranks (default 1)")
    parser.add_argument("--json", help="write the JSON report here (default: stdout)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)


def command(arguments: argparse.Namespace) -> int:
    """Run ``bench memory`` (or, with ``--worker``, the measurement itself under mpirun)."""
    if arguments.worker:
        from mpi4py import MPI

        result = measure(arguments.cells)
        if MPI.COMM_WORLD.rank == 0:
            with open(arguments.json, "w", encoding="utf-8") as file:
                json.dump(result, file)
        return 0
    report = run(arguments.cells, arguments.ranks)
    common.emit(report, table(report), arguments.json)
    return 0
