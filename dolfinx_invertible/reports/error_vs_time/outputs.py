"""The study's files: ``runs.csv``, ``summary.md``, ``summary.json`` and one figure per study."""

from __future__ import annotations

import json
import math
import os
import pathlib
from collections.abc import Sequence
from typing import Any

from dolfinx_invertible.reports.error_vs_time.analysis import (
    cheapest_runs,
    curve_orders,
    describe_run,
    reference_error_estimate,
    reference_row,
)
from dolfinx_invertible.reports.error_vs_time.study import COLLAPSE_TIME, STUDIES, TWIST_TIME
from dolfinx_invertible.reports.error_vs_time.work_precision import plot_study, write_csv

__all__ = ["format_value", "write_results"]

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


def format_value(value, digits: int = 3) -> str:
    """Return a number to ``digits`` significant digits; '–' for None or non-finite."""
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
        reference = reference_row(rows, study)
        if reference is not None:
            lines.append(
                f"Reference: {describe_run(reference)} "
                f"({format_value(reference.get('dofs'))} dofs, "
                f"{format_value(reference['wall_time_s'])} s"
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
                f"order: about {format_value(estimate, 2)}; "
                "smaller measured errors are not resolved."
            )
        lines += ["", "| curve | kind | order | finest pair | runs |", "|---|---|---|---|---|"]
        for entry in result["orders"]:
            if entry["study"] == study:
                lines.append(
                    f"| {entry['curve']} | {entry['kind']} ({entry['error']}) | "
                    f"{format_value(entry['order'], 3)} | "
                    f"{format_value(entry['finest_pair'], 3)} | "
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
                    f"{entry['configuration'] or 'not reached'} | "
                    f"{format_value(entry['measured'])} | "
                    f"{format_value(entry['wall_time_s'])} |"
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
                    f"| {tolerance} | {format_value(row.get('error'))} | "
                    f"{format_value(row.get('newton_iterations'))} | "
                    f"{format_value(row.get('krylov_iterations'))} | "
                    f"{format_value(row['wall_time_s'])} |"
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
    orders = curve_orders(rows)
    result: dict[str, Any] = {
        "quick": quick,
        "runs": len(rows),
        "ranks": ranks,
        "orders": orders,
        "cheapest": cheapest_runs(rows),
        "studies": {},
    }
    for study in sorted({row["study"] for row in rows}):
        entry: dict[str, Any] = {"reference_error_estimate": None}
        reference = reference_row(rows, study)
        if study == "cook-membrane" and reference is not None and reference.get("quantity"):
            from dolfinx_invertible.scenes.cook_membrane import REFERENCE_TIP_DISPLACEMENT

            entry["reference_tip_displacement"] = reference["quantity"]
            entry["published_tip_displacement"] = REFERENCE_TIP_DISPLACEMENT
            entry["reference_vs_published"] = reference["quantity"] / REFERENCE_TIP_DISPLACEMENT - 1
        if study != "collapse":
            entry["reference_error_estimate"] = reference_error_estimate(rows, orders, study)
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
