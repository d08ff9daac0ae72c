"""Run a scene: build it, attach its outputs and observers, advance it, summarise it.

The output of a run in its directory (``results/SCENE/`` by default;
:mod:`dolfinx_invertible.scenes.outputs` writes it):

- ``SCENE.xdmf`` + ``SCENE.h5`` + ``SCENE.steps/``: the displacement and the per-cell diagnostics
  of every completed step (the XML, the mesh, one HDF5 file per step), readable while the run
  goes on and after it stops (also after SIGKILL, up to the last completed step);
- ``SCENE.jsonl``: one line per completed step (time, energy, iterations, inverted cells, ...);
- ``summary.json``: every parameter used and how the run went, written at the end, also after a
  failure or an interrupt (``completed`` false and the reason given), and while the run goes on
  the summary so far (``"running": true``, after every step and failed attempt); the previous
  run's summary is removed when a run starts, so a summary never belongs to another run
  (:mod:`.summary`);
- ``checkpoint.npz`` (with ``checkpoint_every``): the state to continue from
  (:mod:`.checkpoints`), and ``checkpoint-part-G-R-of-N.npz``, each rank's part of the state
  after each of the last two steps;
- scene-specific extras (e.g. ``trajectories.npy``).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from mpi4py import MPI

import dolfinx
import numpy as np

from dolfinx_invertible.choices import OUTPUT_FORMATS
from dolfinx_invertible.io.step_log import json_ready
from dolfinx_invertible.io.vtx import VTX_AVAILABLE
from dolfinx_invertible.scenes.build import build_run
from dolfinx_invertible.scenes.checkpoints import check_resumable, restore_run
from dolfinx_invertible.scenes.observer import RunObserver
from dolfinx_invertible.scenes.outputs import StepCallback, outputs
from dolfinx_invertible.scenes.parameters import Parameters
from dolfinx_invertible.scenes.run import Run
from dolfinx_invertible.scenes.scene import Scene
from dolfinx_invertible.scenes.signals import RunInterrupted, Signals
from dolfinx_invertible.scenes.summary import final_summary, summary_so_far
from dolfinx_invertible.solvers.results import SolverError

__all__ = ["RunInterrupted", "check_output_directory", "run_scene"]


def run_scene(
    scene_class: type[Scene],
    parameters: Parameters,
    *,
    output: str | os.PathLike | None = None,
    quiet: bool = True,
    petsc_options: dict[str, Any] | None = None,
    comm=MPI.COMM_WORLD,
    on_step: Callable[[Run], None] | None = None,
    observers: Sequence[RunObserver] = (),
    problem_options: dict[str, Any] | None = None,
    checkpoint_every: int | None = None,
    resume: bool = False,
    output_format: str = "xdmf",
) -> dict[str, Any]:
    """Run a scene; return its summary (written to ``output/summary.json`` too).

    ``parameters`` hold every value, the scene's defaults filled in (validated here, with the
    options, before anything is computed: ``ValueError``). ``output`` is the directory of the
    files, a path or a string (None writes nothing, as the reports do); ``quiet`` hides the
    progress bar; ``petsc_options`` are solver options without prefix; ``on_step(run)`` is
    called after every accepted step; ``observers`` (:class:`~dolfinx_invertible.scenes.observer.
    RunObserver`) watch the run from its start to its end, every Newton iteration included;
    ``problem_options`` override the scene's and the parameters' options of the problem (see
    :class:`~dolfinx_invertible.HyperelasticProblem`); ``checkpoint_every`` writes
    ``checkpoint.npz`` every this many steps and at the end (:mod:`.checkpoints`);
    ``resume`` continues the stopped run in ``output`` from its checkpoint (same scene and
    parameters; ``t_end`` may be later, ``max_cuts`` may change), appending to its files;
    ``output_format`` is a name of :data:`~dolfinx_invertible.choices.OUTPUT_FORMATS`.
    """
    output = None if output is None else Path(output)
    _check_options(scene_class, parameters, output, checkpoint_every, resume, output_format)
    if output is not None:
        check_output_directory(output, comm)
        if comm.rank == 0:
            (output / "summary.json").unlink(missing_ok=True)
    run = build_run(
        scene_class, parameters, comm, petsc_options=petsc_options, problem_options=problem_options
    )
    if resume:
        restore_run(run, output)
    else:
        run.store(None)
        run.scene.record(run)
    attached = outputs(
        run, output, output_format=output_format, checkpoint_every=checkpoint_every,
        progress=not quiet and comm.rank == 0,
    )  # fmt: skip
    attached += [StepCallback(on_step)] if on_step is not None else []
    _advance(run, [*attached, *observers], output)
    summary = json_ready(final_summary(run))
    if output is not None and comm.rank == 0:
        for name, data in run.scene.files(run).items():
            np.save(output / name, np.asarray(data))
        _write_json(output / "summary.json", summary)
    return summary


def _advance(run: Run, observers: list[RunObserver], output: Path | None) -> None:
    """Step the run to its end under the observers' watch; a failure ends it too.

    An interrupt (SIGINT, SIGTERM) writes the summary so far and is raised again. Until the
    run ends, ``summary.json`` holds the summary so far with ``"running": true``, rewritten
    after every step and every failed attempt: a run killed where it cannot write (SIGKILL, or
    a signal that arrives inside a long PETSc call and is followed by mpirun's kill) still
    leaves what it had done.
    """
    _watch(run, observers)
    try:
        with Signals() as signals:

            def progress() -> None:
                _write_summary_so_far(run, output, running=True)

            def attempt_done(attempt) -> None:
                if not attempt.accepted:
                    with signals.deferred():
                        progress()

            with signals.deferred():
                for observer in observers:
                    observer.start(run)
                progress()
            run.stepper.add_monitor(on_attempt=attempt_done)

            def step_done(t: float, result) -> None:
                # Counted and written as one: an interruption between the two would leave a
                # summary with one step more than the output.
                with signals.deferred():
                    run.store(result)
                    run.scene.record(run)
                    for observer in observers:
                        observer.step(run)
                    progress()

            try:
                run.stepper.advance(run.scene.end_time(run.parameters), on_step=step_done)
                run.completed = True
            except SolverError as error:
                run.failure = {
                    "reason": str(error),
                    "failed_stage": error.stage,
                    "failed_time": error.time_tried,
                }
                run.statistics.nan_encountered |= error.stage == "NaN"
            with signals.deferred():
                for observer in observers:
                    observer.end(run)
    except RunInterrupted as interrupt:
        _close(run, observers)
        # Ranks may be interrupted at different points: no collective operation from here on.
        _write_summary_so_far(run, output, reason=str(interrupt), interrupted=True)
        raise
    _close(run, observers)


def _write_summary_so_far(run: Run, output: Path | None, **marks: Any) -> None:
    """Write the summary so far with ``marks`` added, from rank 0 alone (nothing collective)."""
    if output is not None and run.mesh.comm.rank == 0:
        summary = summary_so_far(run)
        summary.update(marks)
        _write_json(output / "summary.json", json_ready(summary))


def _close(run: Run, observers: list[RunObserver]) -> None:
    for observer in observers:
        observer.close(run)


def _watch(run: Run, observers: list[RunObserver]) -> None:
    """Connect the run's count of attempts and the observers that watch the solver."""
    run.stepper.add_monitor(on_attempt=run.add_attempt)
    hooks = {}
    for name in ("iteration", "step_cap", "attempt"):
        watching = [
            o for o in observers if getattr(type(o), name) is not getattr(RunObserver, name)
        ]
        if watching:
            hooks[f"on_{name}"] = _dispatch(run, watching, name)
    if hooks:
        run.stepper.add_monitor(**hooks)


def _dispatch(run: Run, observers: list[RunObserver], name: str) -> Callable[[Any], None]:
    def call(record) -> None:
        for observer in observers:
            getattr(observer, name)(run, record)

    return call


def _check_options(
    scene_class: type[Scene],
    parameters: Parameters,
    output: Path | None,
    checkpoint_every: int | None,
    resume: bool,
    output_format: str,
) -> None:
    """Raise ``ValueError`` for options that cannot run, before anything is built."""
    parameters.validate()
    scene_class.check_parameters(parameters)
    if checkpoint_every is not None and (
        int(checkpoint_every) != checkpoint_every or checkpoint_every < 1
    ):
        raise ValueError(f"--checkpoint-every must be an integer >= 1, got {checkpoint_every!r}")
    OUTPUT_FORMATS.check(output_format, command_line=True)
    if output_format != "xdmf" and not VTX_AVAILABLE:
        raise ValueError(
            f"--format {output_format}: VTX output needs DOLFINx built with ADIOS2, and "
            f"DOLFINx {dolfinx.__version__} here is not: use --format xdmf"
        )
    if resume:
        if output_format != "xdmf":
            raise ValueError(
                "--resume continues the XDMF series and the step log; VTX files are not "
                "appended to: use --format xdmf"
            )
        if output is None:
            raise ValueError("--resume needs the output directory of the run")
        check_resumable(output, scene_class, parameters)


def check_output_directory(path: Path, comm) -> None:
    """Create ``path`` and make sure files can be written there; clear error otherwise."""
    error = None
    if comm.rank == 0:
        try:
            path.mkdir(parents=True, exist_ok=True)
            probe = path / ".write-test"
            probe.write_text("")
            probe.unlink()
        except OSError as exception:
            error = (
                f"cannot write to the output directory {path}: {exception.strerror or exception}"
            )
    error = comm.bcast(error, root=0)
    if error is not None:
        raise ValueError(error)


def _write_json(path: Path, data: dict) -> None:
    temporary = path.with_name(f".{path.name}.tmp")
    temporary.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n")
    os.replace(temporary, path)
