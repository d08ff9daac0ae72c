"""Compilation benchmark: cold and warm first assembly, and ranks racing on an empty cache.

``python -m dolfinx_invertible bench compile [--cells 6] [--race-repeats 3] [--json PATH]``

- cold: a child process with a fresh, empty ``NUMBA_CACHE_DIR`` builds our Neo-Hookean + C2
  residual and tangent forms (which compiles their kernels) on a small P1 mesh and assembles them
  once (the energy kernel is compiled afterwards, outside the measured time, for the
  comparison); reported is the time from the child's launch (interpreter start and imports
  included) to the first assembled residual + tangent, with the phases;
- warm: the same in a second child on the cache the first one filled;
- race: ``mpirun -n 2`` children started on a fresh, empty shared cache, so both ranks compile
  and write the same cache entries at the same time, then a second ``mpirun -n 2`` that loads
  what they wrote; both must reproduce the serial run's residual, tangent action and energy
  (compared per dof, matched by dof coordinates; relative tolerance 1e-10). Repeated
  ``--race-repeats`` times, each on its own empty cache.

Targets: cold ≤ 15 s, warm ≤ 2 s. Each cold compile takes tens of seconds, so the whole
command takes minutes; the two-rank cold runs compile on both cores at once.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
import time

import numpy as np

from benchmarks import common

COLD_TARGET_SECONDS = 15.0
WARM_TARGET_SECONDS = 2.0
AGREEMENT_TOLERANCE = 1.0e-10
_LAUNCH_VARIABLE = "DOLFINX_INVERTIBLE_BENCH_LAUNCH"


def _gather_by_coordinates(comm, coordinates: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Owned nodal values of all ranks on rank 0, ordered by node coordinates (else empty)."""
    gathered = comm.gather((coordinates, values), root=0)
    if comm.rank != 0:
        return np.empty((0, values.shape[1]))
    points = np.concatenate([item[0] for item in gathered])
    data = np.concatenate([item[1] for item in gathered])
    rounded = np.round(points, 12)
    order = np.lexsort((rounded[:, 2], rounded[:, 1], rounded[:, 0]))
    return data[order]


def first_assembly(cells: int, launch_time: float | None = None) -> tuple[dict, dict]:
    """Build our forms and assemble residual and tangent once on ``MPI.COMM_WORLD``.

    Returns
    -------
    tuple of dict
        Phase times in seconds since ``launch_time`` (default: the call) and, on rank 0, the
        results to compare: the residual and the tangent applied to a smooth vector, both per
        node in coordinate order, and the energy.
    """
    start = time.time() if launch_time is None else launch_time
    phases = {"python_started": time.time() - start}
    from mpi4py import MPI

    import dolfinx
    import dolfinx.fem.petsc

    from dolfinx_invertible import HyperelasticForms, _compat

    phases["imported"] = time.time() - start
    comm = MPI.COMM_WORLD
    space = common.unit_cube_space(comm, cells, 1)
    u = dolfinx.fem.Function(space)
    # Compressed towards x = 1, so some points are on the fast path and some in the extension.
    u.interpolate(lambda x: np.stack([-0.2 * x[0] ** 2, 0.02 * np.sin(3 * x[2]), 0.0 * x[1]]))
    u.x.scatter_forward()
    elastic, _, _ = common.material()
    forms = HyperelasticForms(u, elastic)
    # Reading the forms compiles (or loads) their kernels, if the constructor did not already.
    residual, jacobian = forms.residual, forms.jacobian
    phases["forms_built"] = time.time() - start
    vector = dolfinx.fem.petsc.assemble_vector(residual)
    vector.ghostUpdate(addv=_petsc_add(), mode=_petsc_reverse())
    matrix = dolfinx.fem.petsc.assemble_matrix(jacobian)
    matrix.assemble()
    phases["assembled"] = time.time() - start
    # The energy kernel, compiled after the measured window: the first Newton step needs only
    # residual and tangent.
    energy = comm.allreduce(dolfinx.fem.assemble_scalar(forms.energy), op=MPI.SUM)

    smooth = dolfinx.fem.Function(space)
    smooth.interpolate(lambda x: np.stack([np.cos(x[1]), x[0] * x[2], np.sin(2 * x[0])]))
    action = matrix.createVecLeft()
    matrix.mult(_compat.petsc_vector(smooth), action)
    owned = space.dofmap.index_map.size_local
    coordinates = space.tabulate_dof_coordinates()[:owned]
    results = {
        "residual": _gather_by_coordinates(comm, coordinates, vector.array.reshape(-1, 3)),
        "tangent_action": _gather_by_coordinates(comm, coordinates, action.array.reshape(-1, 3)),
        "energy": np.array([energy]),
    }
    return phases, results


