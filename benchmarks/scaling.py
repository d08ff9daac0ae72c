"""MPI scaling benchmark: the same P1 problem on 1 and on 2 ranks.

``python -m dolfinx_invertible bench scaling [--cells 20] [--repeats 5] [--ranks 1 2]
[--cases a_ufl b_fast] [--json PATH]`` runs itself under ``mpirun -n 1`` and ``mpirun -n 2``
(one child process each, so every run starts clean) on the unit cube of cells³ × 6 P1
tetrahedra, and times in each, with interleaved repeats (medians of the slowest rank's time):
residual assembly, tangent assembly, and one Newton step (assembly with the Dirichlet condition
+ CG/GAMG solve with the solver's default options), for our Neo-Hookean + C2 kernels on the fast
path (``b_fast``) and, as a reference for what the machine allows, FFCx's UFL Neo-Hookean
(``a_ufl``); see :mod:`benchmarks.common`. Reported: seconds, the speed-up
t(1 rank) / t(n ranks) and dofs per second. The quick default has 27 783 dofs; the full size
(≥ 300 k dofs) is ``--cells 47`` (331 776 dofs).

The speed-up is bounded by the cores actually free: on a shared two-core machine another busy
process takes a core from the two-rank run, so the load average is recorded before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile

from benchmarks import common

OPERATIONS = ("residual", "tangent", "newton_step")
DEFAULT_CASES = ("a_ufl", "b_fast")
SPEED_UP_TARGET = 1.6


def measure(cells: int, repeats: int, cases: tuple[str, ...] = DEFAULT_CASES) -> dict:
    """Time the operations on ``MPI.COMM_WORLD`` (collective); a JSON-ready dict.

    This is what each ``mpirun`` child runs.
    """
    from mpi4py import MPI

    from benchmarks.assembly import case_jobs

    comm = MPI.COMM_WORLD
    space = common.unit_cube_space(comm, cells, 1)
    built = {name: common.build_case(name, space) for name in cases}
    jobs, krylov = {}, {}
    for name, case in built.items():
        case_job, krylov[name] = case_jobs(case)
        jobs.update({(name, operation): job for operation, job in case_job.items()})
    samples = common.interleaved(jobs, repeats, comm)
    seconds: dict = {name: {} for name in cases}
    for (name, operation), values in samples.items():
        seconds[name][operation] = statistics.median(values)
    return {
        "ranks": comm.size,
        "cells": space.mesh.topology.index_map(3).size_global,
        "dofs": space.dofmap.index_map.size_global * space.dofmap.index_map_bs,
        "repeats": repeats,
        "median_seconds": seconds,
        "krylov_iterations": {name: value["iterations"][-1] for name, value in krylov.items()},
    }


def run(
    cells: int,
    repeats: int,
    ranks: tuple[int, ...] = (1, 2),
    cases: tuple[str, ...] = DEFAULT_CASES,
    timeout: float = 3600.0,
) -> dict:
    """Launch :func:`measure` under ``mpirun -n`` each of ``ranks``; speed-ups against the first.

    Returns
    -------
    dict
        JSON-ready report with each run's medians, the speed-ups t(ranks[0]) / t(n) and dofs per
        second for every case and operation.
    """
    report: dict = {
        "benchmark": "scaling",
        "cells_per_edge": cells,
        "repeats": repeats,
        "machine": common.machine(),
        "runs": {},
    }
    with tempfile.TemporaryDirectory(prefix="bench_scaling_") as directory:
        for count in ranks:
            path = os.path.join(directory, f"ranks{count}.json")
            arguments = ["--worker", "--cells", str(cells), "--repeats", str(repeats)]
            arguments += ["--cases", *cases, "--json", path]
            command = common.bench_command("scaling", arguments, count)
            load_before = list(os.getloadavg())
            wall = common.run_child(command, common.child_environment(), timeout)
            with open(path, encoding="utf-8") as file:
                run_report = json.load(file)
            run_report["process_wall_seconds"] = wall
            # Other processes on the machine take cores from the multi-rank runs: keep the record.
            run_report["load_average_before"] = load_before
            run_report["load_average_after"] = list(os.getloadavg())
            report["runs"][str(count)] = run_report
    first = report["runs"][str(ranks[0])]
    report["dofs"] = first["dofs"]
    report["speed_up"] = {}
    report["dofs_per_second"] = {}
    for count in ranks:
        run_report = report["runs"][str(count)]
        for name in cases:
            for operation in OPERATIONS:
                elapsed = run_report["median_seconds"][name][operation]
                key = f"{name}/{operation}"
                report["dofs_per_second"].setdefault(key, {})[str(count)] = first["dofs"] / elapsed
                report["speed_up"].setdefault(key, {})[str(count)] = (
                    first["median_seconds"][name][operation] / elapsed
                )
    report["speed_up_target"] = SPEED_UP_TARGET
    common.record_load_after(report)
    return report


def table(report: dict) -> str:
    """Return the report as a human-readable table."""
    ranks = list(report["runs"])
    lines = [
        f"scaling benchmark: unit cube P1, {report['dofs']} dofs, medians of "
        f"{report['repeats']} (slowest rank), {common.load_text(report)}",
        f"{'case/operation':<22}"
        + "".join(f"{'t(' + n + ') [s]':>12}" for n in ranks)
        + "".join(f"{'speed-up ' + n:>12}" for n in ranks[1:])
        + "".join(f"{'Mdofs/s ' + n:>12}" for n in ranks),
    ]
    for key, speed_ups in report["speed_up"].items():
        name, operation = key.split("/")
        times = "".join(
            f"{report['runs'][n]['median_seconds'][name][operation]:>12.4f}" for n in ranks
        )
        rates = "".join(f"{report['dofs_per_second'][key][n] / 1e6:>12.3f}" for n in ranks)
        gains = "".join(f"{speed_ups[n]:>12.2f}" for n in ranks[1:])
        lines.append(f"{key:<22}{times}{gains}{rates}")
    lines.append(f"target speed-up >= {report['speed_up_target']}")
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``bench scaling``."""
    parser.add_argument(
        "--cells", type=int, default=20, help="cells per edge (default 20; 47 gives 331 776 dofs)"
    )
    parser.add_argument("--repeats", type=int, default=5, help="timed repeats (default 5)")
    parser.add_argument(
        "--ranks", type=int, nargs="+", default=[1, 2], help="MPI rank counts (default 1 2)"
    )
    parser.add_argument(
        "--cases",
        nargs="+",
        default=list(DEFAULT_CASES),
        choices=common.CASES,
        help="benchmark cases (default a_ufl b_fast)",
    )
    parser.add_argument("--json", help="write the JSON report here (default: stdout)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)


def command(arguments: argparse.Namespace) -> int:
    """Run ``bench scaling`` (or, with ``--worker``, one measurement under mpirun)."""
    if arguments.worker:
        from mpi4py import MPI

        result = measure(arguments.cells, arguments.repeats, tuple(arguments.cases))
        if MPI.COMM_WORLD.rank == 0:
            with open(arguments.json, "w", encoding="utf-8") as file:
                json.dump(result, file)
        return 0
    report = run(arguments.cells, arguments.repeats, tuple(arguments.ranks), tuple(arguments.cases))
    common.emit(report, table(report), arguments.json)
    return 0
