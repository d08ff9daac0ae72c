"""Scenes as their meshes grow: outcome, Newton and Krylov counts, cost and memory per step.

``python -m dolfinx_invertible bench scenes [--scenes collapse scatter compress-block stretch-bar]
[--resolutions 8 16 24 32 48] [--ranks 1 2] [--paths direct iterative] [--globalization line-search
trust-region] [--steps N] [--max-cuts N] [--json PATH]`` runs every scene at every resolution on
every rank count, solver path (``--linear-solver``) and globalization (``--globalization``; the
trust region on the iterative path only), each run a child process under ``mpirun -n`` with the
scene's defaults otherwise, and writes one row per run: cells, unknowns, solver path, outcome,
steps, Newton iterations per step, Krylov iterations per Newton iteration, seconds per step, seconds
per step per 10⁵ unknowns and the peak resident memory of the largest rank. ``--steps N`` stops each
run after N time steps (at t = N dt; the scene's loading keeps its schedule over t_end, so these are
the first N steps of the whole scene, and a relaxation ends "not at rest" unless it got there), for
sizes whose full run takes too long; the table says which rows were cut short. ``--max-cuts N``
gives every run that budget of cuts of a failing step instead of the scene's 6. ``--single
SCENE:RESOLUTION:RANKS:PATH`` runs one row (the 10⁶-unknown collapse of the docs). ``--timeout
SECONDS`` ends a run that takes longer (all of its processes) and its row says how far it got: the
worker records its progress after every attempt of a step, and the row of a run that timed out (or
broke) carries the time reached, the steps, attempts and iterations up to then, and why the last
failed attempt failed.

Targets (docs/performance.md, "Scale"): the outcome at every resolution equals resolution 8's
on both paths; Newton iterations per step at resolution 48 within 1.5× of resolution 8's;
Krylov iterations per Newton iteration within 2× across resolutions; seconds per step per
unknown at resolution 48 within 2× of resolution 16's.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import tempfile
import time

from benchmarks import common

SCENES = ("collapse", "scatter", "compress-block", "stretch-bar")
RESOLUTIONS = (8, 16, 24, 32, 48)
PATHS = ("direct", "iterative")


def measure(
    scene_name: str,
    resolution: int,
    path: str,
    steps: int | None,
    pc: str,
    elastic: str,
    progress: str | None = None,
    globalization: str = "auto",
    max_cuts: int | None = None,
) -> dict:
    """Run one scene on ``MPI.COMM_WORLD`` (collective); a JSON-ready row.

    With ``progress``, rank 0 writes there after every attempt and step how far the run has got
    (the row of a run that is stopped before it ends, :func:`_unfinished_row`).
    """
    from mpi4py import MPI

    from dolfinx_invertible.scenes import Parameters, RunObserver, get_scene, run_scene

    comm = MPI.COMM_WORLD
    scene = get_scene(scene_name)
    values = {
        **scene.defaults,
        "resolution": resolution,
        "linear_solver": path,
        "pc": pc,
        "elastic": elastic,
        "globalization": globalization,
    }
    if max_cuts is not None:
        values["max_cuts"] = max_cuts
    if steps is not None:
        if scene.dynamic:
            values["t_stop"] = steps * values.get("dt", Parameters.dt)
        else:
            values["steps"] = steps
    parameters = Parameters(**values)

    class Timer(RunObserver):
        def __init__(self):
            self.started = 0.0
            self.cells = 0
            self.unknowns = 0
            self.attempts = 0
            self.newton_all_attempts = 0
            self.last_failure: str | None = None
            self.globalization = globalization

        def start(self, run) -> None:
            self.started = time.perf_counter()
            self.globalization = run.minimizer.globalization
            self.cells = run.mesh.topology.index_map(run.mesh.topology.dim).size_global
            space = run.u.function_space
            self.unknowns = space.dofmap.index_map.size_global * space.dofmap.index_map_bs
            self._write_progress(run)

        def attempt(self, run, attempt) -> None:
            self.attempts += 1
            result = attempt.result
            self.newton_all_attempts += result.newton_iterations
            if not attempt.accepted:
                self.last_failure = (
                    f"dt = {attempt.end - attempt.start:.3g}: {result.stage} failed "
                    f"({result.reason_name}) after {result.newton_iterations} Newton iterations"
                )
            self._write_progress(run)  # a step may fail many attempts before it completes

        def step(self, run) -> None:
            self._write_progress(run)

        def _write_progress(self, run) -> None:
            if progress is None or comm.rank != 0:
                return
            record = {
                "cells": self.cells,
                "unknowns": self.unknowns,
                "steps": run.statistics.steps,
                "time": run.time,
                "stop_time": parameters.stop_time,
                "attempts": self.attempts,
                "newton": run.statistics.newton_iterations["total"],
                "newton_all_attempts": self.newton_all_attempts,
                "krylov": run.statistics.linear_iterations,
                "stepping_seconds": time.perf_counter() - self.started,
                "last_failure": self.last_failure,
            }
            with open(progress + ".partial", "w", encoding="utf-8") as file:
                json.dump(record, file)
            os.replace(progress + ".partial", progress)

    timer = Timer()
    summary = run_scene(scene, parameters, output=None, comm=comm, observers=[timer])
    stepping_seconds = time.perf_counter() - timer.started
    peak = comm.allreduce(common.peak_rss_bytes(), op=MPI.MAX)
    steps_taken = max(summary["steps"], 1)
    newton = summary["newton_iterations"]["total"]
    return {
        "scene": scene_name,
        "resolution": resolution,
        "ranks": comm.size,
        "path": path,
        "pc": pc,
        "elastic": summary["parameters"]["elastic"],  # the route the run took
        "globalization": timer.globalization,  # what "auto" chose
        "cells": timer.cells,
        "unknowns": summary["dofs"],
        "outcome": summary["outcome"],
        "completed": summary["completed"],
        "cut_short": steps is not None,
        "max_cuts": summary["parameters"]["max_cuts"],
        "steps": summary["steps"],
        "attempts": timer.attempts,
        "cuts": summary["stepping"].get("cuts"),
        "escalations": summary["stepping"].get("escalations"),
        "newton": newton,
        "krylov": summary["linear_iterations"],
        "stepping_seconds": stepping_seconds,
        **_rates(
            steps_taken, newton, summary["linear_iterations"], stepping_seconds, summary["dofs"]
        ),
        "peak_rss_mib": peak / 2**20,
        "reason": summary.get("reason"),
    }


def run(
    scenes,
    resolutions,
    ranks,
    paths,
    steps: int | None,
    pc: str,
    timeout: float,
    elastic=("kernels",),
    globalizations=("auto",),
    max_cuts: int | None = None,
) -> dict:
    """Run every combination in a child process each; return the report.

    A trust region runs on the iterative path only: its combinations with the direct path are
    left out.
    """
    report: dict = {"benchmark": "scenes", "machine": common.machine(), "rows": []}
    with tempfile.TemporaryDirectory(prefix="bench_scenes_") as directory:
        for scene, resolution, count, path, route, globalization in itertools.product(
            scenes, resolutions, ranks, paths, elastic, globalizations
        ):
            if globalization == "trust-region" and path == "direct":
                continue
            single = f"{scene}:{resolution}:{count}:{path}"
            report["rows"].append(
                _child(directory, single, steps, pc, route, timeout, globalization, max_cuts)
            )
            print(_row_text(report["rows"][-1]), flush=True)
    common.record_load_after(report)
    return report


def _child(directory, single, steps, pc, elastic, timeout, globalization, max_cuts) -> dict:
    scene, resolution, count, path = single.split(":")
    name = f"{single.replace(':', '-')}-{elastic}-{globalization}.json"
    output = os.path.join(directory, name)
    arguments = ["--worker", "--single", single, "--pc", pc, "--elastic", elastic]
    arguments += ["--globalization", globalization, "--json", output]
    if steps is not None:
        arguments += ["--steps", str(steps)]
    if max_cuts is not None:
        arguments += ["--max-cuts", str(max_cuts)]
    command = common.bench_command("scenes", arguments, int(count))
    row = {
        "scene": scene,
        "resolution": int(resolution),
        "ranks": int(count),
        "path": path,
        "pc": pc,
        "elastic": elastic,
        "globalization": globalization,
        "cut_short": steps is not None,
        "max_cuts": max_cuts,
    }
    started = time.perf_counter()
    try:
        wall = common.run_child(command, common.child_environment(), timeout)
    except Exception as error:  # a run that breaks is a row of the table, not its end
        outcome = "timed out" if isinstance(error, common.ChildTimeoutError) else "error"
        row["process_wall_seconds"] = time.perf_counter() - started
        return _unfinished_row(row, outcome, str(error)[-500:], _progress_path(output))
    with open(output, encoding="utf-8") as file:
        row = json.load(file)
    row["process_wall_seconds"] = wall
    return row


def _progress_path(output: str) -> str:
    return output + ".progress"


def _unfinished_row(row: dict, outcome: str, reason: str, progress: str) -> dict:
    """The row of a run that did not finish: how far it got, from its progress file."""
    row = {**row, "outcome": outcome, "reason": reason}
    try:
        with open(progress, encoding="utf-8") as file:
            reached = json.load(file)
    except (OSError, ValueError):  # stopped before its first record
        return row
    steps = max(reached["steps"], 1)
    newton = reached["newton"]
    seconds = reached["stepping_seconds"]
    row.update(
        cells=reached["cells"],
        unknowns=reached["unknowns"],
        steps=reached["steps"],
        reached_time=reached["time"],
        stop_time=reached["stop_time"],
        attempts=reached["attempts"],
        newton=newton,
        newton_all_attempts=reached["newton_all_attempts"],
        krylov=reached["krylov"],
        stepping_seconds=seconds,
        last_failure=reached["last_failure"],
    )
    if reached["steps"] > 0:
        row.update(_rates(steps, newton, reached["krylov"], seconds, reached["unknowns"]))
    return row


def _rates(steps: int, newton: int, krylov: int, seconds: float, unknowns: int) -> dict:
    """The per-step and per-iteration figures of a row (``steps`` at least 1)."""
    return {
        "newton_per_step": newton / steps,
        "krylov_per_newton": krylov / max(newton, 1),
        "seconds_per_step": seconds / steps,
        "seconds_per_newton": seconds / max(newton, 1),
        "seconds_per_step_per_1e5": seconds / steps / (unknowns / 1e5),
    }


#: (key, heading, width, format of a value) of the table's columns.
_COLUMNS = (
    ("scene", "scene", 15, "<"),
    ("resolution", "res", 4, ">"),
    ("ranks", "np", 3, ">"),
    ("path", "path", 10, ">"),
    ("elastic", "elastic", 7, ">"),
    ("globalization", "globalization", 13, ">"),
    ("cells", "cells", 9, ">"),
    ("unknowns", "unknowns", 9, ">"),
    ("outcome", "outcome", 17, ">"),
    ("steps", "steps", 6, ">"),
    ("newton_per_step", "Newton/st", 9, ">.2f"),
    ("krylov_per_newton", "Kryl/Newt", 9, ">.1f"),
    ("seconds_per_step", "s/step", 9, ">.2f"),
    ("seconds_per_newton", "s/Newton", 9, ">.3f"),
    ("seconds_per_step_per_1e5", "s/st/1e5", 9, ">.2f"),
    ("peak_rss_mib", "MiB/rank", 8, ">.0f"),
)


def _row_text(row: dict) -> str:
    parts = []
    for key, _, width, form in _COLUMNS:
        value = row.get(key)
        parts.append(("—" if value is None else format(value, form)).rjust(width))
    text = " ".join(parts)
    if row.get("cut_short"):
        text += "  (cut short)"
    if "reached_time" in row:
        text += (
            f"  ({row['outcome']} after {row['process_wall_seconds']:.0f} s at t = "
            f"{row['reached_time']:.4g} of {row['stop_time']:.4g}: {row['steps']} steps, "
            f"{row['attempts']} attempts, {row['newton_all_attempts']} Newton iterations)"
        )
        if row["last_failure"]:
            text += f"  (last failed attempt: {row['last_failure']})"
    elif row.get("outcome") in ("error", "timed out"):
        lines = [line for line in str(row.get("reason", "")).splitlines() if line.strip()]
        text += f"  ({lines[-1].strip() if lines else 'no output'})"
    return text


def table(report: dict) -> str:
    """Return the report as a table (one line per run)."""
    header = " ".join(heading.rjust(width) for _, heading, width, _ in _COLUMNS)
    return common.rows_table("scenes", report, header, _row_text)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``bench scenes``."""
    from dolfinx_invertible.choices import ELASTIC_ROUTES, GLOBALIZATIONS, PRECONDITIONERS

    parser.add_argument("--scenes", nargs="+", default=list(SCENES), help="scenes to run")
    parser.add_argument(
        "--resolutions", type=int, nargs="+", default=[8, 16], help="resolutions (default 8 16)"
    )
    parser.add_argument("--ranks", type=int, nargs="+", default=[2], help="rank counts (default 2)")
    parser.add_argument(
        "--paths", nargs="+", default=list(PATHS), choices=PATHS, help="linear solver paths"
    )
    parser.add_argument(
        "--pc", default="gamg", choices=list(PRECONDITIONERS), help="AMG (iterative)"
    )
    parser.add_argument(
        "--elastic",
        nargs="+",
        default=["kernels"],
        choices=list(ELASTIC_ROUTES),
        help="how the elastic energy is assembled: this package's kernels, DOLFINx's UFL route "
        "(plain Neo-Hookean; only where nothing inverts), or both for a paired comparison "
        "(default kernels)",
    )
    parser.add_argument(
        "--globalization",
        nargs="+",
        default=["auto"],
        choices=list(GLOBALIZATIONS),
        help="Newton's globalization: the trust region on the iterative path and the line search "
        "on the direct one (auto), the energy line search, the trust region (iterative path "
        "only), or two of them for a paired comparison (default auto)",
    )
    parser.add_argument("--steps", type=int, help="stop every run after this many steps")
    parser.add_argument(
        "--max-cuts",
        type=int,
        dest="max_cuts",
        help="consecutive cuts of a failing step before a run stops (default: the scenes' 6)",
    )
    parser.add_argument(
        "--single", metavar="SCENE:RESOLUTION:RANKS:PATH", help="run this one row only"
    )
    parser.add_argument("--timeout", type=float, default=6 * 3600.0, help="seconds per run")
    parser.add_argument("--json", help="write the JSON report here (default: stdout)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)


def command(arguments: argparse.Namespace) -> int:
    """Run ``bench scenes`` (or, with ``--worker``, one row under mpirun)."""
    if arguments.worker:
        from mpi4py import MPI

        scene, resolution, _, path = arguments.single.split(":")
        (elastic,) = arguments.elastic
        (globalization,) = arguments.globalization
        row = measure(
            scene,
            int(resolution),
            path,
            arguments.steps,
            arguments.pc,
            elastic,
            progress=_progress_path(arguments.json),
            globalization=globalization,
            max_cuts=arguments.max_cuts,
        )
        if MPI.COMM_WORLD.rank == 0:
            with open(arguments.json, "w", encoding="utf-8") as file:
                json.dump(row, file)
        return 0
    if arguments.single:
        scene, resolution, ranks, path = arguments.single.split(":")
        selection = ([scene], [int(resolution)], [int(ranks)], [path])
    else:
        selection = (arguments.scenes, arguments.resolutions, arguments.ranks, arguments.paths)
    report = run(
        *selection,
        arguments.steps,
        arguments.pc,
        arguments.timeout,
        arguments.elastic,
        arguments.globalization,
        arguments.max_cuts,
    )
    common.emit(report, table(report), arguments.json)
    return 0
