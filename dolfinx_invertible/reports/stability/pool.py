"""A pool of worker processes that run cells, each a fresh interpreter.

The parent has initialised MPI, so the workers are not forked: each is
``python -m dolfinx_invertible.reports.stability --worker``, which reads cells from its stdin
(one JSON line each) and writes each record as one line on its stdout.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import pathlib
import queue
import select
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import dolfinx_invertible
from dolfinx_invertible.reports.stability.diagnosis import diagnose
from dolfinx_invertible.reports.stability.runner import run_cell
from dolfinx_invertible.reports.stability.study import Cell

__all__ = ["CELL_TIMEOUT", "run_cells", "run_worker"]

#: Wall-clock limit of one cell [s]; a cell over it is stopped and reported.
CELL_TIMEOUT = 900.0

_RESULT = "STABILITY-CELL "
_PROGRESS = "STABILITY-PROGRESS "


def _worker_command() -> list[str]:
    return [sys.executable, "-m", "dolfinx_invertible.reports.stability", "--worker"]


class _Worker:
    """A child interpreter that runs cells sent on its stdin, one JSON line each."""

    def __init__(self, log: pathlib.Path):
        self.log_path = log
        self.log = open(log, "ab")  # noqa: SIM115 (closed in close())
        environment = dict(os.environ)
        # One thread per process: the pool is the parallelism.
        environment.setdefault("OMP_NUM_THREADS", "1")
        environment.setdefault("OPENBLAS_NUM_THREADS", "1")
        environment.setdefault("NUMBA_NUM_THREADS", "1")
        package_root = str(pathlib.Path(dolfinx_invertible.__file__).resolve().parents[1])
        environment["PYTHONPATH"] = os.pathsep.join(
            [package_root, *filter(None, [environment.get("PYTHONPATH")])]
        )
        self.process = subprocess.Popen(
            _worker_command(),
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self.log,
            env=environment,
        )
        self._buffer = b""
        #: How far the current cell got (its last progress line), reset for every cell.
        self.progress: dict[str, Any] | None = None

    def send(self, cell: Cell) -> None:
        self.progress = None
        self.process.stdin.write((json.dumps(dataclasses.asdict(cell)) + "\n").encode())
        self.process.stdin.flush()

    def receive(self, timeout: float) -> dict[str, Any] | None:
        """Return the next result, or ``None`` on timeout or when the worker died."""
        deadline = time.monotonic() + timeout
        stream = self.process.stdout.fileno()
        while True:
            while b"\n" in self._buffer:
                line, self._buffer = self._buffer.split(b"\n", 1)
                text = line.decode(errors="replace")
                if text.startswith(_RESULT):
                    return json.loads(text[len(_RESULT) :])
                if text.startswith(_PROGRESS):
                    self.progress = json.loads(text[len(_PROGRESS) :])
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            ready, _, _ = select.select([stream], [], [], min(remaining, 5.0))
            if ready:
                chunk = os.read(stream, 1 << 16)
                if not chunk:
                    return None
                self._buffer += chunk

    def tail(self) -> str:
        self.log.flush()
        with contextlib.suppress(OSError):
            return self.log_path.read_bytes()[-2000:].decode(errors="replace").strip()
        return ""

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.process.stdin.close()
        try:
            self.process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self.log.close()

    def kill(self) -> None:
        self.process.kill()
        self.process.wait()
        self.log.close()


def _expected_cost(cell: Cell) -> float:
    """Relative cost of a cell (steps × cells of the mesh), to start the longest first."""
    parameters = cell.parameters()
    steps = parameters["t_end"] / cell.dt
    cells = {"collapse": 1.0, "scatter": 1.0, "compress-block": 4.0, "stretch-bar": 5.0}
    resolution = parameters["resolution"] / 4.0
    return steps * cells[cell.scene] * resolution**3


def run_cells(
    cells: Sequence[Cell],
    *,
    workers: int = 2,
    timeout: float = CELL_TIMEOUT,
    log_directory: pathlib.Path,
    on_result: Callable[[dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """Run cells in a pool of worker processes; return their records in the cells' order.

    A worker that dies or exceeds ``timeout`` on a cell is replaced, and the cell is recorded
    with the outcome ``crashed`` or ``timeout``.
    """
    order = sorted(range(len(cells)), key=lambda index: -_expected_cost(cells[index]))
    tasks: queue.Queue[int] = queue.Queue()
    for index in order:
        tasks.put(index)
    results: list[dict[str, Any] | None] = [None] * len(cells)
    lock = threading.Lock()
    errors: list[BaseException] = []
    live: set[_Worker] = set()
    stopping = threading.Event()

    def serve(number: int) -> None:
        log = log_directory / f"worker-{number}.log"
        worker = None
        try:
            while not stopping.is_set():
                try:
                    index = tasks.get_nowait()
                except queue.Empty:
                    break
                cell = cells[index]
                if worker is None:
                    worker = _Worker(log)
                    with lock:
                        live.add(worker)
                worker.send(cell)
                result = worker.receive(timeout)
                if stopping.is_set():
                    break
                if result is None:
                    worker_progress = worker.progress
                    alive = worker.process.poll() is None
                    tail = worker.tail()
                    with lock:
                        live.discard(worker)
                    worker.kill()
                    worker = None
                    outcome = "timeout" if alive else "crashed"
                    result = _lost_cell(cell, outcome, timeout, tail, worker_progress)
                with lock:
                    results[index] = result
                    if on_result is not None:
                        on_result(result)
        except BaseException as error:  # reported by the caller's thread
            errors.append(error)
        finally:
            if worker is not None and not stopping.is_set():
                with lock:
                    live.discard(worker)
                worker.close()

    threads = [
        threading.Thread(target=serve, args=(number,), daemon=True)
        for number in range(max(1, min(workers, len(cells))))
    ]
    for thread in threads:
        thread.start()
    try:
        for thread in threads:
            while thread.is_alive():
                thread.join(timeout=1.0)
    except BaseException:
        # Interrupted: stop the workers rather than leave them running their cells.
        stopping.set()
        with lock:
            for worker in list(live):
                with contextlib.suppress(OSError, ValueError):
                    worker.kill()
            live.clear()
        raise
    if errors:
        raise errors[0]
    return [result for result in results if result is not None]


def _lost_cell(
    cell: Cell,
    outcome: str,
    timeout: float,
    tail: str,
    progress: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Return the record of a cell whose worker timed out or died (how far it got, if known)."""
    reason = (
        f"the cell ran longer than {timeout:.0f} s and was stopped"
        if outcome == "timeout"
        else "the worker process died: " + (tail.splitlines()[-1] if tail else "no output")
    )
    record = {**cell.identity(), "outcome": outcome, "reason": reason}
    if progress:
        record.update(
            steps=progress["steps"],
            newton_total=progress["newton_total"],
            time_reached_star=progress["time_star"],
        )
        reached, end = progress["time_star"], progress["t_end_star"]
        record["reason"] = (
            f"{reason}, at t = {reached:.3g} L/c of {end:.3g} after {progress['steps']} steps, "
            f"{progress['failed_attempts']} failed attempts and {progress['newton_total']} "
            "Newton iterations"
        )
    elif outcome == "timeout":
        record["reason"] = f"{reason} before its first step"
    record["cause"], record["cause_detail"] = diagnose(record)
    return record


