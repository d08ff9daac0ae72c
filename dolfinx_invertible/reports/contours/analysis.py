"""The analytic facts of the primary-contour report, measured on the traced contours."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dolfinx_invertible.constitutive import FixedCorotated, Material
from dolfinx_invertible.constitutive.contours import (
    branches_through_rest,
    contour_residual,
    distance_to_unit_volume,
    primary_contour,
)

__all__ = [
    "FIXED_COROTATED_RATIOS",
    "MEASURED_STRETCH",
    "analytic_checks",
    "fixed_corotated_distances",
    "trajectory_summary",
]

#: λ/μ of the fixed corotated convergence check, and the range of σ₁ it measures on.
FIXED_COROTATED_RATIOS = (1.0, 10.0, 100.0)
MEASURED_STRETCH = (1.0, 3.0)

# σ₂ below −this counts as inverted: the wedge's apex σ = 0 is reached up to round-off.
_INVERTED = 1e-12


def _measured(polylines: list[np.ndarray]) -> np.ndarray:
    """Select the contour points with σ₁ in the measured stretch range."""
    points = np.concatenate(polylines) if polylines else np.empty((0, 2))
    low, high = MEASURED_STRETCH
    return points[(points[:, 0] >= low) & (points[:, 0] <= high)]


def fixed_corotated_distances(
    ratios: Sequence[float] = FIXED_COROTATED_RATIOS, *, spacing: float = 0.01
) -> tuple[dict[str, list[np.ndarray]], dict[str, float]]:
    """Measure the distance of the fixed corotated contour from J = 1 for several λ/μ.

    Parameters
    ----------
    ratios
        The λ/μ values (μ = 1).
    spacing
        Tracing grid spacing.

    Returns
    -------
    tuple of dict
        By λ/μ (formatted ``f"{ratio:g}"``): the branches through the rest state, and the
        largest distance of their points with σ₁ in :data:`MEASURED_STRETCH` from J = 1.
    """
    branches = {}
    distances = {}
    for ratio in ratios:
        material = Material(FixedCorotated(mu=1.0, lam=float(ratio)))
        rest = branches_through_rest(primary_contour(material, spacing=spacing), spacing=spacing)
        measured = _measured(rest)
        if not len(measured):
            raise RuntimeError(f"no fixed corotated contour traced for lambda/mu = {ratio:g}")
        branches[f"{ratio:g}"] = rest
        distances[f"{ratio:g}"] = float(distance_to_unit_volume(measured).max())
    return branches, distances


def _branch_summary(material, polylines, spacing) -> dict:
    rest = branches_through_rest(polylines, spacing=spacing)
    rest_ids = {id(polyline) for polyline in rest}
    points = np.concatenate(polylines)
    interior = np.concatenate([polyline[1:-1] for polyline in polylines])
    rest_points = np.concatenate(rest) if rest else np.empty((0, 2))
    return {
        "branches": len(polylines),
        "branches_through_rest": len(rest),
        "min_sigma2": float(points[:, 1].min()),
        "min_sigma2_through_rest": float(rest_points[:, 1].min()) if len(rest) else None,
        "max_sigma1_through_rest": float(rest_points[:, 0].max()) if len(rest) else None,
        # End points may be chord interpolations on the wedge boundary (near the rest state g
        # nearly vanishes and |v·g|/|g| means little there): the refined vertices are inside.
        "max_residual": float(contour_residual(material, interior).max()),
        "other_branches": [
            {
                "ends": [polyline[0].tolist(), polyline[-1].tolist()],
                "min_sigma2": float(polyline[:, 1].min()),
            }
            for polyline in polylines
            if id(polyline) not in rest_ids
        ],
    }


def analytic_checks(materials, contours, spacing, artists, distances) -> dict:
    """Return the analytic facts of the report as numbers, per material (JSON-ready)."""
    checks = {name: _branch_summary(materials[name], contours[name], spacing) for name in materials}

    corotated = checks["corotated"]
    points = np.concatenate(contours["corotated"])
    corotated["max_distance_from_sum_2"] = float(
        np.abs(points.sum(axis=1) - 2.0).max() / np.sqrt(2)
    )
    corotated["crosses_into_inverted"] = bool(corotated["min_sigma2"] < -_INVERTED)

    fixed = checks["fixed corotated"]
    fixed["enters_inverted"] = bool(fixed["min_sigma2"] < -_INVERTED)
    measured = _measured(branches_through_rest(contours["fixed corotated"], spacing=spacing))
    fixed["distance_to_J1"] = float(distance_to_unit_volume(measured).max())
    fixed["distance_to_J1_by_lambda_over_mu"] = distances

    for name in ("Neo-Hookean + C1", "Neo-Hookean + C2"):
        entry = checks[name]
        entry["branch_through_rest_enters_inverted"] = bool(
            entry["min_sigma2_through_rest"] < -_INVERTED
        )
        entry["enters_inverted"] = bool(entry["min_sigma2"] < -_INVERTED)

    deviation = 0.0
    for name, material in materials.items():
        quiver = artists[name]["quiver"]
        gradient = material.stress_sigma(np.column_stack([quiver.X, quiver.Y]))
        expected = -gradient / np.linalg.norm(gradient, axis=1, keepdims=True)
        drawn = np.column_stack([quiver.U, quiver.V])
        deviation = max(deviation, float(np.abs(drawn - expected).max()))
    checks["quiver_max_deviation_from_minus_gradient"] = deviation
    return checks


def trajectory_summary(trajectories) -> dict:
    """Return per material the smallest σ₂ of each element and its end state."""
    return {
        name: {
            "min_sigma2": values[..., 1].min(axis=1).tolist(),
            "final": values[:, -1].tolist(),
        }
        for name, values in trajectories.items()
    }
