"""Checkpoints of a scene run, and continuing a stopped run from its last one.

A scene's run writes ``checkpoint.npz`` into its output directory every N steps and after its
last step (:func:`write_run_checkpoint`, attached as
:class:`~dolfinx_invertible.scenes.outputs.CheckpointOutput`). The state is assembled from the
run's parts, each giving its own: the stepper's Functions and state (the integrator's history
of a dynamic scene, the last converged solution of load steps; the time, the step controller,
whether the solver escalated), the run's statistics, the scene's own
(:meth:`~dolfinx_invertible.scenes.Scene.checkpoint_state`) and each stateful term's
(:meth:`~dolfinx_invertible.solvers.terms.StatefulTerm.checkpoint_state`), with the parameters
and the number of states stored. ``run SCENE --resume DIR`` builds the same run, reads the
checkpoint into it (:func:`restore_run`, on any number of ranks), truncates the XDMF file and
the step log to the checkpoint's step and goes on from there. After every step each rank also
writes its part of the state, with no communication (:class:`StepParts`), so a run killed at
any instant, or stopped by a signal, continues from its last completed step; resuming takes
whichever is newer (:func:`latest_checkpoint`).
"""

from __future__ import annotations

import re
from pathlib import Path
from time import perf_counter
from typing import Any

from dolfinx_invertible.io.checkpoint import (
    CheckpointError,
    owned_nodes,
    read_checkpoint,
    read_state,
    write_checkpoint,
    write_checkpoint_part,
)
from dolfinx_invertible.scenes.parameters import Parameters
from dolfinx_invertible.scenes.run import Run
from dolfinx_invertible.scenes.statistics import RunStatistics

__all__ = [
    "CHECKPOINT_NAME",
    "StepParts",
    "check_resumable",
    "latest_checkpoint",
    "restore_run",
    "write_run_checkpoint",
]

#: The checkpoint's file name in a run's output directory.
CHECKPOINT_NAME = "checkpoint.npz"
#: Version of the state layout; a checkpoint of another version is refused.
_VERSION = 2


def _run_state(run: Run) -> dict[str, Any]:
    return {
        "version": _VERSION,
        "scene": run.scene.name,
        "parameters": run.parameters.as_dict(),
        "ranks": run.mesh.comm.size,
        "steps_written": run.stored,
        "stepper": run.stepper.checkpoint_state(),
        "statistics": run.statistics.state(),
        "elapsed": perf_counter() - run.started,
        "scene_state": run.scene.checkpoint_state(),
        "terms": [term.checkpoint_state() for term in run.terms],
    }


def write_run_checkpoint(run: Run, output: Path) -> int:
    """Write the run's checkpoint into ``output`` (collective); return its size in bytes."""
    return write_checkpoint(
        output / CHECKPOINT_NAME, run.stepper.checkpoint_fields(), _run_state(run), run.mesh.comm
    )


class StepParts:
    """Each rank's part of the run's state after every step, with no communication.

    A kill (SIGKILL, a lost node, a scheduler's time limit) or a signal can reach the ranks at
    different points, even inside a collective call, where nothing collective can follow; so
    after every completed step each rank writes its own share of the state (the four fields'
    owned nodes, the state as JSON) to a file of its own. Two generations alternate (even and
    odd steps): the ranks pass a collective call in every step, so when one rank writes step
    k + 1, every rank has written step k, and one generation is always complete. Not synced to
    disk (the operating system writes it out; only a crash of the machine loses it): the cost
    is writing the fields, about 0.02 s a step at 10⁵ cells (``benchmarks/checkpoint.py``).
    """

    def __init__(self, output: Path, rank: int, size: int) -> None:
        self.output, self.rank, self.size = output, rank, size
        self._coordinates: dict[str, Any] = {}

    def write(self, run: Run) -> None:
        """Write this rank's part of the state after the step (at a step boundary)."""
        nodes = {}
        for name, function in run.stepper.checkpoint_fields().items():
            if name not in self._coordinates:
                # The nodes do not move: tabulated once, not at every step.
                self._coordinates[name] = owned_nodes(function)[0].copy()
            coordinates = self._coordinates[name]
            block = function.function_space.dofmap.index_map_bs
            values = function.x.array[: len(coordinates) * block].reshape(-1, block)
            nodes[name] = (coordinates, values)
        path = self.output / _part_name(self.rank, self.size, run.stored % 2)
        write_checkpoint_part(path, nodes, _run_state(run), sync=False)