def run_worker() -> int:
    """Run cells read from stdin (one JSON line each); write each record as one line."""
    import logging
    import warnings

    from mpi4py import MPI  # noqa: F401 (initialised before DOLFINx)

    from dolfinx_invertible.io.step_log import json_ready
    from dolfinx_invertible.scenes.runner import RunInterrupted

    for name in ("ffcx", "UFL", "dolfinx", "numba"):
        logging.getLogger(name).setLevel(logging.WARNING)
    warnings.simplefilter("ignore")
    output = sys.stdout
    # Anything the libraries print goes to the log, not into the results.
    sys.stdout = sys.stderr
    for line in sys.stdin:
        if not line.strip():
            continue
        cell = Cell(**json.loads(line))

        def report(progress: dict[str, Any]) -> None:
            output.write(_PROGRESS + json.dumps(json_ready(progress)) + "\n")
            output.flush()

        try:
            record = run_cell(cell, progress=report)
        except RunInterrupted:
            return 1
        except Exception as error:  # a defect: reported as the cell's outcome, not hidden
            import traceback

            traceback.print_exc()
            record = _lost_cell(cell, "crashed", 0.0, f"{type(error).__name__}: {error}")
        output.write(_RESULT + json.dumps(json_ready(record)) + "\n")
        output.flush()
    return 0
