"""The primary-contour report: trace, draw and check, and write the figures."""

from __future__ import annotations

import pathlib
import time
from collections.abc import Sequence

import numpy as np

from dolfinx_invertible.constitutive.contours import WINDOW, primary_contour
from dolfinx_invertible.reports.contours.analysis import (
    analytic_checks,
    fixed_corotated_distances,
    trajectory_summary,
)
from dolfinx_invertible.reports.contours.figures import (
    fixed_corotated_figure,
    panels,
    scene_figure,
)
from dolfinx_invertible.reports.contours.materials import POISSON_RATIO, report_materials
from dolfinx_invertible.reports.contours.trajectories import (
    LATERAL_STIFFNESS,
    RELAXATION_STARTS,
    relaxation_trajectories,
    stretch_trajectories,
)

__all__ = ["run"]


def _times_mu(factor: float) -> str:
    return "0" if factor == 0 else "μ" if factor == 1 else f"{factor:g}μ"


def run(
    output_directory,
    *,
    quick: bool = False,
    mattress: Sequence | None = None,
    triangles: Sequence | None = None,
) -> dict:
    """Write the report's figures and return a JSON-ready summary with the analytic checks.

    Parameters
    ----------
    output_directory
        Directory for the PNG files (created if missing).
    quick
        A coarser tracing grid (spacing 0.04 instead of 0.01), shorter trajectories and
        figures at 60 instead of 100 dpi.
    mattress, triangles
        Output directories of ``mattress-2d`` or ``triangles-2d`` runs: their trajectories
        replace the computed stand-ins of the stretch (relaxation) figure, one panel per run,
        with the contour of the material it ran with.

    Returns
    -------
    dict
        ``figures`` (file names in ``output_directory``), ``materials``, ``spacing``,
        ``window``, ``checks`` (the analytic facts as numbers), ``stretch`` and ``relaxation``
        (per material and element: the smallest σ₂ and the end state; with scene data,
        ``scene_runs``: per run its material, element and step counts, smallest σ₂ and how many
        elements inverted) and ``seconds``.
    """
    begin = time.perf_counter()
    directory = pathlib.Path(output_directory)
    directory.mkdir(parents=True, exist_ok=True)
    spacing = 0.04 if quick else 0.01
    stretches = np.linspace(1.0, 3.5, 26 if quick else 101)
    steps, growth = (40, 1.12) if quick else (60, 1.08)
    # Drawing dominates the quick run.
    dpi = 60 if quick else 100

    materials = report_materials()
    contours = {name: primary_contour(m, spacing=spacing) for name, m in materials.items()}
    stretch = {name: stretch_trajectories(m, stretches=stretches) for name, m in materials.items()}
    relaxation = {
        name: relaxation_trajectories(m, RELAXATION_STARTS, steps=steps, growth=growth)
        for name, m in materials.items()
    }
    ratio_branches, distances = fixed_corotated_distances(spacing=spacing)

    figures = {
        "contours": "contours.png",
        "stretch": "contours_stretch.png",
        "relaxation": "contours_relaxation.png",
        "fixed_corotated": "contours_fixed_corotated.png",
    }
    figure, artists = panels(
        materials,
        contours,
        spacing,
        f"Primary contours v·g = 0 in the singular-value plane, plane strain, ν = {POISSON_RATIO}"
        "\narrows: direction of −∇Ψ (unit length)",
    )
    figure.savefig(directory / figures["contours"], dpi=dpi)
    scene_runs = {}
    if mattress:
        figure, scene_runs["stretch"] = scene_figure(
            list(mattress),
            spacing,
            "Mattress scene: every element's singular values over the "
            "load steps, on the primary contour of the run's material",
        )
    else:
        figure, _ = panels(
            materials,
            contours,
            spacing,
            "Computed stand-in for the stretched mattress: single elements, σ₁ imposed 1 → 3.5,"
            "\nσ₂ at equilibrium with a lateral spring κ (κ = 0: free sides)",
            trajectories=stretch,
            labels=[f"stretch, κ = {_times_mu(factor)}" for factor in LATERAL_STIFFNESS],
        )
    figure.savefig(directory / figures["stretch"], dpi=dpi)
    if triangles:
        figure, scene_runs["relaxation"] = scene_figure(
            list(triangles),
            spacing,
            "Triangles scene: the three triangles' singular values "
            "over time, on the primary contour of the run's material",
        )
    else:
        figure, _ = panels(
            materials,
            contours,
            spacing,
            "Computed stand-in for the relaxing triangles: single free elements, implicit "
            "gradient flow\n(projected Newton per step) from three deformations",
            trajectories=relaxation,
            labels=[
                f"from ({start[0]:g}, {start[1]:g}){', inverted' if start[1] < 0 else ''}"
                for start in RELAXATION_STARTS
            ],
        )
    figure.savefig(directory / figures["relaxation"], dpi=dpi)
    fixed_corotated_figure(ratio_branches, distances).savefig(
        directory / figures["fixed_corotated"], dpi=dpi
    )

    return {
        "figures": figures,
        "materials": {name: repr(material) for name, material in materials.items()},
        "spacing": spacing,
        "window": [list(WINDOW[0]), list(WINDOW[1])],
        "checks": analytic_checks(materials, contours, spacing, artists, distances),
        "stretch": {"lateral_stiffness_over_mu": list(LATERAL_STIFFNESS)}
        | trajectory_summary(stretch)
        | ({"scene_runs": scene_runs["stretch"]} if "stretch" in scene_runs else {}),
        "relaxation": {"starts": RELAXATION_STARTS.tolist()}
        | trajectory_summary(relaxation)
        | ({"scene_runs": scene_runs["relaxation"]} if "relaxation" in scene_runs else {}),
        "seconds": time.perf_counter() - begin,
    }
