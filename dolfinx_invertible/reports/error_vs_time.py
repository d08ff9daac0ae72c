"""Work-precision study: error against wall time over discretisations, integrators and solvers.

Three studies, each a set of scene runs through
:func:`~dolfinx_invertible.scenes.runner.run_scene` (in-process, one after the other, no output
files) compared with reference runs of the same scene:

- ``cook-membrane`` (quasi-static, 2D, ν = 0.4999): the tip displacement, against the report's
  own finest run (P2 on the finest mesh), shown beside the published 6.9083. Varies the mesh,
  P1/P2, the tangent (auto, projected, exact), the linear solver (direct, or CG + GAMG with
  a relative tolerance ``ksp_rtol``) and the assembly (this package's kernels, or DOLFINx's own
  route: UFL Neo-Hookean compiled by FFCx).
- ``twisting-column`` (dynamic, 3D): the displacement at fixed reference points at
  t = :data:`TWIST_TIME`, against a fine-mesh P2 run at a small step (the total error), and for
  the time sweeps also against a run of the same mesh at a quarter of the finest step (the time
  error alone). Varies the mesh, P1/P2, the step, backward Euler/BDF2, the tangent, the linear
  solver and the assembly.
- ``collapse`` (dynamic, 3D, through inversion, the extension active): the scene's cube released
  from F = 0.05 I (its elements invert on the way back), the displacement at fixed reference
  points at t = :data:`COLLAPSE_TIME` on a fixed mesh against a run at a quarter of the finest
  step (the time error). Varies the step, the integrator, C1/C2 and the tangent; a mesh sweep
  shows how far the displacement depends on the mesh, and the full study adds a start from the
  reflection F = diag(−0.5, 1, 1) (every element inverted from the outset) for contrast.

Field errors are relative: ‖u − u_ref‖₂ / ‖u_ref‖₂ over all sample points and components (the
``error`` columns; ``error_max`` is the max-norm analogue). Wall times are those of whole runs
(mesh, forms, solves, the scene's own records), after a warm-up run of every combination of
scene, degree, assembly, extension, tangent and linear solver, so that no run pays for
just-in-time compilation. The output, in ``--out``: ``runs.csv`` (one row per run),
``summary.md`` (orders and cheapest configurations), ``summary.json`` and one PNG per study.
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import json
import math
import os
import pathlib
import sys
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from dolfinx_invertible.reports import add_output_arguments
from dolfinx_invertible.reports.work_precision import (
    cheapest,
    observed_order,
    plot_study,
    relative_errors,
    write_csv,
)

__all__ = [
    "COLLAPSE_TIME",
    "DEFAULT_OUTPUT",
    "STUDIES",
    "TARGETS",
    "TWIST_TIME",
    "Case",
    "add_arguments",
    "command",
    "plan",
    "run",
    "run_case",
    "write_results",
]

#: Where ``report error-vs-time`` writes by default.
DEFAULT_OUTPUT = pathlib.Path("results/reports/error-vs-time")
#: The studies, by name.
STUDIES = {
    "cook-membrane": "Cook's membrane (quasi-static, 2D, ν = 0.4999): tip displacement",
    "twisting-column": "twisting column (dynamic, 3D): displacement field at a fixed time",
    "collapse": "collapse through inversion (dynamic, 3D, from F = 0.05 I): displacement field "
    "at a fixed time",
}
#: Time at which the twisting column's displacement is compared [s].
TWIST_TIME = 0.05
#: Time at which the collapse's displacement is compared [s].
COLLAPSE_TIME = 0.02
#: Initial deformation gradient of the collapse study's contrast series: a reflection, every
#: element inverted.
REFLECTION = np.diag([-0.5, 1.0, 1.0])
#: Relative errors for which the summary names the cheapest run.
TARGETS = (1e-2, 1e-3, 1e-4)
#: Krylov iteration cap of the iterative runs (a failed linear solve is then cut and retried).
KRYLOV_MAX_IT = 1000

_FIELDS = (
    "study",
    "curve",
    "sweep",
    "role",
    "scene",
    "start",
    "model",
    "extension",
    "degree",
    "resolution",
    "h",
    "dt",
    "t_end",
    "steps",
    "scheme",
    "project",
    "elastic",
    "linear_solver",
    "ksp_rtol",
    "dofs",
    "ranks",
    "completed",
    "outcome",
    "quantity",
    "error",
    "error_max",
    "time_error",
    "time_error_max",
    "wall_time_s",
    "stepping_time_s",
    "newton_iterations",
    "krylov_iterations",
    "time_steps",
    "cuts",
    "max_inverted",
    "reference",
    "time_reference",
    "reason",
    "name",
)


@dataclasses.dataclass
class Case:
    """One run of a study.

    Attributes
    ----------
    study
        Key of :data:`STUDIES`.
    curve
        The method it belongs to (one curve of the plots); ``"reference"`` for references.
    sweep
        What varies along its curve: ``"resolution"``, ``"dt"``, ``"ksp_rtol"``, or
        ``"reference"``.
    values
        Parameters that differ from the scene's defaults.
    linear_solver
        ``"auto"`` (direct at these sizes) or ``"iterative"`` (CG + GAMG).
    ksp_rtol
        Relative tolerance of the iterative solver (PETSc ``ksp_rtol``).
    start
        ``"scene"`` (the scene's initial state) or ``"reflected"`` (collapse from
        :data:`REFLECTION`).
    reference, time_reference
        Names of the cases the error and the time error are measured against.
    name
        Unique name (set by :func:`plan`).
    """

    study: str
    curve: str
    sweep: str
    values: dict[str, Any]
    linear_solver: str = "auto"
    ksp_rtol: float | None = None
    start: str = "scene"
    reference: str | None = None
    time_reference: str | None = None
    name: str = ""

    def family(self) -> tuple:
        """Return what a warm-up run must share with this case to compile all it needs."""
        values = self.values
        return (
            self.study,
            self.start,
            values.get("degree"),
            values.get("elastic", "kernels"),
            values.get("extension"),
            values.get("project", "auto"),
            self.linear_solver,
        )


class _Plan:
    def __init__(self):
        self.cases: list[Case] = []

    def add(self, study: str, curve: str, sweep: str, values: dict, **options) -> Case:
        swept = options.get(sweep, values.get(sweep))
        if sweep == "reference":
            name = None
        elif swept is None:
            name = f"{study} | {curve} | direct solver"
        else:
            name = f"{study} | {curve} | {sweep} {swept:g}"
        case = Case(study, curve, sweep, dict(values), **options)
        case.name = name or f"{study} | {curve}"
        if any(other.name == case.name for other in self.cases):
            raise ValueError(f"two cases are called {case.name!r}")
        self.cases.append(case)
        return case


def _cook(plan: _Plan, quick: bool) -> None:
    study = "cook-membrane"
    reference = plan.add(
        study, "reference", "reference", {"degree": 2, "resolution": 32 if quick else 128}
    )
    resolutions = (4, 8, 16) if quick else (4, 8, 16, 32, 64)
    for curve, values in (
        ("P1, kernels", {"degree": 1}),
        ("P2, kernels", {"degree": 2}),
        ("P1, DOLFINx UFL", {"degree": 1, "elastic": "ufl"}),
        ("P2, DOLFINx UFL", {"degree": 2, "elastic": "ufl"}),
    ):
        for resolution in resolutions:
            plan.add(
                study,
                curve,
                "resolution",
                {**values, "resolution": resolution},
                reference=reference.name,
            )
    for curve, project in (
        ("P2, kernels, projected tangent", "yes"),
        ("P2, kernels, exact tangent", "no"),
    ):
        for resolution in resolutions[: 2 if quick else 4]:
            plan.add(
                study,
                curve,
                "resolution",
                {"degree": 2, "resolution": resolution, "project": project},
                reference=reference.name,
            )
    # Tighter tolerances than these exceed the Krylov cap (P2, ν = 0.4999).
    resolution = 8 if quick else 16
    plan.add(
        study,
        f"P2 resolution {resolution}, direct",
        "ksp_rtol",
        {"degree": 2, "resolution": resolution},
        reference=reference.name,
    )
    for tolerance in (1e-1, 1e-3) if quick else (1e-1, 1e-2, 1e-3, 1e-4):
        plan.add(
            study,
            f"P2 resolution {resolution}, CG + GAMG",
            "ksp_rtol",
            {"degree": 2, "resolution": resolution},
            linear_solver="iterative",
            ksp_rtol=tolerance,
            reference=reference.name,
        )


def _twisting_column(plan: _Plan, quick: bool) -> None:
    study = "twisting-column"
    common = {"t_end": TWIST_TIME}
    if quick:
        reference_values = {"degree": 2, "resolution": 2, "dt": 0.000625}
        space_dt, space = 0.00125, {1: (1, 2, 3)}
        # Not resolution 1: its locked P1 modes are too stiff for these steps to resolve.
        time_meshes, steps = ((1, 2),), (0.0025, 0.00125, 0.000625)
        krylov_resolution, tolerances = 2, (1e-4, 1e-8)
    else:
        reference_values = {"degree": 2, "resolution": 4, "dt": 0.000625}
        space_dt, space = 0.000625, {1: (1, 2, 3, 4, 6), 2: (1, 2, 3)}
        time_meshes, steps = ((1, 2), (2, 2)), (0.005, 0.0025, 0.00125, 0.000625)
        # At ksp_rtol 1e-2 Newton stalls here (minutes); it is part of the finding.
        krylov_resolution, tolerances = 4, (1e-2, 1e-3, 1e-4, 1e-8)
    reference = plan.add(
        study, "reference", "reference", {**common, **reference_values, "scheme": "bdf2"}
    )
    for degree, resolutions in space.items():
        for assembly, elastic in (("kernels", "kernels"), ("DOLFINx UFL", "ufl")):
            for resolution in resolutions:
                plan.add(
                    study,
                    f"P{degree}, BDF2, {assembly}",
                    "resolution",
                    {
                        **common,
                        "degree": degree,
                        "resolution": resolution,
                        "dt": space_dt,
                        "scheme": "bdf2",
                        "elastic": elastic,
                    },
                    reference=reference.name,
                )
    for curve, project in (
        ("P1, BDF2, projected tangent", "yes"),
        ("P1, BDF2, exact tangent", "no"),
    ):
        for resolution in space[1][:-1]:
            plan.add(
                study,
                curve,
                "resolution",
                {
                    **common,
                    "degree": 1,
                    "resolution": resolution,
                    "dt": space_dt,
                    "scheme": "bdf2",
                    "project": project,
                },
                reference=reference.name,
            )
    for degree, resolution in time_meshes:
        mesh = {"degree": degree, "resolution": resolution}
        time_reference = plan.add(
            study,
            f"time reference P{degree} resolution {resolution}",
            "reference",
            {**common, **mesh, "dt": steps[-1] / 4, "scheme": "bdf2"},
        )
        for scheme, label in (("backward-euler", "backward Euler"), ("bdf2", "BDF2")):
            for dt in steps:
                plan.add(
                    study,
                    f"P{degree} resolution {resolution}, {label}",
                    "dt",
                    {**common, **mesh, "dt": dt, "scheme": scheme},
                    reference=reference.name,
                    time_reference=time_reference.name,
                )
    plan.add(
        study,
        f"P1 resolution {krylov_resolution}, BDF2, direct",
        "ksp_rtol",
        {**common, "degree": 1, "resolution": krylov_resolution, "dt": 0.00125, "scheme": "bdf2"},
        reference=reference.name,
    )
    for tolerance in tolerances:
        plan.add(
            study,
            f"P1 resolution {krylov_resolution}, BDF2, CG + GAMG",
            "ksp_rtol",
            {
                **common,
                "degree": 1,
                "resolution": krylov_resolution,
                "dt": 0.00125,
                "scheme": "bdf2",
            },
            linear_solver="iterative",
            ksp_rtol=tolerance,
            reference=reference.name,
        )


def _collapse(plan: _Plan, quick: bool) -> None:
    study = "collapse"
    T = COLLAPSE_TIME
    common = {"t_end": T, "resolution": 2, "scheme": "bdf2"}
    # From F = 0.05 I the steps must be small (dt ≲ T/256) before the errors settle to an
    # order: the collapsed elements are stiff as they spring back.
    counts = (64, 128, 256) if quick else (128, 256, 512, 1024, 2048, 4096)
    space_dt = T / (256 if quick else 512)
    reference = plan.add(
        study,
        "reference",
        "reference",
        {**common, "resolution": 4 if quick else 6, "dt": space_dt, "extension": "c2"},
    )
    references = {}
    for extension in ("c2", "c1"):
        time_reference = plan.add(
            study,
            f"time reference {extension.upper()}",
            "reference",
            {**common, "dt": T / (1024 if quick else 16384), "extension": extension},
        )
        references[extension] = time_reference.name
        for scheme, label in (("backward-euler", "backward Euler"), ("bdf2", "BDF2")):
            for count in counts:
                plan.add(
                    study,
                    f"{extension.upper()}, {label}",
                    "dt",
                    {**common, "dt": T / count, "scheme": scheme, "extension": extension},
                    # C1 is another material below its threshold: only its time error.
                    reference=reference.name if extension == "c2" else None,
                    time_reference=time_reference.name,
                )
    for curve, project in (
        ("C2, BDF2, projected tangent", "yes"),
        ("C2, BDF2, exact tangent", "no"),
    ):
        for count in counts[1:] if quick else counts[1:-1]:
            plan.add(
                study,
                curve,
                "dt",
                {**common, "dt": T / count, "extension": "c2", "project": project},
                reference=reference.name,
                time_reference=references["c2"],
            )
    for resolution in (2, 3) if quick else (2, 3, 4):
        plan.add(
            study,
            "C2, BDF2, mesh sweep",
            "resolution",
            {**common, "resolution": resolution, "dt": space_dt, "extension": "c2"},
            reference=reference.name,
        )
    if not quick:
        # A start that is inverted from the outset (a reflection) settles at far larger steps.
        reflected = plan.add(
            study,
            "time reference C2, reflected start",
            "reference",
            {**common, "dt": T / 2048, "extension": "c2"},
            start="reflected",
        )
        for scheme, label in (("backward-euler", "backward Euler"), ("bdf2", "BDF2")):
            for count in (16, 32, 64, 128, 256, 512):
                plan.add(
                    study,
                    f"C2, {label}, reflected start",
                    "dt",
                    {**common, "dt": T / count, "scheme": scheme, "extension": "c2"},
                    time_reference=reflected.name,
                    start="reflected",
                )


def plan(*, quick: bool = False, studies: Sequence[str] | None = None) -> list[Case]:
    """Return the runs of the study, references first within each study.

    Parameters
    ----------
    quick
        The small version (about two minutes on two cores): coarser references, fewer runs.
    studies
        Names of :data:`STUDIES` to include; default all.
    """
    chosen = list(STUDIES) if studies is None else list(studies)
    unknown = [name for name in chosen if name not in STUDIES]
    if unknown:
        raise ValueError(f"unknown studies {unknown}; the studies are {', '.join(STUDIES)}")
    builders = {"cook-membrane": _cook, "twisting-column": _twisting_column, "collapse": _collapse}
    result = _Plan()
    for name in chosen:
        builders[name](result, quick)
    return result.cases


# --- running ------------------------------------------------------------------------------------


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
    """Return the scene class of ``case``: its start, linear solver and sampling."""
    from time import perf_counter

    from dolfinx_invertible.fem import PointValues
    from dolfinx_invertible.scenes import get_scene

    base = get_scene(_SCENES[case.study])
    points = _sample_points(case.study)
    linear_solver = case.linear_solver
    gradient = REFLECTION if case.start == "reflected" else None

    class Probed(base):
        def initial_displacement(self):
            if gradient is None:
                return super().initial_displacement()
            centre = 0.5 * self.parameters.size

            def displacement(x):
                return (gradient - np.eye(3)) @ (x - centre)

            return displacement

        def problem_options(self):
            options = dict(super().problem_options())
            options["linear_solver"] = linear_solver
            return options

        def record(self, run):
            super().record(run)
            if getattr(self, "_stepping_started", None) is None:
                # The first record comes after the setup, before the first step.
                self._stepping_started = perf_counter()

        def quantities(self, run):
            values = dict(super().quantities(run))
            values["stepping_time_s"] = perf_counter() - self._stepping_started
            if points is not None:
                values["samples"] = PointValues(run.u, points)().tolist()
            elif "tip_displacement" in values:
                values["samples"] = [[values["tip_displacement"]]]
            return values

    Probed.__name__ = Probed.__qualname__ = f"Probed{base.__name__}"
    return Probed


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
    try:
        summary = run_scene(scene_class, parameters, output=None, petsc_options=petsc, comm=comm)
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


# --- analysis -------------------------------------------------------------------------------------


def _orders(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Observed orders per curve: in h = 1/resolution (error) or in dt (time error)."""
    result = []
    curves: dict[tuple[str, str, str], list] = {}
    for row in rows:
        if row["sweep"] in ("resolution", "dt"):
            curves.setdefault((row["study"], row["curve"], row["sweep"]), []).append(row)
    for (study, curve, sweep), members in curves.items():
        error = "error" if sweep == "resolution" else "time_error"
        size = "h" if sweep == "resolution" else "dt"
        fit = observed_order([row[size] for row in members], [row.get(error) for row in members])
        result.append(
            {
                "study": study,
                "curve": curve,
                "kind": "space" if sweep == "resolution" else "time",
                "error": error,
                **fit,
            }
        )
    return result