def _part_name(rank: int, size: int, generation: int) -> str:
    return f"checkpoint-part-{generation}-{rank}-of-{size}.npz"


_PART = re.compile(r"checkpoint-part-(?P<generation>[01])-(?P<rank>\d+)-of-(?P<size>\d+)\.npz")


def latest_checkpoint(output: Path) -> tuple[list[Path], dict[str, Any]]:
    """Return the files and the state of the newest complete checkpoint in ``output``.

    The whole checkpoint, or a generation of the ranks' parts (:class:`StepParts`) if every
    rank's part is there with the same step and it is newer. ``CheckpointError`` if there is
    none.
    """
    candidates = []
    whole = output / CHECKPOINT_NAME
    if whole.exists():
        candidates.append(([whole], read_state(whole)))
    # Parts of an earlier run on another number of ranks may be there too: every generation
    # of every rank count is a candidate.
    groups = set()
    for path in output.glob("checkpoint-part-*.npz"):
        match = _PART.fullmatch(path.name)
        if match is not None:
            groups.add((int(match["generation"]), int(match["size"])))
    for generation, size in sorted(groups):
        expected = [output / _part_name(rank, size, generation) for rank in range(size)]
        if not all(path.exists() for path in expected):
            continue
        try:
            states = [read_state(path) for path in expected]
        except CheckpointError:  # a part the kill left half-written: the other generation
            continue
        if all(state["steps_written"] == states[0]["steps_written"] for state in states):
            candidates.append((expected, states[0]))
    if not candidates:
        return [whole], read_state(whole)  # raises: no checkpoint at ...
    return max(candidates, key=lambda candidate: candidate[1]["steps_written"])


#: Parameters a resumed run may give new values: where it stops and how far it may cut a step.
MAY_CHANGE_ON_RESUME = ("t_end", "t_stop", "max_cuts")


def check_resumable(output: Path, scene_class, parameters: Parameters) -> dict[str, Any]:
    """Return the state of the checkpoint in ``output``; ``ValueError`` if it cannot continue.

    The run must be the same scene with the same parameters, except where it stops: ``t_end``
    may grow (unless the scene's loading is ``timed_by_end``), and ``t_stop`` may change; so may
    ``max_cuts``, to continue a run whose cuts ran out with a larger budget.
    """
    scene_name = scene_class.name
    _, state = latest_checkpoint(output)
    if state.get("version") != _VERSION:
        raise ValueError(f"{output / CHECKPOINT_NAME}: a checkpoint of another version")
    if state["scene"] != scene_name:
        raise ValueError(f"{output} holds a run of the {state['scene']} scene, not of {scene_name}")
    given = parameters.as_dict()
    differing = [
        name
        for name, value in state["parameters"].items()
        if name not in MAY_CHANGE_ON_RESUME and given.get(name) != value
    ]
    if differing:
        raise ValueError(
            f"--resume continues {output} with its own parameters; these differ: "
            + ", ".join(
                f"{name} {given.get(name)!r} (run: {state['parameters'][name]!r})"
                for name in differing
            )  # fmt: skip
        )
    if scene_class.timed_by_end and parameters.t_end != state["parameters"]["t_end"]:
        raise ValueError(
            f"--t-end {parameters.t_end:g}: the {scene_name} scene's loading is timed by the end "
            f"time of its run ({state['parameters']['t_end']:g} s), which a resumed run keeps"
        )
    end, reached = scene_class.end_time(parameters), state["stepper"]["time"]
    if not end > reached:
        raise ValueError(
            f"stopping at t = {end:g} (--t-end, --steps): the run in {output} is at "
            f"t = {reached:g} already"
        )
    return state


def restore_run(run: Run, output: Path) -> dict[str, Any]:
    """Set the built run to its checkpoint in ``output`` (collective); return the state."""
    files, _ = latest_checkpoint(output)
    state = read_checkpoint(files, run.stepper.checkpoint_fields(), run.mesh.comm)
    run.stepper.restore(state["stepper"])
    run.statistics = RunStatistics.from_state(state["statistics"])
    run.stored = int(state["steps_written"])
    run.resumed = True
    run.started = perf_counter() - state["elapsed"]
    run.scene.restore(state["scene_state"])
    for term, term_state in zip(run.terms, state["terms"], strict=True):
        term.restore(term_state)
    return state