def _petsc_add():
    from petsc4py import PETSc

    return PETSc.InsertMode.ADD


def _petsc_reverse():
    from petsc4py import PETSc

    return PETSc.ScatterMode.REVERSE


def _source_stamps() -> dict:
    """Modification times of the package's source files: numba keys its cache on them."""
    import dolfinx_invertible

    package = os.path.dirname(os.path.abspath(dolfinx_invertible.__file__))
    stamps = {}
    for folder, _, files in os.walk(package):
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                stamps[os.path.relpath(path, package)] = os.stat(path).st_mtime
    return stamps


def relative_difference(results: dict, reference: dict) -> float:
    """Largest relative difference over the compared quantities (inf on a shape mismatch)."""
    worst = 0.0
    for name, expected in reference.items():
        actual = results[name]
        if actual.shape != expected.shape:
            return float("inf")
        if expected.size == 0:  # ranks other than 0 hold no gathered values
            continue
        scale = max(float(np.max(np.abs(expected))), 1e-300)
        worst = max(worst, float(np.max(np.abs(actual - expected))) / scale)
    return worst


def _child(cells: int, cache: str, output: str, ranks: int | None, timeout: float) -> dict:
    """One worker process (or mpirun job) on numba cache ``cache``; its report and results."""
    arguments = ["--worker", "--cells", str(cells), "--json", output + ".json"]
    command = common.bench_command("compile", arguments, ranks)
    environment = common.child_environment(NUMBA_CACHE_DIR=cache)
    environment[_LAUNCH_VARIABLE] = repr(time.time())
    wall = common.run_child(command, environment, timeout)
    with open(output + ".json", encoding="utf-8") as file:
        report = json.load(file)
    with np.load(output + ".npz") as data:
        results = {name: data[name] for name in data.files}
    report["process_wall_seconds"] = wall
    report["cache_files"] = sum(len(files) for _, _, files in os.walk(cache))
    return report, results


def run(cells: int, race_repeats: int, timeout: float = 1800.0) -> dict:
    """Cold, warm and race runs in child processes; a JSON-ready report.

    Parameters
    ----------
    cells
        Cells per edge of the unit cube (P1); small, since compilation is what is measured.
    race_repeats
        Number of ``mpirun -n 2`` runs on a fresh empty cache (each followed by a warm one).
    timeout
        Seconds before a child is considered hung.
    """
    report: dict = {
        "benchmark": "compile",
        "cells_per_edge": cells,
        "targets_seconds": {"cold": COLD_TARGET_SECONDS, "warm": WARM_TARGET_SECONDS},
        "agreement_tolerance": AGREEMENT_TOLERANCE,
        "machine": common.machine(),
    }
    stamps = _source_stamps()
    directory = tempfile.mkdtemp(prefix="bench_compile_")
    try:
        cache = os.path.join(directory, "cache_serial")
        os.mkdir(cache)
        cold, reference = _child(cells, cache, os.path.join(directory, "cold"), None, timeout)
        warm, warm_results = _child(cells, cache, os.path.join(directory, "warm"), None, timeout)
        cold["difference_to_warm"] = relative_difference(reference, warm_results)
        report["cold"], report["warm"] = cold, warm
        races = []
        for index in range(race_repeats):
            cache = os.path.join(directory, f"cache_race{index}")
            os.mkdir(cache)
            entry = {}
            for stage in ("empty_cache", "cache_written_by_race"):
                output = os.path.join(directory, f"race{index}_{stage}")
                child, results = _child(cells, cache, output, 2, timeout)
                child["difference_to_serial"] = relative_difference(results, reference)
                child["agrees"] = bool(child["difference_to_serial"] <= AGREEMENT_TOLERANCE)
                entry[stage] = child
            races.append(entry)
        report["race"] = races
    finally:
        shutil.rmtree(directory, ignore_errors=True)
    report["cold_seconds"] = report["cold"]["phases"]["assembled"]
    report["warm_seconds"] = report["warm"]["phases"]["assembled"]
    # An edit of the package during the run makes numba recompile in a "warm" run.
    changed = sorted(name for name, stamp in _source_stamps().items() if stamps.get(name) != stamp)
    report["sources_changed_during_run"] = changed
    report["race_ok"] = all(stage["agrees"] for entry in races for stage in entry.values())
    common.record_load_after(report)
    return report


