"""The plan of the study: its runs (cases), per study, with their references."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["COLLAPSE_TIME", "Case", "REFLECTION", "STUDIES", "TWIST_TIME", "plan"]

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
