"""The report's drawings: contours, the field of −g, element trajectories, the figures."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dolfinx_invertible.constitutive import Material
from dolfinx_invertible.constitutive.contours import (
    REST,
    WINDOW,
    branches_through_rest,
    check_window,
    distance_to_unit_volume,
    energy_derivatives,
    primary_contour,
)
from dolfinx_invertible.reports.contours.analysis import MEASURED_STRETCH
from dolfinx_invertible.reports.contours.scene_output import load_scene_trajectories

__all__ = [
    "fixed_corotated_figure",
    "gradient_field",
    "overlay_trajectories",
    "panels",
    "plot_contours",
    "scene_figure",
]

_COLORS = ("tab:orange", "tab:green", "tab:purple")


def gradient_field(
    material: Material, *, window=WINDOW, count: tuple[int, int] = (19, 17)
) -> tuple[np.ndarray, np.ndarray]:
    """Sample points strictly inside the canonical wedge and the energy gradient g there.

    Parameters
    ----------
    material
        The material (2D).
    window
        The plotted window.
    count
        Grid points along σ₁ and σ₂ before keeping those inside the wedge.

    Returns
    -------
    tuple of numpy.ndarray
        Points (n, 2) and g = ∇Ψ̂ at them (n, 2).
    """
    (low_1, high_1), (low_2, high_2) = check_window(window)
    margin_1 = 0.5 * (high_1 - low_1) / count[0]
    margin_2 = 0.5 * (high_2 - low_2) / count[1]
    axis_1 = np.linspace(low_1 + margin_1, high_1 - margin_1, count[0])
    axis_2 = np.linspace(low_2 + margin_2, high_2 - margin_2, count[1])
    points = np.stack(np.meshgrid(axis_1, axis_2), axis=-1).reshape(-1, 2)
    points = points[points[:, 0] > np.abs(points[:, 1]) + 0.5 * min(margin_1, margin_2)]
    gradient, _ = energy_derivatives(material, points)
    defined = np.isfinite(gradient).all(axis=1)
    return points[defined], gradient[defined]


def _shade(axes, window) -> None:
    """Shade σ₁ < |σ₂| (invalid) and tint the inverted half σ₂ < 0 of the wedge."""
    (low_1, high_1), (low_2, high_2) = window
    sigma_1 = np.unique(np.concatenate([np.linspace(low_1, high_1, 400), [0.0]]))
    sigma_1 = sigma_1[(sigma_1 >= low_1) & (sigma_1 <= high_1)]
    wedge = sigma_1 >= 0.0
    upper = np.where(wedge, np.clip(sigma_1, low_2, high_2), low_2)
    lower = np.where(wedge, np.clip(-sigma_1, low_2, high_2), low_2)
    style = {"facecolor": "0.82", "edgecolor": "0.6", "hatch": "//", "linewidth": 0.0}
    axes.fill_between(sigma_1, upper, high_2, label="invalid (σ₁ < |σ₂|)", **style)
    axes.fill_between(sigma_1, low_2, lower, **style)
    inverted_top = np.where(wedge, np.clip(0.0, low_2, high_2), low_2)
    axes.fill_between(
        sigma_1,
        lower,
        np.maximum(lower, inverted_top),
        facecolor="tab:red",
        alpha=0.08,
        linewidth=0.0,
        label="inverted (σ₂ < 0)",
    )
    if low_2 < 0.0 < high_2:
        axes.axhline(0.0, color="tab:red", linewidth=0.6, alpha=0.6)


def _reference_curves(axes, window) -> None:
    """σ₁ + σ₂ = 2 and J = 1 inside the wedge, for reference."""
    (low_1, high_1), (low_2, high_2) = window
    sigma_1 = np.linspace(max(low_1, 1.0), max(high_1, 1.0), 300)
    for values, style, label in (
        (2.0 - sigma_1, "--", "σ₁ + σ₂ = 2"),
        (1.0 / sigma_1, ":", "J = 1"),
    ):
        inside = (values >= low_2) & (values <= high_2)
        axes.plot(
            sigma_1[inside],
            values[inside],
            color="0.35",
            linestyle=style,
            linewidth=0.9,
            label=label,
        )


def _draw_branches(axes, polylines, spacing) -> dict:
    """Draw the branch through the rest state solid, the others dashed."""
    rest = {id(polyline) for polyline in branches_through_rest(polylines, spacing=spacing)}
    lines = {"rest": [], "other": []}
    for polyline in polylines:
        key = "rest" if id(polyline) in rest else "other"
        label = None
        if not lines[key]:
            label = "primary contour through rest" if key == "rest" else "other branches"
        style = (
            {"linewidth": 2.4, "linestyle": "-"}
            if key == "rest"
            else {"linewidth": 1.4, "linestyle": (0, (4, 2))}
        )
        (line,) = axes.plot(
            polyline[:, 0], polyline[:, 1], color="black", label=label, zorder=3, **style
        )
        lines[key].append(line)
    return lines


def plot_contours(
    axes,
    material: Material,
    *,
    window=WINDOW,
    spacing: float = 0.01,
    title: str | None = None,
    contour: list[np.ndarray] | None = None,
    arrows: tuple[int, int] = (19, 17),
    legend: bool = True,
) -> dict:
    """Draw a material's primary contour, the field of −g and the invalid region on ``axes``.

    The arrows show the direction of −g = −∇Ψ̂, the force on an element in σ-space (where it
    moves when it relaxes), all of one length; the shaded region is outside the canonical
    wedge σ₁ ≥ |σ₂|, and the tinted part of the wedge is inverted (σ₂ < 0). The branch of the
    contour through the rest state (star) is solid, other branches dashed; thin grey lines are
    σ₁ + σ₂ = 2 (dashed) and J = 1 (dotted) for reference.

    Parameters
    ----------
    axes
        A matplotlib Axes.
    material
        The material (2D).
    window
        The plotted window.
    spacing
        Tracing grid spacing (also used to find the branch through rest in ``contour``).
    title
        Axes title.
    contour
        Polylines from :func:`primary_contour` traced with ``spacing``, to reuse a trace.
    arrows
        Arrow grid (σ₁, σ₂) before keeping the points inside the wedge.
    legend
        Draw a legend.

    Returns
    -------
    dict
        ``"quiver"``: the Quiver, whose X, Y, U, V are the arrow positions and −g/|g|;
        ``"contour"``: ``{"rest": [...], "other": [...]}``, the Line2D of the branches;
        ``"polylines"``: the traced polylines.
    """
    window = check_window(window)
    if contour is None:
        contour = primary_contour(material, window=window, spacing=spacing)
    _shade(axes, window)
    _reference_curves(axes, window)
    points, gradient = gradient_field(material, window=window, count=arrows)
    norm = np.linalg.norm(gradient, axis=1, keepdims=True)
    direction = -gradient / np.where(norm > 0.0, norm, 1.0)
    length = 0.6 * min(window[0][1] - window[0][0], window[1][1] - window[1][0]) / max(arrows)
    quiver = axes.quiver(
        points[:, 0],
        points[:, 1],
        direction[:, 0],
        direction[:, 1],
        angles="xy",
        scale_units="xy",
        scale=1.0 / length,
        width=0.0035,
        color="tab:blue",
        alpha=0.55,
    )
    lines = _draw_branches(axes, contour, spacing)
    axes.plot(*REST, marker="*", color="gold", markeredgecolor="black", markersize=11, zorder=5)
    axes.set_xlim(*window[0])
    axes.set_ylim(*window[1])
    axes.set_aspect("equal")
    axes.set_xlabel("σ₁")
    axes.set_ylabel("σ₂ (signed)")
    if title:
        axes.set_title(title, fontsize=10)
    if legend:
        axes.legend(loc="upper left", fontsize=7, framealpha=0.92)
    return {"quiver": quiver, "contour": lines, "polylines": contour}


def overlay_trajectories(
    axes,
    trajectories: np.ndarray,
    *,
    labels: Sequence[str] | None = None,
    colors: Sequence | None = None,
    tolerance: float = 1e-9,
    linewidth: float = 1.4,
    markers: bool = True,
) -> list:
    """Draw element trajectories in the σ-plane on top of a contour plot.

    Parameters
    ----------
    axes
        A matplotlib Axes, typically one :func:`plot_contours` drew on.
    trajectories
        Shape (elements, steps, 2): each element's signed singular values per step, sorted in
        the IFE convention (σ₁ ≥ |σ₂|, an inversion's sign on σ₂), e.g. from a scene's output.
    labels
        One legend label per element, or None.
    colors
        One matplotlib colour per element, or None for the colour cycle.
    tolerance
        Relative slack on σ₁ ≥ |σ₂| for round-off in the data.
    linewidth
        Line width of the trajectories.
    markers
        Mark each start (circle) and end (square).

    Returns
    -------
    list
        The Line2D of each trajectory, in element order.
    """
    trajectories = np.asarray(trajectories, dtype=float)
    if trajectories.ndim != 3 or trajectories.shape[2] != 2 or trajectories.shape[1] < 1:
        raise ValueError(
            f"trajectories must have shape (elements, steps, 2), got shape {trajectories.shape}"
        )
    bad = np.argwhere(~np.isfinite(trajectories).all(axis=2))
    if len(bad):
        element, step = bad[0]
        raise ValueError(
            f"trajectories has {len(bad)} non-finite points, the first at element {element}, "
            f"step {step}"
        )
    slack = tolerance * np.maximum(1.0, np.abs(trajectories).max(axis=2))
    wrong = np.argwhere(trajectories[..., 0] < np.abs(trajectories[..., 1]) - slack)
    if len(wrong):
        element, step = wrong[0]
        raise ValueError(
            f"trajectories must follow the IFE convention sigma1 >= |sigma2|; {len(wrong)} "
            f"points do not, the first at element {element}, step {step}: "
            f"{trajectories[element, step].tolist()}"
        )
    count = len(trajectories)
    for name, values in (("labels", labels), ("colors", colors)):
        if values is not None and len(values) != count:
            raise ValueError(f"{name} has {len(values)} entries for {count} trajectories")
    lines = []
    for element, path in enumerate(trajectories):
        options = {"linewidth": linewidth, "zorder": 4}
        if colors is not None:
            options["color"] = colors[element]
        if labels is not None:
            options["label"] = labels[element]
        (line,) = axes.plot(path[:, 0], path[:, 1], **options)
        if markers:
            color = line.get_color()
            axes.plot(*path[0], marker="o", color=color, markersize=5, zorder=6)
            axes.plot(
                *path[-1], marker="s", color=color, markeredgecolor="black", markersize=5, zorder=6
            )
        lines.append(line)
    return lines


def _new_figure(**options):
    """Make a figure on an Agg canvas outside pyplot: no global backend state to change."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(layout="constrained", **options)
    FigureCanvasAgg(figure)
    return figure


def panels(materials, contours, spacing, title, trajectories=None, labels=None):
    """Draw one panel per material: its contour, −g and, if given, its elements' trajectories.

    Returns the figure and each panel's artists (see :func:`plot_contours`) by material name.
    """
    figure = _new_figure(figsize=(11, 10.2))
    artists = {}
    for axes, (name, material) in zip(
        figure.subplots(2, 2).ravel(), materials.items(), strict=True
    ):
        drawn = plot_contours(
            axes, material, spacing=spacing, contour=contours[name], title=name, legend=False
        )
        if trajectories is not None:
            elements = len(trajectories[name])
            drawn["trajectories"] = overlay_trajectories(
                axes, trajectories[name], labels=labels, colors=_COLORS[:elements]
            )
        axes.legend(loc="upper left", fontsize=7, framealpha=0.92)
        artists[name] = drawn
    figure.suptitle(title, fontsize=11)
    return figure, artists


def fixed_corotated_figure(branches, distances):
    """Draw the fixed corotated branches through rest and their distance to J = 1, per λ/μ."""
    figure = _new_figure(figsize=(11, 4.6))
    left, right = figure.subplots(1, 2)
    sigma_1 = np.linspace(0.8, 3.2, 200)
    left.plot(sigma_1, 1.0 / sigma_1, color="0.2", linestyle=":", linewidth=1.4, label="J = 1")
    colors = ("tab:red", "tab:orange", "tab:blue", "tab:green", "tab:purple")
    for number, (ratio, polylines) in enumerate(branches.items()):
        color = colors[number % len(colors)]
        for index, polyline in enumerate(polylines):
            first = index == 0
            left.plot(
                polyline[:, 0],
                polyline[:, 1],
                color=color,
                linewidth=1.6,
                label=f"λ/μ = {ratio}" if first else None,
            )
            # The rest state itself is on J = 1: leave it out of the logarithmic plot.
            away = polyline[:, 0] > 1.0 + 1e-3
            right.semilogy(
                polyline[away, 0],
                distance_to_unit_volume(polyline[away]),
                color=color,
                label=f"λ/μ = {ratio}: max {distances[ratio]:.2e}" if first else None,
            )
    for axes in (left, right):
        axes.axvspan(*MEASURED_STRETCH, color="0.5", alpha=0.07, linewidth=0.0)
        axes.set_xlim(0.8, 3.2)
        axes.set_xlabel("σ₁")
        axes.legend(fontsize=8)
    left.set_ylim(0.2, 1.2)
    left.set_ylabel("σ₂")
    left.set_title("branch through rest (σ₂ ≤ σ₁)", fontsize=10)
    right.set_ylabel("distance to J = 1")
    right.set_title(
        f"distance to J = 1; max over {MEASURED_STRETCH[0]:g} ≤ σ₁ ≤ {MEASURED_STRETCH[1]:g} "
        "(shaded)",
        fontsize=10,
    )
    figure.suptitle("Fixed corotated: the primary contour approaches J = 1 as λ/μ grows")
    return figure


def _scene_label(summary: dict) -> str:
    parameters = summary["parameters"]
    extension = "" if summary["extension"] == "none" else f" + {summary['extension'].upper()}"
    return f"{summary['scene']}: {summary['model']}{extension}, ν = {parameters['nu']:g}"


def scene_figure(directories, spacing: float, title: str) -> tuple:
    """One panel per scene run: its material's contour and every element's trajectory."""
    runs = [load_scene_trajectories(directory) for directory in directories]
    figure = _new_figure(figsize=(5.6 * len(runs), 5.6))
    axes_list = np.atleast_1d(figure.subplots(1, len(runs)))
    summaries = []
    for axes, directory, (trajectories, material, summary) in zip(
        axes_list, directories, runs, strict=True
    ):
        plot_contours(axes, material, spacing=spacing, title=_scene_label(summary), legend=False)
        elements = len(trajectories)
        if elements <= len(_COLORS):
            overlay_trajectories(
                axes,
                trajectories,
                colors=_COLORS[:elements],
                labels=[f"element {index}" for index in range(elements)],
            )
        else:
            # Many elements: thin lines of one colour, without start and end markers.
            overlay_trajectories(
                axes,
                trajectories,
                colors=["tab:orange"] * elements,
                linewidth=0.5,
                markers=False,
            )
        axes.legend(loc="upper left", fontsize=7, framealpha=0.92)
        summaries.append(
            {
                "directory": str(directory),
                "scene": summary["scene"],
                "material": repr(material),
                "completed": summary.get("completed"),
                "elements": elements,
                "steps": int(trajectories.shape[1]),
                "min_sigma2": float(trajectories[..., 1].min()),
                "inverted_elements": int(np.count_nonzero(trajectories[..., 1].min(axis=1) < 0)),
            }
        )
    import textwrap

    # Wrapped to the figure's width (about 12 characters per inch at this size).
    figure.suptitle(textwrap.fill(title, width=int(12 * 5.6 * len(runs))), fontsize=11)
    return figure, summaries
