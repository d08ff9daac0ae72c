"""Run one cell of the matrix (in a worker) and measure what tells its causes apart.

A cell is one scene run without output on ``MPI.COMM_SELF``. A failed step is examined (the
last Newton iterate's singular values and tangent, the step limits' caps, a retry with the cut
step); a relaxation that ends inverted or away from rest is continued with long damped steps.
:func:`~dolfinx_invertible.reports.stability.diagnosis.diagnose` maps the numbers to a cause.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from typing import Any

from dolfinx_invertible.reports.stability.diagnosis import diagnose
from dolfinx_invertible.reports.stability.instrumentation import Recorder
from dolfinx_invertible.reports.stability.study import (
    CONTINUATION_STEP,
    CONTINUATION_TIME,
    METHODS_BY_NAME,
    SIZE,
    Cell,
)

__all__ = [
    "LONG_SOLVE",
    "SPECTRUM_LIMIT",
    "inverted_energy_minimum",
    "overlapping_cells",
    "progress_record",
    "run_cell",
]

#: Newton iterations allowed in the diagnostic retry of a step that hit the cap or stalled.
LONG_SOLVE = 1000
#: Largest tangent assembled densely for its spectrum at a failure (unknowns).
SPECTRUM_LIMIT = 3000
#: Candidate (cell, centroid) pairs the overlap count tests at a time.
_OVERLAP_PAIRS = 1 << 20

#: How a failure message names the SNES and KSP reasons (SolveResult.describe).
_REASON_PATTERN = re.compile(r"failed \((?P<snes>[A-Z_]+)(?:, KSP (?P<ksp>[A-Z_0-9]+))?\)")
_CUT_PATTERN = re.compile(r"last dt = (?P<dt>[0-9.eE+-]+)")


def _initial_inverted_cells(scene_class, parameters, comm) -> int:
    """Cells with J ≤ 0 at a quadrature point in the scene's initial state."""
    import dolfinx

    from dolfinx_invertible.fem.diagnostics import cell_diagnostics, summary
    from dolfinx_invertible.fem.spaces import vector_function_space
    from dolfinx_invertible.scenes.parameters import make_material

    scene = scene_class(parameters, comm)
    scene.mesh = scene.create_mesh()
    u = dolfinx.fem.Function(vector_function_space(scene.mesh, parameters.degree))
    initial = scene.initial_displacement()
    if initial is not None:
        u.interpolate(initial)
        u.x.scatter_forward()
    return int(summary(cell_diagnostics(u, make_material(parameters)), comm)["inverted_cells"])


def _point_singular_values(u, quadrature_degree: int | None = None):
    """Return (J, σ) at every quadrature point of every owned cell: shapes (n,), (n, d)."""
    import basix
    import dolfinx
    import numpy as np
    import ufl

    from dolfinx_invertible import _compat
    from dolfinx_invertible.constitutive.svd import polar_svd
    from dolfinx_invertible.fem.forms import default_quadrature_degree

    mesh = u.function_space.mesh
    d = mesh.topology.dim
    cell_type = _compat.basix_element(u.function_space).cell_type
    if quadrature_degree is None:
        quadrature_degree = default_quadrature_degree(
            _compat.element_degree(u.function_space), cell_type
        )
    points, _ = basix.make_quadrature(cell_type, quadrature_degree)
    expression = dolfinx.fem.Expression(ufl.Identity(d) + ufl.grad(u), points)
    cells = np.arange(mesh.topology.index_map(d).size_local, dtype=np.int32)
    values = _compat.evaluate_expression(expression, mesh, cells)
    F = np.ascontiguousarray(values.reshape(-1, d, d))
    _, sigma, _ = polar_svd(F)
    return np.linalg.det(F), sigma


