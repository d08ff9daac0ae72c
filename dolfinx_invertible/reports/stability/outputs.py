"""The study's files: the CSV, one heat map per scene and the Markdown summary."""

from __future__ import annotations

import csv
import math
import pathlib
from collections import Counter
from collections.abc import Iterable, Sequence
from typing import Any

from dolfinx_invertible.reports.stability.diagnosis import CAUSES
from dolfinx_invertible.reports.stability.study import (
    CONTINUATION_STEP,
    CONTINUATION_TIME,
    DENSITY,
    METHODS,
    MINIMUM_STEPS,
    POISSON_RATIOS,
    REST,
    SCENES,
    SIZE,
    TIME_STEPS,
    YOUNGS_MODULI,
    Cell,
    method_label,
)

__all__ = ["COLUMNS", "display_outcome", "plot_heat_map", "summary_lines", "write_csv"]

#: CSV columns, in order (see docs/stability.md for their meaning).
COLUMNS = (
    "scene",
    "method",
    "nu",
    "E",
    "dt",
    "dt_star",
    "t_end_star",
    "resolution",
    "damping",
    "outcome",
    "cause",
    "failed_stage",
    "snes_reason",
    "ksp_reason",
    "failed_time_star",
    "failed_step_star",
    "steps",
    "cuts",
    "step_min_star",
    "newton_total",
    "newton_max",
    "linear_total",
    "projected_total",
    "min_J_reached",
    "final_min_J",
    "final_inverted",
    "max_inverted",
    "rest_distance",
    "kinetic_final",
    "kinetic_max",
    "last_inverted_star",
    "continued_inverted",
    "continued_rest_distance",
    "attempt_iterations",
    "residual_drop",
    "residual_drop_last10",
    "inverted_points",
    "kink_gap",
    "cap_last",
    "cap_median",
    "tangent_min",
    "tangent_max",
    "tangent_negative",
    "tangent_condition",
    "retry",
    "long_retry",
    "long_retry_iterations",
    "nan",
    "wall_time_s",
    "cause_detail",
    "reason",
)

#: Outcome shown in the heat maps -> (label, colour, legend text).
_DISPLAY = {
    "recovered": ("R", "#1a9850", "recovered"),
    "completed": ("C", "#1a9850", "completed (stretch bar)"),
    "completed_inverted": ("C·inv", "#a6d96a", "completed, cells inverted at the end"),
    "not_at_rest": ("N", "#fee08b", "not at rest (uninverted)"),
    "stalled_inverted": ("S", "#fc8d59", "stalled inverted"),
    "failed": (
        "F",
        "#d73027",
        "failed at: ls line search, lin linear solve, stall no progress, cap iteration cap",
    ),
    "nan": ("NaN", "#542788", "NaN"),
    "does_not_apply": ("n/a", "#d9d9d9", "does not apply (starts inverted)"),
    "timeout": ("T", "#525252", "timeout"),
    "crashed": ("X", "#000000", "worker crashed"),
}
_STAGES = {
    "line search": "ls",
    "linear solve": "lin",
    "iteration cap": "cap",
    "stalled": "stall",
    "step check": "chk",
    "NaN": "nan",
}


def display_outcome(record: dict[str, Any]) -> str:
    """Return the heat-map category of a record (completed runs split by inverted cells)."""
    outcome = record.get("outcome", "crashed")
    if outcome == "completed" and (record.get("final_inverted") or 0) > 0:
        return "completed_inverted"
    return outcome


def write_csv(records: Sequence[dict[str, Any]], path: pathlib.Path) -> None:
    """Write one row per record with :data:`COLUMNS`."""
    with path.open("w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=COLUMNS, extrasaction="ignore")
        writer.writeheader()
        for record in records:
            writer.writerow({name: _csv_value(record.get(name)) for name in COLUMNS})


def _csv_value(value):
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.6g}"
    return value


def _points(records: Iterable[dict[str, Any]]) -> list[tuple[float, float, float]]:
    return sorted({(record["nu"], record["E"], record["dt"]) for record in records})


def _exponent(value: float) -> str:
    exponent = math.log10(value)
    if abs(exponent - round(exponent)) < 1e-9:
        return f"1e{int(round(exponent))}"
    return f"{value:g}"


