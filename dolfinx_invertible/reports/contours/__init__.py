"""Primary contours in the 2D singular-value plane (Stomakhin et al. 2012, §3.2, Figs. 1–2).

The report draws the primary contour {σ : v·g = 0} of four materials in plane strain
(:mod:`dolfinx_invertible.constitutive.contours` traces it), the field of −g, and element
trajectories on top: a stretched element relaxes its stiff mode first and then follows the
contour, so a contour that crosses into σ₂ < 0 (corotated: σ₁ + σ₂ = 2) drives stretched
elements through inversion, and one that stays out (fixed corotated: J = 1 for large λ/μ) does
not. The figures shade the window outside the canonical wedge σ₁ ≥ |σ₂|.

- :mod:`.materials`: the four materials;
- :mod:`.trajectories`: the computed stand-ins for the element trajectories;
- :mod:`.scene_output`: the trajectories a ``mattress-2d`` or ``triangles-2d`` run wrote;
- :mod:`.analysis`: the analytic facts, measured on the traced contours;
- :mod:`.figures`: the drawings;
- :mod:`.report`: :func:`run`, which writes the figures and returns the checks;
- :mod:`.cli`: ``python -m dolfinx_invertible report contours``.

Scene data. ``--mattress DIR`` and ``--triangles DIR`` (:func:`run`'s ``mattress`` and
``triangles``) take the output directory of a ``mattress-2d`` or ``triangles-2d`` run, whose
``trajectories.npy`` (elements × steps × 2, the IFE convention) and ``summary.json`` (the
material) replace the computed stand-ins of the stretch and relaxation figures.
"""

from dolfinx_invertible.reports.contours.analysis import fixed_corotated_distances
from dolfinx_invertible.reports.contours.cli import DEFAULT_OUTPUT, add_arguments, command
from dolfinx_invertible.reports.contours.figures import (
    gradient_field,
    overlay_trajectories,
    plot_contours,
)
from dolfinx_invertible.reports.contours.materials import report_materials
from dolfinx_invertible.reports.contours.report import run
from dolfinx_invertible.reports.contours.scene_output import load_scene_trajectories
from dolfinx_invertible.reports.contours.trajectories import (
    relaxation_trajectories,
    stretch_trajectories,
)

__all__ = [
    "DEFAULT_OUTPUT",
    "add_arguments",
    "command",
    "fixed_corotated_distances",
    "gradient_field",
    "load_scene_trajectories",
    "overlay_trajectories",
    "plot_contours",
    "relaxation_trajectories",
    "report_materials",
    "run",
    "stretch_trajectories",
]