def _state_diagnostics(u, material, minimizer) -> dict[str, Any]:
    """Numbers about a state that tell failure causes apart (see :func:`diagnose`).

    - ``inverted_points``: quadrature points with J ≤ 0;
    - ``kink_gap``: the smallest |σ₂ + σ₃| / σ₁ over the inverted points (canonical signed
      singular values, σ₃ < 0): 0 on the corotated models' kink, where the two smallest |σ|
      swap and the stress jumps;
    - ``tangent_min``, ``tangent_max``, ``tangent_negative``: the extreme eigenvalues and the
      number of negative ones of the tangent at the state (free dofs only, dense, small
      problems only), and ``tangent_condition`` = max |λ| / min |λ|.
    """
    import numpy as np

    J, sigma = _point_singular_values(u)
    inverted = J <= 0.0
    data: dict[str, Any] = {"inverted_points": int(np.count_nonzero(inverted))}
    if inverted.any():
        s = sigma[inverted]
        data["kink_gap"] = float(np.min(np.abs(s[:, -2] + s[:, -1]) / s[:, 0]))
    problem = minimizer.problem
    free = problem.free_owned
    if 0 < len(free) <= SPECTRUM_LIMIT:
        from dolfinx_invertible import _compat

        vector = problem.create_vector()
        _compat.petsc_vector(u).copy(vector)
        tangent = problem.create_matrix()
        problem.J(None, vector, tangent, tangent)
        dense = tangent.convert("dense").getDenseArray()
        eigenvalues = np.linalg.eigvalsh(dense[np.ix_(free, free)])
        magnitude = np.abs(eigenvalues)
        data.update(
            tangent_min=float(eigenvalues[0]),
            tangent_max=float(eigenvalues[-1]),
            tangent_negative=int(np.count_nonzero(eigenvalues < 0.0)),
            tangent_condition=float(magnitude.max() / max(magnitude.min(), 1e-300)),
        )
    return data