def _reference_row(rows, study: str) -> dict[str, Any] | None:
    return next(
        (row for row in rows if row["study"] == study and row["curve"] == "reference"), None
    )


def _describe(row: dict[str, Any]) -> str:
    parts = [f"P{row['degree']}", f"resolution {row['resolution']}"]
    if row.get("dt") is not None:
        parts += [f"dt {row['dt']:.4g}", row["scheme"]]
    if row["study"] == "collapse":
        parts.append(row["extension"].upper())
    if row.get("start") == "reflected":
        parts.append("reflected start")
    if row["project"] != "auto":
        parts.append({"yes": "projected", "no": "exact"}[row["project"]] + " tangent")
    parts.append("DOLFINx UFL" if row["elastic"] == "ufl" else "kernels")
    if row["linear_solver"] == "iterative":
        parts.append(f"CG + GAMG, ksp_rtol {row['ksp_rtol']:g}")
    return ", ".join(parts)


def _cheapest(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Return the cheapest run per study, error kind and target (runs of the scene's start)."""
    result = []
    for study in STUDIES:
        members = [
            row
            for row in rows
            if row["study"] == study and row["role"] == "run" and row.get("start") == "scene"
        ]
        if not members:
            continue
        for error in ("error", "time_error"):
            if not any(row.get(error) is not None for row in members):
                continue
            for target in TARGETS:
                best = cheapest(members, target, error=error)
                result.append(
                    {
                        "study": study,
                        "error": error,
                        "target": target,
                        "run": None if best is None else best["name"],
                        "configuration": None if best is None else _describe(best),
                        "measured": None if best is None else best[error],
                        "wall_time_s": None if best is None else best["wall_time_s"],
                    }
                )
    return result


def _reference_error_estimate(rows, orders, study: str) -> float | None:
    """Estimate the reference's own error from the finest P2 space run and its order.

    With e(h) ≈ C hᵖ and the measured e₁ = |u(h₁) − u_ref| ≈ C(h₁ᵖ − h_refᵖ) (same sign),
    C h_refᵖ = e₁ r / (1 − r) with r = (h_ref/h₁)ᵖ.
    """
    reference = _reference_row(rows, study)
    if reference is None or not reference.get("completed"):
        return None
    curve = next(
        (
            entry
            for entry in orders
            if entry["study"] == study
            and entry["kind"] == "space"
            and entry["curve"].startswith(f"P{reference['degree']}, ")
            and "kernels" in entry["curve"]
            and math.isfinite(entry["order"])
        ),
        None,
    )
    if curve is None:
        return None
    finest = min(
        (
            row
            for row in rows
            if row["curve"] == curve["curve"]
            and row["study"] == study
            and row.get("error") is not None
            and row["completed"]
        ),
        key=lambda row: row["h"],
        default=None,
    )
    if finest is None or not curve["order"] > 0.0:
        return None
    ratio = (reference["h"] / finest["h"]) ** curve["order"]
    return float(finest["error"] * ratio / (1.0 - ratio))


# --- output -----------------------------------------------------------------------------------


def _format(value, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def _markdown(result: dict[str, Any], rows: list[dict[str, Any]]) -> str:
    lines = [
        "# Error against wall time",
        "",
        f"{'Quick' if result['quick'] else 'Full'} study, {result['runs']} runs on "
        f"{result['ranks']} rank(s) in {result['seconds']:.0f} s (warm-up runs included), "
        f"load average {result['load_average'][0]:.2f} before and "
        f"{result['load_average'][1]:.2f} after (of {os.cpu_count()} cores). Every run: "
        "`runs.csv`. Errors are relative: ‖u − u_ref‖₂/‖u_ref‖₂ over the sample points "
        "(the tip displacement for Cook's membrane); `error` is against the study's reference, "
        "`time_error` against a run on the same mesh at a quarter of the finest step of its "
        "sweep (the time error alone). Orders are least-squares slopes of log error against log h "
        "(h = 1/resolution) or log dt; 'finest pair' is the slope between the two finest runs.",
        "",
    ]
    for study, description in STUDIES.items():
        members = [row for row in rows if row["study"] == study]
        if not members:
            continue
        lines += [f"## {description}", ""]
        reference = _reference_row(rows, study)
        if reference is not None:
            lines.append(
                f"Reference: {_describe(reference)} ({_format(reference.get('dofs'))} dofs, "
                f"{_format(reference['wall_time_s'])} s"
                + ("" if reference.get("completed") else f"; FAILED: {reference.get('reason')}")
                + ")."
            )
        extra = result["studies"].get(study, {})
        if study == "cook-membrane" and reference is not None and reference.get("quantity"):
            lines.append(
                f"Its tip displacement {reference['quantity']:.5f} against the published "
                f"6.9083: {extra.get('reference_vs_published', math.nan):+.2%}."
            )
        if study == "twisting-column":
            lines.append(f"Compared at t = {TWIST_TIME} s at 13 × 3 × 3 points of the column.")
        if study == "collapse":
            lines.append(
                f"Compared at t = {COLLAPSE_TIME} s at 5 × 5 × 5 points of the cube, released from "
                "F = 0.05 I (the 'reflected start' series: from F = diag(−0.5, 1, 1)). C1 is "
                "another material than C2 below its threshold: its runs have a time error only, "
                "against C1's own fine-step run. The cheapest runs are among those from "
                "F = 0.05 I."
            )
        estimate = extra.get("reference_error_estimate")
        if estimate is not None:
            lines.append(
                f"The reference's own error, extrapolated from the finest space run with its "
                f"order: about {_format(estimate, 2)}; smaller measured errors are not resolved."
            )
        lines += ["", "| curve | kind | order | finest pair | runs |", "|---|---|---|---|---|"]
        for entry in result["orders"]:
            if entry["study"] == study:
                lines.append(
                    f"| {entry['curve']} | {entry['kind']} ({entry['error']}) | "
                    f"{_format(entry['order'], 3)} | {_format(entry['finest_pair'], 3)} | "
                    f"{entry['points']} |"
                )
        lines += [
            "",
            "| error | target | cheapest run | measured | wall time [s] |",
            "|---|---|---|---|---|",
        ]
        for entry in result["cheapest"]:
            if entry["study"] == study:
                lines.append(
                    f"| {entry['error']} | {entry['target']:g} | "
                    f"{entry['configuration'] or 'not reached'} | {_format(entry['measured'])} | "
                    f"{_format(entry['wall_time_s'])} |"
                )
        failed = [row for row in members if not row.get("completed")]
        if failed:
            lines += ["", "Runs that did not complete:", ""]
            lines += [
                f"- {row['name']}: {row.get('reason') or row.get('outcome')}" for row in failed
            ]
        krylov = [row for row in members if row["sweep"] == "ksp_rtol"]
        if krylov:
            lines += [
                "",
                "| ksp_rtol | error | Newton | Krylov | wall time [s] |",
                "|---|---|---|---|---|",
            ]
            for row in sorted(
                krylov, key=lambda row: (row["ksp_rtol"] is None, -(row["ksp_rtol"] or 0))
            ):
                tolerance = "direct" if row["ksp_rtol"] is None else f"{row['ksp_rtol']:g}"
                lines.append(
                    f"| {tolerance} | {_format(row.get('error'))} | "
                    f"{_format(row.get('newton_iterations'))} | "
                    f"{_format(row.get('krylov_iterations'))} | {_format(row['wall_time_s'])} |"
                )
        if result["figures"].get(study):
            lines += ["", f"![{study}]({result['figures'][study]})"]
        lines.append("")
    return "\n".join(lines)


def _figures(directory: pathlib.Path, rows, result, dpi: int) -> dict[str, str]:
    figures = {}
    for study in STUDIES:
        members = [row for row in rows if row["study"] == study and row["role"] == "run"]
        if not members:
            continue
        space_curves = sorted({row["curve"] for row in members if row["sweep"] == "resolution"})
        time_curves = sorted({row["curve"] for row in members if row["sweep"] == "dt"})
        wall = {"x": "wall_time_s", "xlabel": "wall time [s]"}
        mesh_convergence = {
            "x": "h",
            "error": "error",
            "xlabel": "h = 1/resolution",
            "ylabel": "relative error",
            "title": "mesh convergence",
            "curves": space_curves,
            "slopes": True,
        }
        if study == "cook-membrane":
            published = result["studies"][study].get("reference_vs_published")
            panels = [
                {
                    **wall,
                    "error": "error",
                    "ylabel": "relative error of the tip displacement",
                    "title": "against the finest run",
                    "lines": [
                        (
                            abs(published) if published is not None else None,
                            "finest run vs published 6.9083",
                        )
                    ],
                },
                mesh_convergence,
            ]
        else:
            panels = [
                {
                    **wall,
                    "error": "error",
                    "ylabel": "relative error (vs reference)",
                    "title": "total error: against the fine reference",
                },
                {
                    **wall,
                    "error": "time_error",
                    "ylabel": "relative time error",
                    "title": "time error: against a fine-dt run on the same mesh",
                    "curves": time_curves,
                },
                mesh_convergence,
                {
                    "x": "dt",
                    "error": "time_error",
                    "xlabel": "dt [s]",
                    "ylabel": "relative time error",
                    "title": "time convergence",
                    "curves": time_curves,
                    "slopes": True,
                },
            ]
        name = f"error_vs_time_{study.replace('-', '_')}.png"
        plot_study(directory / name, members, title=STUDIES[study], panels=panels, dpi=dpi)
        figures[study] = name
    return figures


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


def write_results(
    output_directory,
    rows: list[dict[str, Any]],
    *,
    quick: bool,
    ranks: int,
    seconds: float,
    load_average: Sequence[float],
) -> dict:
    """Analyse the rows of a study (errors filled in) and write its files; return the summary.

    :func:`run` ends here; ``report error-vs-time --redraw`` calls it on the rows of an earlier
    ``summary.json``, to redo the tables and figures without running anything again.
    """
    from mpi4py import MPI

    from dolfinx_invertible.io.step_log import json_ready

    comm = MPI.COMM_WORLD
    directory = pathlib.Path(output_directory)
    orders = _orders(rows)
    result: dict[str, Any] = {
        "quick": quick,
        "runs": len(rows),
        "ranks": ranks,
        "orders": orders,
        "cheapest": _cheapest(rows),
        "studies": {},
    }
    for study in sorted({row["study"] for row in rows}):
        entry: dict[str, Any] = {"reference_error_estimate": None}
        reference = _reference_row(rows, study)
        if study == "cook-membrane" and reference is not None and reference.get("quantity"):
            from dolfinx_invertible.scenes.cook_membrane import REFERENCE_TIP_DISPLACEMENT

            entry["reference_tip_displacement"] = reference["quantity"]
            entry["published_tip_displacement"] = REFERENCE_TIP_DISPLACEMENT
            entry["reference_vs_published"] = reference["quantity"] / REFERENCE_TIP_DISPLACEMENT - 1
        if study != "collapse":
            entry["reference_error_estimate"] = _reference_error_estimate(rows, orders, study)
        result["studies"][study] = entry
    files = {"csv": "runs.csv", "markdown": "summary.md", "json": "summary.json"}
    result["figures"] = {}
    if comm.rank == 0:
        directory.mkdir(parents=True, exist_ok=True)
        write_csv(directory / files["csv"], rows, _FIELDS)
        result["figures"] = _figures(directory, rows, result, dpi=70 if quick else 100)
    result["figures"] = comm.bcast(result["figures"], root=0)
    result["files"] = files
    result["seconds"] = seconds
    result["load_average"] = list(load_average)
    result["rows"] = rows
    if comm.rank == 0:
        (directory / files["markdown"]).write_text(_markdown(result, rows))
        (directory / files["json"]).write_text(
            json.dumps(json_ready(result), indent=1, allow_nan=False) + "\n"
        )
    return json_ready(result)


# --- command line -------------------------------------------------------------------------------


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``report error-vs-time``."""
    add_output_arguments(
        parser, DEFAULT_OUTPUT, "the small study (about 2 minutes on 2 cores; the tests run it)"
    )
    parser.add_argument(
        "--study",
        action="append",
        choices=list(STUDIES),
        dest="studies",
        help="run only this study (repeatable; default: all)",
    )
    parser.add_argument(
        "--redraw",
        action="store_true",
        help="redo the tables and figures from DIR/summary.json of an earlier run, running nothing",
    )
    parser.add_argument("--verbose", action="store_true", help="show compiler and solver chatter")


def command(arguments: argparse.Namespace) -> int:
    """Run ``report error-vs-time``; print the orders and the cheapest runs."""
    from mpi4py import MPI

    if arguments.redraw:
        path = arguments.out / "summary.json"
        if not path.is_file():
            print(f"error: --redraw needs {path} from an earlier run", file=sys.stderr)
            return 2
        earlier = json.loads(path.read_text())
        result = write_results(
            arguments.out,
            earlier["rows"],
            quick=earlier["quick"],
            ranks=earlier["ranks"],
            seconds=earlier["seconds"],
            load_average=earlier["load_average"],
        )
    else:
        result = run(arguments.out, quick=arguments.quick, studies=arguments.studies, progress=True)
    if MPI.COMM_WORLD.rank == 0:
        for entry in result["orders"]:
            print(
                f"{entry['study']}: {entry['curve']}: {entry['kind']} order "
                f"{_format(entry['order'])} ({entry['points']} runs)"
            )
        for entry in result["cheapest"]:
            print(
                f"{entry['study']}: {entry['error']} <= {entry['target']:g}: "
                f"{entry['configuration'] or 'not reached'}"
            )
        print(
            f"wrote {arguments.out}/ (runs.csv, summary.md, summary.json, figures) in "
            f"{result['seconds']:.0f} s"
        )
    return 0
