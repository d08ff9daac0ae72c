"""Contact scenes: counts and where a run's time goes, on 1 and 2 ranks.

``python -m dolfinx_invertible bench contact [--scenes cubes-in-bowl links] [--resolutions 2 3 4]
[--ranks 1 2] [--paths direct] [--count N] [--json PATH]`` runs every scene at every resolution
(default: the scene's own), rank count and solver path (``--linear-solver``), each run a child
process under ``mpirun -n`` with the scene's defaults otherwise, and writes one row per run:
cells, surface vertices, steps, cuts, Newton iterations per step, Krylov iterations per Newton
iteration, the run's stepping time, and the shares of that time (rank 0's) in

- **candidates**: ipctk's broad and narrow phase, the collision sets of the body contact term
  (built once per new state) and the search for its smallest distance;
- **CCD**: the step caps, continuous collision detection along each Newton direction (surfaces
  and obstacles);
- **barrier**: the body contact term's energy, gradient and Hessian assembled (friction
  included where the scene has it), outside the candidates;
- **obstacles**: the obstacle term's energy, gradient and Hessian (the bowl);
- **elastic**: the finite-element energy, residual and tangent (everything the problem
  assembles but the terms);
- **linear**: PETSc's ``KSPSolve`` and the preconditioner's set-ups (MUMPS's factorisations,
  AMG's hierarchies) outside it: the linear solves whole;

and the rest (the line search's bookkeeping, the diagnostics of every step, Python). Shares are
exclusive: a collision set built inside an energy evaluation counts as candidates, not barrier.
The timers wrap the classes' methods in the worker process only.
"""

from __future__ import annotations

import argparse
import collections
import functools
import itertools
import json
import os
import tempfile
import time

from benchmarks import common

SCENES = ("cubes-in-bowl", "links")
PATHS = ("direct", "iterative")
SHARES = ("candidates", "CCD", "barrier", "obstacles", "elastic", "linear")


class _Clock:
    """Exclusive times per category: a category's time leaves out the categories it calls."""

    def __init__(self) -> None:
        self.seconds: collections.Counter = collections.Counter()
        self._stack: list[list] = []  # [category, start, time of the calls it made]

    def wrap(self, owner, name: str, category: str) -> None:
        method = getattr(owner, name)
        clock = self

        @functools.wraps(method)
        def timed(*arguments, **keywords):
            frame = [category, time.perf_counter(), 0.0]
            clock._stack.append(frame)
            try:
                return method(*arguments, **keywords)
            finally:
                clock._stack.pop()
                elapsed = time.perf_counter() - frame[1]
                clock.seconds[category] += elapsed - frame[2]
                if clock._stack:
                    clock._stack[-1][2] += elapsed

        setattr(owner, name, timed)


def _install(clock: _Clock) -> None:
    from dolfinx_invertible.contact.body_contact import BodyContactTerm, SurfaceCollisionFreeStep
    from dolfinx_invertible.contact.step import CollisionFreeStep
    from dolfinx_invertible.contact.term import ContactTerm
    from dolfinx_invertible.solvers.problem import EnergyProblem

    clock.wrap(BodyContactTerm, "_collisions_for", "candidates")
    clock.wrap(BodyContactTerm, "minimum_distance", "candidates")
    clock.wrap(SurfaceCollisionFreeStep, "largest_step", "CCD")
    clock.wrap(CollisionFreeStep, "largest_step", "CCD")
    for name in ("energy", "add_residual", "add_tangent"):
        clock.wrap(BodyContactTerm, name, "barrier")
        clock.wrap(ContactTerm, name, "obstacles")
    for name in ("objective", "F", "J"):
        clock.wrap(EnergyProblem, name, "elastic")


def _linear_seconds() -> float:
    """PETSc's time in KSPSolve plus the preconditioner's set-ups outside it (this rank).

    The minimiser factorises before it solves (the inertia test reads the factorisation), so
    MUMPS's factorisation is a PCSetUp of its own; one inside a KSPSolve is inside its
    KSPSetUp, which is subtracted so that it counts once.
    """
    from petsc4py import PETSc

    def seconds(name: str) -> float:
        return PETSc.Log.Event(name).getPerfInfo()["time"]

    return seconds("KSPSolve") + max(seconds("PCSetUp") - seconds("KSPSetUp"), 0.0)


