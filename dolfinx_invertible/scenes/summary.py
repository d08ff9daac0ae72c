"""The summary of a scene run: every parameter, what the run counted, how it ended.

``summary.json`` holds the scene and its material, the parameters, what the ``"auto"`` solver
choices became, the ranks and unknowns, the run's statistics
(:class:`~dolfinx_invertible.scenes.statistics.RunStatistics`), the final state's diagnostics,
the step controller's statistics, the stateful terms' figures, the outcome (a relaxation's:
``recovered``, ``rest_distance``, ...; a failure's: ``reason``, ``failed_stage``,
``failed_time``, and the failed attempts of the step that did not pass,
``unfinished_step_attempts``), and the scene's own quantities.
"""

from __future__ import annotations

from time import perf_counter
from typing import Any

from dolfinx_invertible.scenes.outcome import relaxation_outcome, rest_distance
from dolfinx_invertible.scenes.run import Run

__all__ = ["final_summary", "summary_so_far"]


def summary_so_far(run: Run, *, final: dict[str, Any] | None = None) -> dict[str, Any]:
    """Return the summary's common part; ``final``: the final state's global diagnostics.

    Without ``final`` (an interrupted run) the last stored state's diagnostics stand in, and
    nothing collective is done.
    """
    parameters = run.parameters
    space = run.u.function_space
    last = final if final is not None else run.diagnostics
    minimizer = run.minimizer
    statistics = run.statistics.summary()
    statistics["max_inverted"] = max(statistics["max_inverted"], last.get("inverted_cells", 0) or 0)
    summary = {
        "scene": run.scene.name,
        "model": parameters.model,
        "extension": parameters.extension,
        "parameters": parameters.as_dict(),
        # What the "auto" choices of the parameters became.
        "solver": {
            "linear_solver": minimizer.linear_solver,
            "globalization": minimizer.globalization,
        },
        "ranks": run.mesh.comm.size,
        "dofs": space.dofmap.index_map.size_global * space.dofmap.index_map_bs,
        "time": run.time,
        "completed": run.completed,
        "converged": not run.failure,
        "final_min_J": last.get("min_J"),
        "final_inverted": last.get("inverted_cells"),
        **statistics,
        "wall_time_s": perf_counter() - run.started,
        "stepping": run.controller.statistics(),
    }
    for term in run.terms:
        summary.update(term.summary_quantities())
    summary.update(run.failure)
    if run.failed_attempts:
        # The attempts of the step that did not pass: no stored state's record holds them.
        summary["unfinished_step_attempts"] = list(run.failed_attempts)
    return summary


def final_summary(run: Run) -> dict[str, Any]:
    """Return the whole summary of a run that ended, completed or failed (collective)."""
    from dolfinx_invertible.fem.diagnostics import cell_diagnostics, summary

    final = summary(cell_diagnostics(run.u, run.material), run.mesh.comm)
    result = summary_so_far(run, final=final)
    failed_stage = run.failure.get("failed_stage")
    if run.scene.relaxation:
        distance = rest_distance(run.u)
        outcome = relaxation_outcome(run.completed, failed_stage, final["inverted_cells"], distance)
        result.update(
            rest_distance=distance,
            recovered=outcome == "recovered",
            outcome=outcome,
            kinetic_energy_final=run.kinetic_energy,
        )
    elif run.completed:
        result["outcome"] = "completed"
    else:
        result["outcome"] = "nan" if failed_stage == "NaN" else "failed"
    result.update(run.scene.quantities(run))
    return result
