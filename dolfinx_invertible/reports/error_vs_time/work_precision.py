"""Work-precision helpers: errors between sampled runs, observed orders, cheapest runs, plots.

Independent of DOLFINx: everything here works on the rows (dicts) the error-vs-time report
collects, so it can be tested on made-up data.
"""

from __future__ import annotations

import csv
import math
import pathlib
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

__all__ = [
    "cheapest",
    "observed_order",
    "plot_study",
    "relative_errors",
    "write_csv",
]


def relative_errors(values: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """Return the relative ℓ² and max-norm differences of sampled values from a reference.

    Parameters
    ----------
    values, reference
        Arrays of one shape, e.g. (points, components): the same samples of two runs.

    Returns
    -------
    (l2, max)
        ‖values − reference‖₂ / ‖reference‖₂ over all entries, and
        max |values − reference| / max |reference| with |·| the Euclidean norm per point (last
        axis).
    """
    values = np.asarray(values, dtype=float)
    reference = np.asarray(reference, dtype=float)
    if values.shape != reference.shape:
        raise ValueError(
            f"samples of shape {values.shape} against a reference of {reference.shape}"
        )
    scale = np.linalg.norm(reference)
    if not scale > 0.0:
        raise ValueError("the reference samples are all zero: no relative error")
    difference = values - reference
    l2 = float(np.linalg.norm(difference) / scale)
    pointwise = np.linalg.norm(difference.reshape(len(difference), -1), axis=1)
    magnitude = np.linalg.norm(reference.reshape(len(reference), -1), axis=1)
    return l2, float(pointwise.max() / magnitude.max())


def observed_order(sizes: Sequence[float], errors: Sequence[float]) -> dict[str, Any]:
    """Fit error ≈ C · size^p by least squares in log–log over the usable points.

    Points with a non-finite or non-positive error or size are left out.

    Returns
    -------
    dict
        ``order`` (the fitted p over all usable points), ``finest_pair`` (the slope between
        the two smallest sizes), ``points`` (how many were used), ``sizes`` (their range); the
        orders are NaN with fewer than two points.
    """
    pairs = sorted(
        (float(size), float(error))
        for size, error in zip(sizes, errors, strict=True)
        if size is not None
        and error is not None
        and math.isfinite(size)
        and math.isfinite(error)
        and size > 0.0
        and error > 0.0
    )
    result: dict[str, Any] = {"order": math.nan, "finest_pair": math.nan, "points": len(pairs)}
    if len(pairs) < 2 or len({size for size, _ in pairs}) < 2:
        return result
    logs = np.log(np.array(pairs))
    result["order"] = float(np.polyfit(logs[:, 0], logs[:, 1], 1)[0])
    (small, error_small), (next_size, error_next) = logs[0], logs[1]
    result["finest_pair"] = float((error_next - error_small) / (next_size - small))
    result["sizes"] = [pairs[0][0], pairs[-1][0]]
    return result


def cheapest(
    rows: Iterable[dict[str, Any]], target: float, *, error: str = "error"
) -> dict[str, Any] | None:
    """Return the row of least wall time whose ``error`` is at most ``target``, or None."""
    candidates = [
        row
        for row in rows
        if row.get("completed")
        and row.get(error) is not None
        and math.isfinite(row[error])
        and row[error] <= target
        and row.get("wall_time_s") is not None
    ]
    return min(candidates, key=lambda row: row["wall_time_s"], default=None)


def write_csv(path: pathlib.Path, rows: Sequence[dict[str, Any]], fields: Sequence[str]) -> None:
    """Write ``rows`` with the columns ``fields`` (missing values empty, floats to 6 digits)."""

    def cell(value):
        if value is None or (isinstance(value, float) and not math.isfinite(value)):
            return ""
        if isinstance(value, float):
            return f"{value:.6g}"
        return value

    with open(path, "w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(fields), extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({name: cell(row.get(name)) for name in fields})


def _new_figure(**options):
    """Make a figure on an Agg canvas outside pyplot: no global backend state to change."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(layout="constrained", **options)
    FigureCanvasAgg(figure)
    return figure


def _finite(value) -> bool:
    return value is not None and isinstance(value, (int, float)) and math.isfinite(value)


def _sweep_value(row) -> float:
    value = row.get(row.get("sweep"))
    return float(value) if _finite(value) else 0.0


def _curves(rows, error: str, x: str):
    """Return {curve: rows} of the completed rows with a finite error and x, in sweep order.

    Along a curve the points follow its swept parameter (``row[row["sweep"]]``), so that a
    work-precision curve runs from coarse to fine even where the wall times are not monotone.
    """
    curves: dict[str, list] = {}
    for row in rows:
        if not row.get("completed") or not _finite(row.get(error)) or not _finite(row.get(x)):
            continue
        if row[error] <= 0.0:
            continue
        curves.setdefault(row["curve"], []).append(row)
    return {name: sorted(members, key=_sweep_value) for name, members in curves.items() if members}


def plot_study(
    path: pathlib.Path,
    rows: Sequence[dict[str, Any]],
    *,
    title: str,
    panels: Sequence[dict[str, Any]],
    dpi: int = 100,
) -> None:
    """Draw one figure of log–log panels, one curve per method (the rows' ``curve``).

    Parameters
    ----------
    path
        The PNG to write.
    rows
        The study's rows (reference runs excluded by the caller).
    title
        Figure title.
    panels
        One dict per panel: ``x`` and ``error`` (row keys), ``xlabel``, ``ylabel``, ``title``,
        optionally ``curves`` (the curve names to draw; default all that have data),
        ``slopes`` (True: the legend gives each curve's fitted order) and ``lines`` (a list of
        (value, label) horizontal reference lines).
    dpi
        Resolution.
    """
    import matplotlib

    columns = min(2, len(panels))
    rows_of_panels = math.ceil(len(panels) / columns)
    figure = _new_figure(figsize=(6.5 * columns, 5.0 * rows_of_panels))
    axes_list = np.atleast_1d(figure.subplots(rows_of_panels, columns)).ravel()
    colours = matplotlib.colormaps["tab20"].colors
    names = sorted({row["curve"] for row in rows})
    colour_of = {name: colours[index % len(colours)] for index, name in enumerate(names)}
    markers = "osd^v<>pPhX*"
    for axes in axes_list[len(panels) :]:
        axes.set_visible(False)
    for axes, panel in zip(axes_list, panels, strict=False):
        curves = _curves(rows, panel["error"], panel["x"])
        wanted = panel.get("curves")
        drawn = 0
        for index, (name, members) in enumerate(sorted(curves.items())):
            if wanted is not None and name not in wanted:
                continue
            xs = [row[panel["x"]] for row in members]
            ys = [row[panel["error"]] for row in members]
            label = name
            if panel.get("slopes"):
                order = observed_order(xs, ys)["order"]
                if math.isfinite(order):
                    label = f"{name} (order {order:.2f})"
            axes.loglog(
                xs,
                ys,
                marker=markers[index % len(markers)],
                color=colour_of[name],
                label=label,
                linewidth=1.2,
                markersize=5,
            )
            drawn += 1
        for value, label in panel.get("lines", ()):
            if _finite(value) and value > 0.0:
                axes.axhline(value, color="grey", linestyle="--", linewidth=1.0, label=label)
        axes.set_xlabel(panel["xlabel"])
        axes.set_ylabel(panel["ylabel"])
        axes.set_title(panel["title"], fontsize=10)
        axes.grid(True, which="both", alpha=0.3)
        if drawn:
            axes.legend(fontsize=7, loc="best")
        else:
            axes.text(0.5, 0.5, "no completed runs", transform=axes.transAxes, ha="center")
    figure.suptitle(title, fontsize=11)
    figure.savefig(path, dpi=dpi)
