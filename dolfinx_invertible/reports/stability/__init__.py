"""Stability study: which methods come through which scenes, over E, ν and the time step.

The matrix: the scenes ``collapse``, ``scatter``, ``compress-block`` and ``stretch-bar`` ×
eight methods (:data:`~.study.METHODS`) × ν in :data:`~.study.POISSON_RATIOS` × E in
:data:`~.study.YOUNGS_MODULI` (ρ = :data:`~.study.DENSITY`) × dt in
:data:`~.study.TIME_STEPS`. Every cell is one scene run
(:func:`~dolfinx_invertible.scenes.runner.run_scene` without output, on ``MPI.COMM_SELF``) in a
pool of worker processes started as fresh interpreters (the parent has initialised MPI, so no
fork); the parent writes one CSV row per cell, one heat map per scene and a Markdown summary
that names the cause of every cell that did not come through.

Methodology (see docs/stability.md). A relaxation scene depends only on ν, the extension and
the dimensionless step dt·c/L (c = √(E/ρ), L the body size; docs/design.md, "Scale"), so every
run uses a body of :data:`~.study.SIZE` = 0.1 m and an end time in units of L/c
(:data:`~.study.SCENE_SETUPS`); the matrix's six (E, dt) pairs are then four dimensionless steps
0.01, 0.1, 1 and 10, two of them twice, which the report uses as a consistency check. The
relaxation scenes get mass-proportional damping of half the critical damping of the lowest
mode (the compress-block scene's own default): every underdamped mode then decays like
exp(−ζπ·t c/L), a factor 10⁻⁴ over the end time, so "recovered" (no inverted cell, rest
distance below 10⁻³ of the diameter) is reachable in every cell of the matrix. The stretch bar
keeps its own (no damping, its end time in units of L/c).

Causes. A cell that does not come through is diagnosed from data: a failed step is retried
once more from the last converged state with the cut step, and the last Newton iterate of that
attempt is examined (singular values of its inverted points against the corotated model's kink
σ₂ + σ₃ = 0, the inversion-free cap, the spectrum of the tangent, the step size against the
controller's floor); a relaxation that ends inverted or away from rest is continued with long
damped steps (each nearly a static minimisation from the state before) to tell a trapped,
inverted equilibrium from an end time that was too short. :func:`diagnose` maps the numbers

- :mod:`.study`: the matrix (scenes, methods, ν, E, dt) and every cell's scene parameters;
- :mod:`.runner`: one cell, run in a worker, and the numbers its diagnosis reads;
- :mod:`.instrumentation`: the SNES monitor and step-limit caps a cell records;
- :mod:`.diagnosis`: the cause of a cell that did not come through;
- :mod:`.pool`: the worker processes (``python -m dolfinx_invertible.reports.stability
  --worker``);
- :mod:`.outputs`: the CSV, the heat maps and the Markdown summary;
- :mod:`.report`: :func:`run`, the whole study, and :func:`check_options`, what it refuses;
- :mod:`.cli`: ``python -m dolfinx_invertible report stability [--quick] [--out DIR]``.
"""

from dolfinx_invertible.reports.stability.cli import add_arguments, command
from dolfinx_invertible.reports.stability.diagnosis import diagnose
from dolfinx_invertible.reports.stability.outputs import COLUMNS
from dolfinx_invertible.reports.stability.pool import run_cells
from dolfinx_invertible.reports.stability.report import check_options, run
from dolfinx_invertible.reports.stability.study import (
    DENSITY,
    METHODS,
    POISSON_RATIOS,
    SCENE_SETUPS,
    SCENES,
    SIZE,
    TIME_STEPS,
    YOUNGS_MODULI,
    Cell,
    Method,
    SceneSetup,
    matrix,
)

__all__ = [
    "COLUMNS",
    "DENSITY",
    "METHODS",
    "POISSON_RATIOS",
    "SCENES",
    "SCENE_SETUPS",
    "SIZE",
    "TIME_STEPS",
    "YOUNGS_MODULI",
    "Cell",
    "Method",
    "SceneSetup",
    "add_arguments",
    "check_options",
    "command",
    "diagnose",
    "matrix",
    "run",
    "run_cells",
]
