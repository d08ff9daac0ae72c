"""Work-precision study: error against wall time over discretisations, integrators and solvers.

Three studies, each a set of scene runs through
:func:`~dolfinx_invertible.scenes.runner.run_scene` (in-process, one after the other, no output
files) compared with reference runs of the same scene:

- ``cook-membrane`` (quasi-static, 2D, ν = 0.4999): the tip displacement, against the report's
  own finest run (P2 on the finest mesh), shown beside the published 6.9083. Varies the mesh,
  P1/P2, the tangent (auto, projected, exact), the linear solver (direct, or CG + GAMG with
  a relative tolerance ``ksp_rtol``) and the assembly (this package's kernels, or DOLFINx's own
  route: UFL Neo-Hookean compiled by FFCx).
- ``twisting-column`` (dynamic, 3D): the displacement at fixed reference points at
  t = :data:`~.study.TWIST_TIME`, against a fine-mesh P2 run at a small step (the total
  error), and for the time sweeps also against a run of the same mesh at a quarter of the
  finest step (the time error alone). Varies the mesh, P1/P2, the step, backward Euler/BDF2,
  the tangent, the linear solver and the assembly.
- ``collapse`` (dynamic, 3D, through inversion, the extension active): the scene's cube released
  from F = 0.05 I (its elements invert on the way back), the displacement at fixed reference
  points at t = :data:`~.study.COLLAPSE_TIME` on a fixed mesh against a run at a quarter of
  the finest step (the time error). Varies the step, the integrator, C1/C2 and the tangent; a
  mesh sweep shows how far the displacement depends on the mesh, and the full study adds a
  start from the reflection F = diag(−0.5, 1, 1) (every element inverted from the outset) for
  contrast.

Field errors are relative: ‖u − u_ref‖₂ / ‖u_ref‖₂ over all sample points and components (the
``error`` columns; ``error_max`` is the max-norm analogue). Wall times are those of whole runs
(mesh, forms, solves, the scene's own records), after a warm-up run of every combination of
scene, degree, assembly, extension, tangent and linear solver, so that no run pays for

- :mod:`.study`: the plan, one :class:`~.study.Case` per run;
- :mod:`.runner`: running the cases (:func:`run_case`) and the whole study (:func:`run`);
- :mod:`.work_precision`: errors between sampled runs, fitted orders, cheapest runs, plots (no
  DOLFINx);
- :mod:`.analysis`: the orders per curve, the cheapest runs per target, the reference's error;
- :mod:`.outputs`: the CSV, the Markdown, the JSON summary and the figures;
- :mod:`.cli`: ``python -m dolfinx_invertible report error-vs-time``.
"""

from dolfinx_invertible.reports.error_vs_time.analysis import TARGETS
from dolfinx_invertible.reports.error_vs_time.cli import DEFAULT_OUTPUT, add_arguments, command
from dolfinx_invertible.reports.error_vs_time.outputs import write_results
from dolfinx_invertible.reports.error_vs_time.runner import run, run_case
from dolfinx_invertible.reports.error_vs_time.study import (
    COLLAPSE_TIME,
    STUDIES,
    TWIST_TIME,
    Case,
    plan,
)

__all__ = [
    "COLLAPSE_TIME",
    "DEFAULT_OUTPUT",
    "STUDIES",
    "TARGETS",
    "TWIST_TIME",
    "Case",
    "add_arguments",
    "command",
    "plan",
    "run",
    "run_case",
    "write_results",
]
