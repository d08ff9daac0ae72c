"""What a scene run writes, each output an observer of the run (:class:`RunObserver`).

The runner attaches them from its options (:func:`outputs`), before the caller's observers:

- :class:`XDMFOutput`: the displacement and the per-cell diagnostics of every stored state in
  one XDMF series (:class:`~dolfinx_invertible.io.xdmf.ResultWriter`);
- :class:`VTXOutput`: the same as ADIOS2 VTX files
  (:class:`~dolfinx_invertible.io.vtx.VTXResultWriter`);
- :class:`StepLogOutput`: the JSON-lines step log, one line per stored state (``run.record``);
- :class:`CheckpointOutput`: the state to continue from (:mod:`.checkpoints`);
- :class:`ProgressBar`: a progress bar on rank 0.

Adding an output is a class here with the hooks it needs, and a line in :func:`outputs`. A
fresh run's outputs write the initial state in :meth:`~RunObserver.start`; a continued run's
(``run.resumed``) append to what the first run wrote.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from dolfinx_invertible.io.step_log import StepLog
from dolfinx_invertible.scenes.checkpoints import StepParts, write_run_checkpoint
from dolfinx_invertible.scenes.observer import RunObserver
from dolfinx_invertible.scenes.run import Run

__all__ = [
    "CheckpointOutput",
    "ProgressBar",
    "StepCallback",
    "StepLogOutput",
    "VTXOutput",
    "XDMFOutput",
    "outputs",
]


class _Writer(RunObserver):
    """An output that writes every stored state with a writer made at the start."""

    def __init__(self) -> None:
        self.writer = None

    def _open(self, run: Run) -> Any:
        raise NotImplementedError

    def start(self, run: Run) -> None:
        """Open the files; write the initial state of a fresh run."""
        self.writer = self._open(run)
        if not run.resumed:
            self.step(run)

    def step(self, run: Run) -> None:
        """Write the state just stored."""
        self.writer.write(run.time, run.u, run.cell_values)

    def close(self, run: Run) -> None:
        """Close the files."""
        if self.writer is not None:
            self.writer.close()


class XDMFOutput(_Writer):
    """``SCENE.xdmf`` (+ ``SCENE.h5``, ``SCENE.steps/``): ParaView's XDMF3 series."""

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.path = path

    def _open(self, run: Run) -> Any:
        from dolfinx_invertible.io.xdmf import ResultWriter

        # A continued run drops what its first run wrote after the checkpoint.
        resume = (run.stored, run.time) if run.resumed else None
        return ResultWriter(self.path, run.mesh, resume=resume, log=False)


class VTXOutput(_Writer):
    """``SCENE.bp`` and ``SCENE-cells.bp``: the displacement at full order (ADIOS2)."""

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.path = path

    def _open(self, run: Run) -> Any:
        from dolfinx_invertible.io.vtx import VTXResultWriter

        return VTXResultWriter(self.path, run.u)


class StepLogOutput(RunObserver):
    """``SCENE.jsonl``: one JSON line per stored state, ``step`` and ``time`` first."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.log: StepLog | None = None

    def start(self, run: Run) -> None:
        """Open the log (a continued run keeps its first ``run.stored`` lines)."""
        keep = run.stored if run.resumed else None
        self.log = StepLog(self.path, run.mesh.comm, keep=keep)
        if not run.resumed:
            self.step(run)

    def step(self, run: Run) -> None:
        """Append the record of the state just stored."""
        self.log.append(StepLog.format(run.stored - 1, run.time, run.record))

    def close(self, run: Run) -> None:
        """Close the log."""
        if self.log is not None:
            self.log.close()


class CheckpointOutput(RunObserver):
    """``checkpoint.npz`` every ``every`` steps and at the end; each rank's part every step."""

    def __init__(self, output: Path, every: int) -> None:
        self.output, self.every = output, every
        self.parts: StepParts | None = None

    def start(self, run: Run) -> None:
        """Prepare the ranks' parts."""
        comm = run.mesh.comm
        self.parts = StepParts(self.output, comm.rank, comm.size)

    def step(self, run: Run) -> None:
        """Write the whole checkpoint every ``every`` steps, this rank's part every step."""
        if run.statistics.steps % self.every == 0:
            write_run_checkpoint(run, self.output)
        self.parts.write(run)

    def end(self, run: Run) -> None:
        """Write the last state unless the last step wrote it (also after a failed step).

        After a failure the state is the last completed step's (or the initial one) and the
        step controller's cuts so far: ``--resume`` continues the cuts from there.
        """
        steps = run.statistics.steps
        if steps % self.every != 0 or steps == 0:
            write_run_checkpoint(run, self.output)


class ProgressBar(RunObserver):
    """A tqdm progress bar on rank 0: the time (or load) reached, Newton and inverted cells."""

    def __init__(self, total: float, unit: str) -> None:
        self.total, self.unit = total, unit
        self.bar = None

    def start(self, run: Run) -> None:
        """Show the bar on rank 0."""
        if run.mesh.comm.rank != 0:
            return
        from tqdm import tqdm

        self.bar = tqdm(
            total=self.total, unit=self.unit, dynamic_ncols=True, leave=True, initial=run.time,
            bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} {unit} [{elapsed}<{remaining}] "
            "{postfix}",
        )  # fmt: skip

    def step(self, run: Run) -> None:
        """Move the bar to the time reached."""
        if self.bar is not None:
            self.bar.update(run.time - self.bar.n)
            self.bar.set_postfix(
                {
                    "newton": run.result.newton_iterations,
                    "inverted": run.diagnostics["inverted_cells"],
                },
                refresh=False,
            )

    def close(self, run: Run) -> None:
        """Close the bar."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None


class StepCallback(RunObserver):
    """Calls ``on_step(run)`` after every accepted step (``run_scene(on_step=...)``)."""

    def __init__(self, on_step: Callable[[Run], None]) -> None:
        self.on_step = on_step

    def step(self, run: Run) -> None:
        """Call the function."""
        self.on_step(run)


def outputs(
    run: Run,
    output: Path | None,
    *,
    output_format: str = "xdmf",
    checkpoint_every: int | None = None,
    progress: bool = False,
) -> list[RunObserver]:
    """Return the outputs a run's options ask for, in the order they write each state.

    Files only with an ``output`` directory: the series (``output_format``), the step log and,
    with ``checkpoint_every``, the checkpoints; the progress bar where ``progress`` is true.
    """
    attached: list[RunObserver] = []
    if output is not None:
        name = run.scene.name
        if output_format in ("xdmf", "both"):
            attached.append(XDMFOutput(output / f"{name}.xdmf"))
        if output_format in ("vtx", "both"):
            attached.append(VTXOutput(output / f"{name}.bp"))
        attached.append(StepLogOutput(output / f"{name}.jsonl"))
        if checkpoint_every is not None:
            attached.append(CheckpointOutput(output, checkpoint_every))
    if progress:
        dynamic = run.scene.dynamic
        attached.append(ProgressBar(run.scene.end_time(run.parameters), "s" if dynamic else "load"))
    return attached