def plot_heat_map(records: Sequence[dict[str, Any]], scene: str, path: pathlib.Path) -> None:
    """Draw the outcomes of one scene: methods × (ν, E, dt), one coloured cell each."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import to_rgb
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    rows = [record for record in records if record["scene"] == scene]
    methods = [method for method in METHODS if any(r["method"] == method.name for r in rows)]
    points = _points(rows)
    by_key = {(r["method"], r["nu"], r["E"], r["dt"]): r for r in rows}
    width = max(6.0, 0.62 * len(points) + 3.2)
    figure = Figure(figsize=(width, 0.5 * len(methods) + 2.6))
    FigureCanvasAgg(figure)
    axes = figure.add_axes([2.9 / width, 0.3, 1.0 - 3.1 / width, 0.5])
    for row, method in enumerate(methods):
        for column, (nu, E, dt) in enumerate(points):
            record = by_key.get((method.name, nu, E, dt))
            if record is None:
                continue
            category = display_outcome(record)
            label, colour, _ = _DISPLAY.get(category, ("?", "#ffffff", category))
            if category == "failed":
                label += "\n" + _STAGES.get(record.get("failed_stage") or "", "?")
            axes.add_patch(
                _rectangle(column, row, colour),
            )
            red, green, blue = to_rgb(colour)
            dark = 0.299 * red + 0.587 * green + 0.114 * blue < 0.5
            axes.text(
                column + 0.5,
                row + 0.5,
                label,
                ha="center",
                va="center",
                fontsize=7,
                color="white" if dark else "black",
            )
    axes.set_xlim(0, len(points))
    axes.set_ylim(len(methods), 0)
    axes.set_yticks([row + 0.5 for row in range(len(methods))])
    axes.set_yticklabels([method.label for method in methods], fontsize=8)
    axes.set_xticks([column + 0.5 for column in range(len(points))])
    axes.set_xticklabels(
        [
            f"{_exponent(E)}\n{_exponent(dt)}\n{dt / (SIZE / math.sqrt(E / DENSITY)):g}"
            for _, E, dt in points
        ],
        fontsize=7,
    )
    axes.tick_params(length=0)
    axes.text(
        -0.01, -0.085, "E [Pa]\ndt [s]\ndt·c/L", transform=axes.transAxes, ha="right",
        va="top", fontsize=7,
    )  # fmt: skip
    for column, (nu, _, _) in enumerate(points):
        if column == 0 or points[column - 1][0] != nu:
            if column:
                axes.axvline(column, color="black", linewidth=1.5)
            span = sum(1 for point in points if point[0] == nu)
            ratio = 2.0 * nu / (1.0 - 2.0 * nu)
            axes.text(
                column + span / 2,
                -0.25,
                f"ν = {nu:g} (λ/μ = {ratio:.3g})",
                ha="center",
                va="bottom",
                fontsize=8,
            )
    for spine in axes.spines.values():
        spine.set_visible(False)
    present = []
    for record in rows:
        category = display_outcome(record)
        if category not in present:
            present.append(category)
    handles = [
        Patch(facecolor=_DISPLAY[category][1], edgecolor="black", label=_DISPLAY[category][2])
        for category in _DISPLAY
        if category in present
    ]
    figure.legend(
        handles=handles, loc="lower center", ncol=min(4, max(1, len(handles))), fontsize=7,
        frameon=False,
    )  # fmt: skip
    figure.suptitle(
        f"{scene}: outcome per method, ν, E and dt\n(ρ = {DENSITY:g} kg/m³, L = {SIZE:g} m, "
        "c = √(E/ρ))",
        fontsize=9,
    )
    figure.savefig(path, dpi=110)


def _rectangle(column: int, row: int, colour: str):
    from matplotlib.patches import Rectangle

    return Rectangle((column, row), 1.0, 1.0, facecolor=colour, edgecolor="white", linewidth=1.0)


def _table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return lines


def _came_through(record: dict[str, Any]) -> bool:
    return record.get("outcome") in ("recovered", "completed")


def summary_lines(
    records: Sequence[dict[str, Any]],
    *,
    quick: bool,
    wall_time: float,
    load: tuple[float, float] | None,
    command_line: str,
) -> list[str]:
    """Return the Markdown summary of the study (see docs/stability.md)."""
    lines = [
        "# Stability study" + (" (quick subset)" if quick else ""),
        "",
        f"{len(records)} cells; wall time {wall_time / 60:.1f} min with {_workers_used(records)} "
        "worker processes"
        + (f", load average {load[0]:.2f} before and {load[1]:.2f} after" if load else "")
        + ".",
        "",
        f"Regenerate: `{command_line}`",
        "",
        "## Method",
        "",
        f"Scenes {', '.join(SCENES)}; body size L = {SIZE:g} m, ρ = {DENSITY:g} kg/m³, "
        "c = √(E/ρ); every run ends at max(end time, "
        f"{MINIMUM_STEPS} dt). End times in L/c and damping (fraction of critical damping of "
        "the lowest mode π c/L):",
        "",
    ]
    setup_rows = []
    resolutions = {record["scene"]: record.get("resolution") for record in records}
    for scene in SCENES:
        cell = Cell(scene, METHODS[0].name, POISSON_RATIOS[0], YOUNGS_MODULI[1], TIME_STEPS[0])
        parameters = cell.parameters()
        setup_rows.append(
            (
                scene,
                resolutions.get(scene) or parameters["resolution"],
                f"{parameters['t_end'] / cell.time_unit:g}",
                f"{parameters['damping']:g}",
            )
        )
    lines += _table(("scene", "resolution", "end time [L/c]", "damping ζ"), setup_rows)
    lines += [
        "",
        "Outcomes: *recovered* (every step converged, no inverted cell, rest distance < "
        f"{REST:g} of the diameter at the end), *stalled inverted* (converged, cells still "
        "inverted), *not at rest* (converged, uninverted, rest distance above the tolerance), "
        "*completed* (stretch bar), *failed* (a step failed after all cuts; the stage and "
        "PETSc reasons are given), *NaN*, *does not apply* (plain Neo-Hookean from an "
        "inverted start). A cell that did not come through is diagnosed from data: a "
        "relaxation is continued with damped steps of "
        f"{CONTINUATION_STEP:g} L/c for {CONTINUATION_TIME:g} L/c (each a near-static "
        "minimisation from the state before): if it then recovers, the end time was too short; "
        "if it stays inverted, it sits in an inverted local minimum. A failed step's last "
        "Newton iterate is examined (inverted points' singular values against the kink "
        "σ₂ + σ₃ = 0, inversion-free caps, the tangent's spectrum) and the step is retried once "
        "with the cut step (`retry`); a retry that stops at the iteration cap or stalls is run "
        "once more with a larger cap and no progress test (`long_retry`, "
        "`long_retry_iterations`), and if that converges the "
        "cause is the iteration cap.",
        "",
        "## Headline",
        "",
    ]
    counts = Counter(display_outcome(record) for record in records)
    lines += _table(
        ("outcome", "cells"),
        [(_DISPLAY[name][2], counts[name]) for name in _DISPLAY if counts[name]],
    )
    lines += ["", "Per method (all scenes):", ""]
    categories = [name for name in _DISPLAY if counts[name]]
    method_rows = []
    for method in METHODS:
        mine = [record for record in records if record["method"] == method.name]
        if not mine:
            continue
        tally = Counter(display_outcome(record) for record in mine)
        method_rows.append((method.label, *(tally[name] or "" for name in categories)))
    lines += _table(("method", *(_DISPLAY[name][0] for name in categories)), method_rows)
    legend = ", ".join(f"{_DISPLAY[name][0]} {_DISPLAY[name][2]}" for name in categories)
    lines += ["", f"Legend: {legend}."]
    lines += ["", "## The study's goals", ""]
    nan_cells = [r for r in records if r.get("outcome") == "nan" or r.get("nan")]
    lines.append(f"- NaN anywhere: {len(nan_cells)} cells.")
    c2_small = [r for r in records if r["method"] == "nh-c2" and r["dt"] == TIME_STEPS[0]]
    c2_missed = [record for record in c2_small if not _came_through(record)]
    lines.append(
        f"- Neo-Hookean + C2 with dt = {TIME_STEPS[0]:g} s: {len(c2_small) - len(c2_missed)} of "
        f"{len(c2_small)} cells recovered or completed"
        + (
            "; the others: "
            + "; ".join(
                f"{r['scene']} ν = {r['nu']:g}, E = {r['E']:g}: {r['outcome']} ({r.get('cause')})"
                for r in c2_missed
            )
            if c2_missed
            else ""
        )
        + "."
    )
    lines += ["", "### C2 against IFE on the paper's relaxations (collapse, scatter)", ""]
    paper_rows = []
    for scene in ("collapse", "scatter"):
        for nu in sorted({record["nu"] for record in records}):
            row = [scene, f"{nu:g} ({2 * nu / (1 - 2 * nu):.3g})"]
            for method in ("nh-c2", "nh-ife"):
                mine = [
                    r for r in records if r["scene"] == scene and r["method"] == method
                    and r["nu"] == nu
                ]  # fmt: skip
                good = sum(1 for r in mine if _came_through(r))
                row.append(f"{good}/{len(mine)}" if mine else "–")
            paper_rows.append(row)
    lines += _table(("scene", "ν (λ/μ)", "C2 recovered", "IFE recovered"), paper_rows)
    lines += ["", "## Scale invariance", ""]
    lines += _invariance_lines(records)
    lines += ["", "## Every cell that did not come through, with its cause", ""]
    missed = [record for record in records if not _came_through(record)]
    by_cause: dict[str, list[dict[str, Any]]] = {}
    for record in missed:
        by_cause.setdefault(record.get("cause") or "unknown", []).append(record)
    lines += _table(
        ("cause", "cells", "methods"),
        [
            (
                cause,
                len(group),
                ", ".join(sorted({method_label(r["method"]) for r in group})),
            )
            for cause, group in sorted(by_cause.items(), key=lambda item: -len(item[1]))
        ],
    )
    lines += ["", *_CAUSE_TEXT_LINES(by_cause)]
    lines += [""]
    lines += _table(
        ("scene", "method", "ν", "E", "dt", "outcome", "cause: data"),
        [
            (
                r["scene"],
                method_label(r["method"]),
                f"{r['nu']:g}",
                f"{r['E']:g}",
                f"{r['dt']:g}",
                r.get("outcome"),
                f"**{r.get('cause')}**: {r.get('cause_detail') or r.get('reason') or ''}".replace(
                    "|", "/"
                ),
            )
            for r in missed
        ],
    )
    return lines + [""]


def _workers_used(records: Sequence[dict[str, Any]]) -> str:
    return str(records[0].get("workers", "")) if records and records[0].get("workers") else "the"


def _CAUSE_TEXT_LINES(by_cause: dict[str, list[dict[str, Any]]]) -> list[str]:  # noqa: N802
    return [f"- **{cause}**: {CAUSES[cause]}" for cause in by_cause if cause in CAUSES]


def _invariance_lines(records: Sequence[dict[str, Any]]) -> list[str]:
    """Compare cells with the same dt·c/L (the same dimensionless problem)."""
    groups: dict[tuple, list[dict[str, Any]]] = {}
    for record in records:
        star = round(math.log10(record["dt_star"]), 6)
        groups.setdefault((record["scene"], record["method"], record["nu"], star), []).append(
            record
        )
    pairs = [group for group in groups.values() if len(group) > 1]
    if not pairs:
        return ["No two cells share a dimensionless step."]
    same_outcome = sum(1 for group in pairs if len({r.get("outcome") for r in group}) == 1)
    same_newton = sum(1 for group in pairs if len({r.get("newton_total") for r in group}) == 1)
    spreads = [
        (max(totals) - min(totals)) / max(max(totals), 1)
        for totals in (
            [r["newton_total"] for r in group if r.get("newton_total") is not None]
            for group in pairs
        )
        if totals
    ]
    lines = [
        f"Cells with the same dt·c/L (different E and dt) are the same dimensionless problem: "
        f"{len(pairs)} such pairs, {same_outcome} with the same outcome, {same_newton} with the "
        f"same total of Newton iterations; the largest difference in that total is "
        f"{100 * max(spreads, default=0.0):.1f} % (E and dt differ by factors that are not "
        "powers of two, so the twins round differently).",
    ]
    differing = [group for group in pairs if len({r.get("outcome") for r in group}) > 1]
    for group in differing:
        first = group[0]
        lines.append(
            f"- differs: {first['scene']}, {method_label(first['method'])}, ν = {first['nu']:g}, "
            f"dt·c/L = {first['dt_star']:g}: "
            + ", ".join(f"E = {r['E']:g}: {r.get('outcome')}" for r in group)
        )
    return lines