def _failure_diagnostics(recorder: Recorder, material) -> dict[str, Any]:
    """Examine the last Newton iterate of the failed step, then retry the step once.

    The numbers of the iterate: :func:`_state_diagnostics`, the residual norms of the attempt
    (``attempt_iterations``, ``residual_drop`` = last over first, ``residual_drop_last10``
    over the last ten iterations) and the caps of the step limits (``cap_last``, ``cap_min``,
    ``cap_median``). The retry, from the restored last converged state with the step the
    controller cut to (below its floor or past its cuts), tells whether one more cut would
    have converged (``retry``: ``"converged"`` or the stage it failed in). A retry that
    stopped at the iteration cap or stalled is run once more, same state and step, with
    :data:`LONG_SOLVE` iterations allowed and no progress test (``long_retry``, and
    ``long_retry_iterations`` when it converged): does Newton get there with more iterations.
    """
    import dolfinx

    from dolfinx_invertible import _compat
    from dolfinx_invertible.solvers.results import SolverError

    run = recorder.run
    dynamics = run.stepper
    minimizer = run.minimizer
    data: dict[str, Any] = {"attempt_iterations": max(len(recorder.norms) - 1, 0)}
    norms = recorder.norms
    if len(norms) > 1 and norms[0] > 0.0:
        data["residual_drop"] = norms[-1] / norms[0]
        recent = norms[-11:]
        data["residual_drop_last10"] = recent[-1] / recent[0] if recent[0] > 0.0 else None
    caps = recorder.caps
    if caps:
        data.update(
            cap_last=caps[-1], cap_min=min(caps), cap_median=float(sorted(caps)[len(caps) // 2])
        )
    state = dolfinx.fem.Function(run.u.function_space)
    if recorder.iterate is not None:
        recorder.iterate.copy(_compat.petsc_vector(state))
    state.x.scatter_forward()
    data.update(_state_diagnostics(state, material, minimizer))
    step = dynamics.controller.step
    data.update(retry_step=step, step_floor=dynamics.controller.minimum)
    remaining = run.parameters.t_end - dynamics.time
    try:
        dynamics.step(remaining)
        data["retry"] = "converged"
    except SolverError as error:
        data["retry"] = error.stage
    if data["retry"] in ("iteration cap", "stalled"):
        # Would Newton get there with more iterations? Same step, a larger cap, no progress test.
        cap, window = minimizer.max_iterations, minimizer.stall_window
        minimizer.max_iterations, minimizer.stall_window = LONG_SOLVE, None
        dynamics.controller.step = step
        try:
            data["long_retry_iterations"] = dynamics.step(remaining).newton_iterations
            data["long_retry"] = "converged"
        except SolverError as error:
            data["long_retry"] = error.stage
        finally:
            minimizer.max_iterations, minimizer.stall_window = cap, window
    return data


def overlapping_cells(u) -> int:
    """Count the cells whose deformed centroid lies inside another deformed cell (P1 simplices).

    Cells that share a vertex are not compared. A positive count means the body has passed
    through itself: an uninverted, locally injective configuration can still be tangled
    globally, and the elastic energy has no term against it. Only the centroids within a
    cell's reach (its farthest vertex from its own centroid) are tested against it, about a
    million pairs at a time, so time and memory follow the number of such pairs, not the
    square of the number of cells.
    """
    import numpy as np
    from scipy.spatial import cKDTree

    from dolfinx_invertible import _compat

    space = u.function_space
    d = space.mesh.geometry.dim
    cells = _compat.cell_dofs(space)[:, : d + 1]
    positions = space.tabulate_dof_coordinates()[:, :d] + u.x.array.reshape(-1, d)
    simplices = positions[cells]
    centroids = simplices.mean(axis=1)
    edges = np.transpose(simplices[:, 1:] - simplices[:, :1], (0, 2, 1))
    determinant = np.linalg.det(edges)
    usable = np.flatnonzero(np.abs(determinant) > 1e-14 * np.abs(edges).max() ** d)
    inverse = np.linalg.inv(edges[usable])
    reach = np.linalg.norm(simplices[usable] - centroids[usable, None, :], axis=2).max(axis=1)
    tree = cKDTree(centroids)
    pairs = np.asarray(tree.query_ball_point(centroids[usable], reach, return_length=True))
    offsets = np.concatenate([[0], np.cumsum(pairs)])
    covered = np.zeros(len(cells), dtype=bool)
    tolerance = 1e-9
    first = 0
    while first < len(usable):
        # About _OVERLAP_PAIRS pairs at a time bound the memory of a tangled body too.
        end = np.searchsorted(offsets, offsets[first] + _OVERLAP_PAIRS, side="right") - 1
        chunk = np.arange(first, max(first + 1, int(end)))
        first = chunk[-1] + 1
        if offsets[first] == offsets[chunk[0]]:
            continue
        near = tree.query_ball_point(centroids[usable[chunk]], reach[chunk])
        point = np.concatenate([np.asarray(indices, dtype=np.int64) for indices in near])
        container = np.repeat(chunk, pairs[chunk])
        cell = usable[container]
        barycentric = np.einsum(
            "kij,kj->ki", inverse[container], centroids[point] - simplices[cell, 0]
        )
        inside = (barycentric > tolerance).all(axis=1) & (barycentric.sum(axis=1) < 1 - tolerance)
        shared = (cells[cell][:, :, None] == cells[point][:, None, :]).any(axis=(1, 2))
        covered[point[inside & ~shared]] = True
    return int(np.count_nonzero(covered))


def inverted_energy_minimum(parameters) -> float | None:
    """Return min (Ψ(F) − Ψ(I))/μ over the inverted stretches F = diag(s, s, −s), s ≤ 100.

    A negative value means inverted states lie below the rest state, so a released body can
    fall into them and keep going. ``None`` for a material without energy (IFE) or one that
    is undefined there (plain Neo-Hookean).
    """
    import numpy as np

    from dolfinx_invertible.constitutive.material import NoEnergyError
    from dolfinx_invertible.scenes.parameters import make_material

    material = make_material(parameters)
    if material.positive_only:
        return None
    stretches = np.geomspace(0.05, 100.0, 41)
    F = np.zeros((len(stretches) + 1, 3, 3))
    F[:-1, 0, 0] = F[:-1, 1, 1] = stretches
    F[:-1, 2, 2] = -stretches
    F[-1] = np.eye(3)
    try:
        energy = material.energy(F)
    except NoEnergyError:
        return None
    return float(np.min(energy[:-1] - energy[-1]) / material.model.mu)


def _continue(run, cell: Cell) -> dict[str, Any]:
    """Continue a relaxation with long damped steps: is its end state trapped or just slow."""
    import numpy as np

    from dolfinx_invertible.fem.diagnostics import cell_diagnostics, summary
    from dolfinx_invertible.scenes.outcome import body_diameter, rest_distance
    from dolfinx_invertible.solvers.results import SolverError

    dynamics = run.stepper
    dynamics.controller.set_nominal(CONTINUATION_STEP * cell.time_unit)
    data: dict[str, Any] = {}
    previous = run.u.x.array.copy()
    diameter = body_diameter(run.u)

    def step_done(t: float, result) -> None:
        # How far the last step moved any node, and what it cost: an equilibrium moves by
        # nothing and takes no Newton iteration.
        motion = np.abs(run.u.x.array - previous).reshape(-1, run.mesh.geometry.dim)
        data["continued_last_motion"] = float(np.linalg.norm(motion, axis=1).max() / diameter)
        data["continued_last_newton"] = result.newton_iterations
        previous[:] = run.u.x.array

    try:
        dynamics.advance(dynamics.time + CONTINUATION_TIME * cell.time_unit, on_step=step_done)
        data["continued"] = "completed"
    except SolverError as error:
        data["continued"] = f"failed ({error.stage})"
    state = summary(cell_diagnostics(run.u, run.material), run.mesh.comm)
    # A minimum or a saddle: the exact tangent's curvature at the end state (the projected one
    # would hide a negative direction); the mass term of a 10 L/c step adds < 1e-3 of it.
    forms = getattr(dynamics.problem, "forms", None)
    if data["continued"] == "completed" and hasattr(forms, "set_projection"):
        forms.set_projection(False)
        curvature = _state_diagnostics(run.u, run.material, run.minimizer)
        data.update(
            continued_tangent_min=curvature.get("tangent_min"),
            continued_tangent_max=curvature.get("tangent_max"),
            continued_tangent_negative=curvature.get("tangent_negative"),
        )
    data.update(
        continued_inverted=state["inverted_cells"],
        continued_rest_distance=rest_distance(run.u),
        continued_time=dynamics.time / cell.time_unit,
        continued_overlap=overlapping_cells(run.u),
    )
    return data


def _parse_reason(message: str | None) -> tuple[str | None, str | None, float | None]:
    if not message:
        return None, None, None
    found = _REASON_PATTERN.search(message)
    step = _CUT_PATTERN.search(message)
    return (
        found.group("snes") if found else None,
        found.group("ksp") if found and found.group("ksp") else None,
        float(step.group("dt")) if step else None,
    )


def progress_record(cell: Cell, run) -> dict[str, Any]:
    """How far a cell's run got: time in the cell's time unit, steps, cuts, Newton iterations."""
    statistics = run.statistics
    return {
        "time_star": run.time / cell.time_unit,
        "t_end_star": run.parameters.t_end / cell.time_unit,
        "steps": statistics.steps,
        "failed_attempts": statistics.failed_attempts,
        "newton_total": statistics.newton_iterations["total"],
    }


def run_cell(
    cell: Cell, progress: Callable[[dict[str, Any]], None] | None = None
) -> dict[str, Any]:
    """Run one cell here (``MPI.COMM_SELF``) and return its record (CSV columns and more).

    ``progress``, if given, is called after every stored step with how far the run got
    (:func:`progress_record`).
    """
    from mpi4py import MPI

    from dolfinx_invertible.scenes import get_scene, run_scene
    from dolfinx_invertible.scenes.parameters import Parameters, make_material

    start = time.perf_counter()
    scene_class = get_scene(cell.scene)
    parameters = Parameters(**cell.parameters())
    method = METHODS_BY_NAME[cell.method]
    record: dict[str, Any] = {
        **cell.identity(),
        "t_end_star": parameters.t_end / cell.time_unit,
        "resolution": parameters.resolution,
        "damping": parameters.damping,
        "size": parameters.size,
        "density": parameters.density,
        "parameters": cell.parameters(),
    }
    comm = MPI.COMM_SELF
    if method.needs_positive_volume:
        inverted = _initial_inverted_cells(scene_class, parameters, comm)
        if inverted:
            record.update(
                outcome="does_not_apply",
                reason=f"starts with {inverted} inverted cells, where plain Neo-Hookean's "
                "energy is undefined (J <= 0)",
                initial_inverted=inverted,
                wall_time_s=time.perf_counter() - start,
            )
            record["cause"], record["cause_detail"] = diagnose(record)
            return record
    recorder = Recorder(
        on_step=None if progress is None else lambda run: progress(progress_record(cell, run))
    )
    summary = run_scene(scene_class, parameters, output=None, comm=comm, observers=[recorder])
    snes, ksp, failed_step = _parse_reason(summary.get("reason"))
    stepping = summary.get("stepping", {})
    kinetic = summary.get("kinetic_energy_final")
    energy_scale = cell.E * SIZE**3
    record.update(
        outcome=summary["outcome"],
        failed_stage=summary.get("failed_stage"),
        snes_reason=snes,
        ksp_reason=ksp,
        failed_time_star=(
            summary["failed_time"] / cell.time_unit if summary.get("failed_time") else None
        ),
        failed_step_star=failed_step / cell.time_unit if failed_step else None,
        reason=summary.get("reason"),
        steps=summary["steps"],
        cuts=stepping.get("cuts"),
        step_min_star=(stepping["step_min"] / cell.time_unit if stepping.get("step_min") else None),
        newton_total=summary["newton_iterations"]["total"],
        newton_max=summary["newton_iterations"]["max"],
        linear_total=summary["linear_iterations"],
        projected_total=recorder.projected,
        min_J_reached=summary.get("min_J_reached"),
        final_min_J=summary.get("final_min_J"),
        final_inverted=summary.get("final_inverted"),
        max_inverted=summary.get("max_inverted"),
        rest_distance=summary.get("rest_distance"),
        kinetic_final=kinetic / energy_scale if kinetic is not None else None,
        kinetic_max=recorder.kinetic_max / energy_scale,
        last_inverted_star=(
            recorder.last_inverted_time / cell.time_unit
            if recorder.last_inverted_time is not None
            else None
        ),
        nan=bool(summary.get("nan_encountered")),
        run_time_s=summary["wall_time_s"],
    )
    run = recorder.run
    record["inverted_energy_min"] = inverted_energy_minimum(parameters)
    if run is not None and run.scene.dynamic:
        if record["outcome"] in ("stalled_inverted", "not_at_rest", "failed"):
            record["overlap_cells"] = overlapping_cells(run.u)
            record["largest_singular_value"] = float(_point_singular_values(run.u)[1].max())
        if record["outcome"] == "failed":
            record.update(_failure_diagnostics(recorder, make_material(parameters)))
        elif record["outcome"] in ("stalled_inverted", "not_at_rest"):
            record.update(_continue(run, cell))
    record["wall_time_s"] = time.perf_counter() - start
    record["cause"], record["cause_detail"] = diagnose(record)
    return record