def measure(scene_name: str, resolution: int | None, path: str, count: int | None) -> dict:
    """Run one scene on ``MPI.COMM_WORLD`` with the timers (collective); a JSON-ready row.

    ``resolution`` and ``count`` None keep the scene's own.
    """
    from mpi4py import MPI

    from petsc4py import PETSc

    from dolfinx_invertible.scenes import Parameters, RunObserver, get_scene, run_scene

    comm = MPI.COMM_WORLD
    clock = _Clock()
    _install(clock)
    PETSc.Log.begin()
    scene = get_scene(scene_name)
    values = {**scene.defaults, "linear_solver": path}
    if resolution is not None:
        values["resolution"] = resolution
    if count is not None:
        values["count"] = count

    class Start(RunObserver):
        def __init__(self):
            self.started = 0.0
            self.cells = 0
            self.surface_vertices = 0

        def start(self, run) -> None:
            self.started = time.perf_counter()
            self.cells = run.mesh.topology.index_map(run.mesh.topology.dim).size_global
            for term in run.terms:
                surface = getattr(term, "surface", None)
                if surface is not None:
                    self.surface_vertices = len(surface)
            clock.seconds.clear()
            self.linear_before = _linear_seconds()

    start = Start()
    summary = run_scene(scene, Parameters(**values), output=None, comm=comm, observers=[start])
    seconds = time.perf_counter() - start.started
    shares = dict(clock.seconds)
    shares["linear"] = _linear_seconds() - start.linear_before
    steps = max(summary["steps"], 1)
    newton = summary["newton_iterations"]["total"]
    return {
        "scene": scene_name,
        "resolution": values.get("resolution"),
        "count": values.get("count"),
        "ranks": comm.size,
        "path": path,
        "cells": start.cells,
        "surface_vertices": start.surface_vertices,
        "outcome": summary["outcome"],
        "steps": summary["steps"],
        "cuts": summary["stepping"].get("cuts"),
        "newton": newton,
        "newton_per_step": newton / steps,
        "krylov_per_newton": summary["linear_iterations"] / max(newton, 1),
        "failed_attempts_seconds": summary.get("failed_attempts_wall_time"),
        "intersections": summary.get("intersections"),
        "min_distance": summary.get("min_distance"),
        "seconds": seconds,
        "shares": {name: shares.get(name, 0.0) / seconds for name in SHARES},
    }


def run(scenes, resolutions, ranks, paths, count: int | None, timeout: float) -> dict:
    """Run every combination in a child process each; return the report."""
    report: dict = {"benchmark": "contact", "machine": common.machine(), "rows": []}
    with tempfile.TemporaryDirectory(prefix="bench_contact_") as directory:
        for scene, resolution, ranks_count, path in itertools.product(
            scenes, resolutions or [None], ranks, paths
        ):
            output = os.path.join(directory, f"{scene}-{resolution}-{ranks_count}-{path}.json")
            arguments = ["--worker", "--scenes", scene, "--paths", path, "--json", output]
            if resolution is not None:
                arguments += ["--resolutions", str(resolution)]
            if count is not None:
                arguments += ["--count", str(count)]
            command = common.bench_command("contact", arguments, ranks_count)
            common.run_child(command, common.child_environment(), timeout)
            with open(output, encoding="utf-8") as file:
                report["rows"].append(json.load(file))
            print(_row_text(report["rows"][-1]), flush=True)
    common.record_load_after(report)
    return report


_HEADER = (
    "scene           res ranks path       cells surface  steps cuts Newton/step Krylov/Newton"
    "      s " + " ".join(f"{name:>10s}" for name in SHARES) + "  rest"
)


def _row_text(row: dict) -> str:
    shares = row["shares"]
    rest = 1.0 - sum(shares.values())
    scene = row["scene"] + (f" ×{row['count']}" if row.get("count") else "")
    return (
        f"{scene:15s} {row['resolution']:3d} {row['ranks']:5d} {row['path']:9s}"
        f" {row['cells']:6d} {row['surface_vertices']:7d} {row['steps']:6d} {row['cuts']:4d}"
        f" {row['newton_per_step']:11.1f} {row['krylov_per_newton']:13.1f} {row['seconds']:6.1f} "
        + " ".join(f"{shares[name]:10.1%}" for name in SHARES)
        + f" {rest:5.1%}"
    )


def table(report: dict) -> str:
    """Return the report as a table (one line per run)."""
    return common.rows_table("contact", report, _HEADER, _row_text)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``bench contact``."""
    parser.add_argument("--scenes", nargs="+", default=list(SCENES), help="scenes to run")
    parser.add_argument(
        "--resolutions", type=int, nargs="+", help="resolutions (default: each scene's own)"
    )
    parser.add_argument(
        "--ranks", type=int, nargs="+", default=[1, 2], help="rank counts (default 1 2)"
    )
    parser.add_argument(
        "--paths", nargs="+", default=["direct"], choices=PATHS, help="linear solver paths"
    )
    parser.add_argument("--count", type=int, help="cubes in the bowl (cubes-in-bowl only)")
    parser.add_argument("--timeout", type=float, default=6 * 3600.0, help="seconds per run")
    parser.add_argument("--json", help="write the JSON report here (default: stdout)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)


def command(arguments: argparse.Namespace) -> int:
    """Run ``bench contact`` (or, with ``--worker``, one row under mpirun)."""
    if arguments.worker:
        from mpi4py import MPI

        (resolution,) = arguments.resolutions or [None]
        row = measure(arguments.scenes[0], resolution, arguments.paths[0], arguments.count)
        if MPI.COMM_WORLD.rank == 0:
            with open(arguments.json, "w", encoding="utf-8") as file:
                json.dump(row, file)
        return 0
    report = run(
        arguments.scenes,
        arguments.resolutions,
        arguments.ranks,
        arguments.paths,
        arguments.count,
        arguments.timeout,
    )
    common.emit(report, table(report), arguments.json)
    return 0
