"""Checkpoints of a scene run, and continuing a stopped run from its last one.

A dynamic scene's run writes ``checkpoint.npz`` into its output directory every N steps and
after its last step (:func:`write_run_checkpoint`): the displacement and velocity of the current
and the previous step (BDF2 needs both), the time, the step controller's state, whether the
solver escalated, the run's counts, the scene's own scalar state (contact statistics, say),
the parameters and the number of steps written. ``run SCENE --resume DIR`` builds the same run,
reads the checkpoint into it (:func:`restore_run`, on any number of ranks), truncates the XDMF
file and the step log to the checkpoint's step and goes on from there.
"""

from __future__ import annotations

from pathlib import Path
from time import perf_counter
from typing import Any

from dolfinx_invertible.io.checkpoint import read_checkpoint, read_state, write_checkpoint
from dolfinx_invertible.scenes.parameters import Parameters
from dolfinx_invertible.scenes.run import Run

__all__ = [
    "CHECKPOINT_NAME",
    "check_resumable",
    "restore_run",
    "write_run_checkpoint",
]

#: The checkpoint's file name in a run's output directory.
CHECKPOINT_NAME = "checkpoint.npz"
#: Version of the state layout; a checkpoint of another version is refused.
_VERSION = 1
_COUNTS = ("steps", "newton_total", "newton_max", "linear_total", "max_inverted", "min_J",
           "nan_encountered", "svd_points", "time")  # fmt: skip


def _scene_state(scene) -> dict[str, Any]:
    """Return the scene's scalar attributes: what its hooks accumulate over the steps."""
    return {
        name: value
        for name, value in vars(scene).items()
        if isinstance(value, (bool, int, float, str)) and name not in ("comm",)
    }


def write_run_checkpoint(run: Run, output: Path, steps_written: int) -> int:
    """Write the run's checkpoint into ``output`` (collective); return its size in bytes."""
    state = {
        "version": _VERSION,
        "scene": run.scene.name,
        "parameters": run.parameters.as_dict(),
        "ranks": run.mesh.comm.size,
        "steps_written": steps_written,
        "dynamics": run.dynamics.checkpoint_state(),
        "run": {name: getattr(run, name) for name in _COUNTS},
        "elapsed": perf_counter() - run.started,
        "scene_state": _scene_state(run.scene),
    }
    return write_checkpoint(
        output / CHECKPOINT_NAME, run.dynamics.checkpoint_fields(), state, run.mesh.comm
    )


def check_resumable(output: Path, scene_name: str, parameters: Parameters) -> dict[str, Any]:
    """Return the state of the checkpoint in ``output``; ``ValueError`` if it cannot continue.

    The run must be the same scene with the same parameters, except ``t_end``, which may grow.
    """
    state = read_state(output / CHECKPOINT_NAME)
    if state.get("version") != _VERSION:
        raise ValueError(f"{output / CHECKPOINT_NAME}: a checkpoint of another version")
    if state["scene"] != scene_name:
        raise ValueError(f"{output} holds a run of the {state['scene']} scene, not of {scene_name}")
    given = parameters.as_dict()
    differing = [
        name
        for name, value in state["parameters"].items()
        if name != "t_end" and given.get(name) != value
    ]
    if differing:
        raise ValueError(
            f"--resume continues {output} with its own parameters; these differ: "
            + ", ".join(
                f"{name} {given.get(name)!r} (run: {state['parameters'][name]!r})"
                for name in differing
            )  # fmt: skip
        )
    if not parameters.t_end > state["dynamics"]["time"]:
        raise ValueError(
            f"--t-end {parameters.t_end:g}: the run in {output} is at t = "
            f"{state['dynamics']['time']:g} already"
        )
    return state


def restore_run(run: Run, output: Path) -> dict[str, Any]:
    """Set the built run to its checkpoint in ``output`` (collective); return the state."""
    state = read_checkpoint(
        output / CHECKPOINT_NAME, run.dynamics.checkpoint_fields(), run.mesh.comm
    )
    run.dynamics.restore(state["dynamics"])
    for name in _COUNTS:
        setattr(run, name, state["run"][name])
    run.started = perf_counter() - state["elapsed"]
    for name, value in state["scene_state"].items():
        setattr(run.scene, name, value)
    return state