def table(report: dict) -> str:
    """Return the report as a human-readable table."""
    lines = [
        f"compile benchmark: P1 unit cube {report['cells_per_edge']}^3 x 6, "
        f"{common.load_text(report)}",
        "seconds since process launch:",
        f"{'run':<34}{'started':>9}{'imported':>10}{'forms':>9}{'assembled':>11}{'target':>8}",
    ]
    for name in ("cold", "warm"):
        phases = report[name]["phases"]
        lines.append(
            f"{name + ' (1 process)':<34}{phases['python_started']:>9.2f}"
            f"{phases['imported']:>10.2f}"
            f"{phases['forms_built']:>9.2f}{phases['assembled']:>11.2f}"
            f"{report['targets_seconds'][name]:>8.0f}"
        )
    for index, entry in enumerate(report["race"]):
        for stage, child in entry.items():
            phases = child["phases"]
            verdict = "agrees" if child["agrees"] else "DIFFERS"
            lines.append(
                f"{f'race {index} mpirun -n 2, {stage}':<34}{phases['python_started']:>9.2f}"
                f"{phases['imported']:>10.2f}{phases['forms_built']:>9.2f}"
                f"{phases['assembled']:>11.2f}  max rel. diff to serial "
                f"{child['difference_to_serial']:.1e} ({verdict})"
            )
    lines.append(f"race check: {'ok' if report['race_ok'] else 'FAILED'}")
    if report["sources_changed_during_run"]:
        lines.append(
            "warning: package sources changed during the run; later runs may have recompiled: "
            + ", ".join(report["sources_changed_during_run"])
        )
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``bench compile``."""
    parser.add_argument("--cells", type=int, default=6, help="cells per edge (default 6)")
    parser.add_argument(
        "--race-repeats", type=int, default=3, help="empty-cache mpirun -n 2 runs (default 3)"
    )
    parser.add_argument("--json", help="write the JSON report here (default: stdout)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)


def command(arguments: argparse.Namespace) -> int:
    """Run ``bench compile``; exit code 1 if a race run disagreed with the serial run."""
    if arguments.worker:
        from mpi4py import MPI

        launch = os.environ.get(_LAUNCH_VARIABLE)
        phases, results = first_assembly(arguments.cells, float(launch) if launch else None)
        if MPI.COMM_WORLD.rank == 0:
            stem = arguments.json[: -len(".json")]
            np.savez(stem + ".npz", **results)
            with open(arguments.json, "w", encoding="utf-8") as file:
                json.dump({"ranks": MPI.COMM_WORLD.size, "phases": phases}, file)
        return 0
    report = run(arguments.cells, arguments.race_repeats)
    common.emit(report, table(report), arguments.json)
    return 0 if report["race_ok"] else 1
