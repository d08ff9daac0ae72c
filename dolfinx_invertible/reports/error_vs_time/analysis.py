"""Observed orders, the cheapest runs per target and the reference's own error."""

from __future__ import annotations

import math
from typing import Any

from dolfinx_invertible.reports.error_vs_time.study import STUDIES
from dolfinx_invertible.reports.error_vs_time.work_precision import cheapest, observed_order

__all__ = [
    "TARGETS",
    "cheapest_runs",
    "curve_orders",
    "describe_run",
    "reference_error_estimate",
    "reference_row",
]

#: Relative errors for which the summary names the cheapest run.
TARGETS = (1e-2, 1e-3, 1e-4)


def curve_orders(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
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


def reference_row(rows, study: str) -> dict[str, Any] | None:
    """Return the row of the study's reference run, or None."""
    return next(
        (row for row in rows if row["study"] == study and row["curve"] == "reference"), None
    )


def describe_run(row: dict[str, Any]) -> str:
    """Return a run's configuration in words (degree, mesh, step, tangent, assembly, solver)."""
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


def cheapest_runs(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
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
                        "configuration": None if best is None else describe_run(best),
                        "measured": None if best is None else best[error],
                        "wall_time_s": None if best is None else best["wall_time_s"],
                    }
                )
    return result


def reference_error_estimate(rows, orders, study: str) -> float | None:
    """Estimate the reference's own error from the finest P2 space run and its order.

    With e(h) ≈ C hᵖ and the measured e₁ = |u(h₁) − u_ref| ≈ C(h₁ᵖ − h_refᵖ) (same sign),
    C h_refᵖ = e₁ r / (1 − r) with r = (h_ref/h₁)ᵖ.
    """
    reference = reference_row(rows, study)
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
