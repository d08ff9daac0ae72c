"""Running the cases of the study: each a scene run in-process, sampled where it is compared."""

from __future__ import annotations

import dataclasses
import gc
import os
import pathlib
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from dolfinx_invertible.reports.error_vs_time.outputs import write_results
from dolfinx_invertible.reports.error_vs_time.study import Case, plan
from dolfinx_invertible.reports.error_vs_time.work_precision import relative_errors

__all__ = ["KRYLOV_MAX_IT", "run", "run_case"]

#: Krylov iteration cap of the iterative runs (a failed linear solve is then cut and retried).
KRYLOV_MAX_IT = 1000


def _sample_points(study: str) -> np.ndarray | None:
    if study == "twisting-column":
        along, across = np.linspace(0.0, 6.0, 13), np.linspace(0.0, 1.0, 3)
        return np.array(np.meshgrid(along, across, across, indexing="ij")).reshape(3, -1).T
    if study == "collapse":
        side = np.linspace(0.0, 1.0, 5)
        return np.array(np.meshgrid(side, side, side, indexing="ij")).reshape(3, -1).T
    return None


_SCENES = {
    "cook-membrane": "cook-membrane",
    "twisting-column": "twisting-column",
    "collapse": "collapse",
}


def _scene_class(case: Case):
    """Return the scene class of ``case``: the study's scene, or the collapse reflected."""
    from dolfinx_invertible.scenes import get_scene

    if case.start == "reflected":
        from dolfinx_invertible.reports.error_vs_time.reflected_collapse import ReflectedCollapse

        return ReflectedCollapse
    return get_scene(_SCENES[case.study])


def _parameters(case: Case, scene_class):
    from dolfinx_invertible.scenes import Parameters

    values = dict(scene_class.defaults)
    values.update(case.values)
    return Parameters(**values)


def run_case(case: Case, *, comm=None) -> tuple[dict[str, Any], np.ndarray | None]:
    """Run one case; return its row (without errors) and its samples (None if it failed)."""
    from time import perf_counter

    from mpi4py import MPI

    from dolfinx_invertible.scenes.runner import run_scene

    comm = MPI.COMM_WORLD if comm is None else comm
    scene_class = _scene_class(case)
    parameters = _parameters(case, scene_class)
    petsc = None
    if case.ksp_rtol is not None:
        petsc = {"ksp_rtol": case.ksp_rtol, "ksp_max_it": KRYLOV_MAX_IT}
    row: dict[str, Any] = {
        "name": case.name,
        "study": case.study,
        "curve": case.curve,
        "sweep": case.sweep,
        "role": "reference" if case.sweep == "reference" else "run",
        "scene": scene_class.name,
        "start": case.start,
        "model": parameters.model,
        "extension": parameters.extension,
        "degree": parameters.degree,
        "resolution": parameters.resolution,
        "h": 1.0 / parameters.resolution,
        "dt": parameters.dt if scene_class.dynamic else None,
        "t_end": parameters.t_end if scene_class.dynamic else None,
        "steps": None if scene_class.dynamic else parameters.steps,
        "scheme": parameters.scheme if scene_class.dynamic else None,
        "project": parameters.project,
        "elastic": parameters.elastic,
        "linear_solver": case.linear_solver,
        "ksp_rtol": case.ksp_rtol,
        "reference": case.reference,
        "time_reference": case.time_reference,
        "ranks": comm.size,
    }
    start = perf_counter()
    samples = None
    from dolfinx_invertible.reports.error_vs_time.probe import Probe

    probe = Probe(_sample_points(case.study))
    try:
        summary = run_scene(
            scene_class,
            parameters,
            output=None,
            petsc_options=petsc,
            comm=comm,
            observers=[probe],
            problem_options={"linear_solver": case.linear_solver},
        )
        summary.update(probe.values)
        if probe.points is None and "tip_displacement" in summary:
            summary["samples"] = [[summary["tip_displacement"]]]
    except Exception as error:  # a run that breaks is a result of the study, not its end
        row.update(completed=False, outcome="error", reason=f"{type(error).__name__}: {error}")
        row["wall_time_s"] = perf_counter() - start
        return row, None
    row["wall_time_s"] = perf_counter() - start
    stepping = summary.get("stepping") or {}
    row.update(
        completed=bool(summary["completed"]),
        outcome=summary.get("outcome"),
        dofs=summary["dofs"],
        stepping_time_s=summary.get("stepping_time_s"),
        newton_iterations=summary["newton_iterations"]["total"],
        krylov_iterations=summary["linear_iterations"],
        time_steps=stepping.get("steps"),
        cuts=stepping.get("cuts"),
        max_inverted=summary.get("max_inverted"),
        quantity=summary.get("tip_displacement"),
        reason=summary.get("reason"),
    )
    if row["completed"] and summary.get("samples") is not None:
        samples = np.asarray(summary["samples"], dtype=float)
    return row, samples


def _warm_up_case(case: Case) -> Case:
    values = dict(case.values)
    values["resolution"] = 1 if case.study != "cook-membrane" else 2
    if "dt" in values:
        values["t_end"] = values["dt"]
    else:
        values["steps"] = 1
    return dataclasses.replace(case, values=values, name=f"warm-up of {case.name}")


def _errors(rows: list[dict[str, Any]], samples: dict[str, np.ndarray | None]) -> None:
    for row in rows:
        own = samples.get(row["name"])
        for key, field in (("reference", "error"), ("time_reference", "time_error")):
            row.setdefault(field, None)
            row.setdefault(f"{field}_max", None)
            reference = samples.get(row.get(key)) if row.get(key) else None
            if own is None or reference is None:
                continue
            row[field], row[f"{field}_max"] = relative_errors(own, reference)


def run(
    output_directory,
    *,
    quick: bool = False,
    studies: Sequence[str] | None = None,
    progress: bool = False,
) -> dict:
    """Run the study; write ``runs.csv``, ``summary.md``, ``summary.json`` and the figures.

    Parameters
    ----------
    output_directory
        Directory of the output (created if missing).
    quick
        The small version (about two minutes on two cores; the tests run it).
    studies
        Names of :data:`STUDIES` to run; default all.
    progress
        Print one line per run.

    Returns
    -------
    dict
        JSON-ready: ``rows`` (every run with its errors), ``orders``, ``cheapest``,
        ``studies`` (per study: the reference's comparison with published values and its
        estimated error), ``figures``, ``files``, ``seconds``, ``load_average``.
    """
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    begin = time.perf_counter()
    load_before = os.getloadavg()[0]
    directory = pathlib.Path(output_directory)
    if comm.rank == 0:
        directory.mkdir(parents=True, exist_ok=True)
    cases = plan(quick=quick, studies=studies)
    rows: list[dict[str, Any]] = []
    samples: dict[str, np.ndarray | None] = {}
    warmed: set[tuple] = set()
    for index, case in enumerate(cases, start=1):
        if case.family() not in warmed:
            warmed.add(case.family())
            run_case(_warm_up_case(case), comm=comm)
        row, values = run_case(case, comm=comm)
        gc.collect()
        rows.append(row)
        samples[case.name] = values
        if progress and comm.rank == 0:
            state = "ok" if row.get("completed") else f"FAILED ({row.get('outcome')})"
            print(
                f"[{index}/{len(cases)}] {case.name}: {row['wall_time_s']:.2f} s, {state}",
                flush=True,
            )
    _errors(rows, samples)
    return write_results(
        directory,
        rows,
        quick=quick,
        ranks=comm.size,
        seconds=time.perf_counter() - begin,
        load_average=[load_before, os.getloadavg()[0]],
    )
