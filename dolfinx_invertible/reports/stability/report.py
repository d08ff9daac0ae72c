"""Run the stability study and write its files."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import pathlib
import time
from collections import Counter
from collections.abc import Sequence
from typing import Any

from dolfinx_invertible.reports.stability.diagnosis import diagnose
from dolfinx_invertible.reports.stability.outputs import (
    display_outcome,
    plot_heat_map,
    summary_lines,
    write_csv,
)
from dolfinx_invertible.reports.stability.pool import CELL_TIMEOUT, run_cells
from dolfinx_invertible.reports.stability.study import (
    METHODS_BY_NAME,
    POISSON_RATIOS,
    SCENES,
    TIME_STEPS,
    YOUNGS_MODULI,
    matrix,
    method_label,
)

__all__ = ["check_options", "run"]


def _axes(
    poisson_ratios: Sequence[float] | None,
    youngs_moduli: Sequence[float] | None,
    time_steps: Sequence[float] | None,
) -> tuple[tuple[str, Sequence[float] | None, tuple[float, ...]], ...]:
    """Each axis a value may be chosen on: its cell attribute, the chosen values, the axis."""
    return (
        ("nu", poisson_ratios, POISSON_RATIOS),
        ("E", youngs_moduli, YOUNGS_MODULI),
        ("dt", time_steps, TIME_STEPS),
    )


def check_options(
    *,
    scenes: Sequence[str] | None = None,
    methods: Sequence[str] | None = None,
    poisson_ratios: Sequence[float] | None = None,
    youngs_moduli: Sequence[float] | None = None,
    time_steps: Sequence[float] | None = None,
    resolution: int | None = None,
    cell_timeout: float = CELL_TIMEOUT,
    workers: int = 2,
) -> None:
    """Raise ``ValueError`` for an option :func:`run` refuses, before anything runs.

    The parameters are :func:`run`'s.
    """
    unknown = [name for name in scenes or () if name not in SCENES]
    unknown += [name for name in methods or () if name not in METHODS_BY_NAME]
    if unknown:
        raise ValueError(
            f"unknown scene or method {', '.join(unknown)}; scenes: {', '.join(SCENES)}; "
            f"methods: {', '.join(METHODS_BY_NAME)}"
        )
    for name, chosen, values in _axes(poisson_ratios, youngs_moduli, time_steps):
        off_axis = [value for value in chosen or () if value not in values]
        if off_axis:
            raise ValueError(
                f"{name} = {', '.join(map(str, off_axis))} is not on the study's axis: "
                f"{', '.join(map(str, values))}"
            )
    if resolution is not None and not (isinstance(resolution, int) and resolution >= 1):
        raise ValueError(f"resolution must be a positive integer, got {resolution!r}")
    if not cell_timeout > 0.0:
        raise ValueError(f"cell_timeout must be a number of seconds > 0, got {cell_timeout!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be a positive integer, got {workers!r}")


def run(
    output_directory,
    *,
    quick: bool = False,
    workers: int = 2,
    resume: bool = False,
    scenes: Sequence[str] | None = None,
    methods: Sequence[str] | None = None,
    poisson_ratios: Sequence[float] | None = None,
    youngs_moduli: Sequence[float] | None = None,
    time_steps: Sequence[float] | None = None,
    resolution: int | None = None,
    cell_timeout: float = CELL_TIMEOUT,
    progress: bool = False,
    command_line: str | None = None,
) -> dict[str, Any]:
    """Run the study (or its quick subset) and write the CSV, the heat maps and the summary.

    Parameters
    ----------
    output_directory
        Where ``stability.csv``, ``stability.md``, ``stability_SCENE.png`` and ``cells.jsonl``
        (every record in full) go.
    quick
        The quick subset (:func:`matrix`).
    workers
        Worker processes.
    resume
        Reuse the records in ``cells.jsonl`` of cells of this matrix that ran with the same
        parameters.
    scenes, methods, poisson_ratios, youngs_moduli, time_steps
        Restrict the matrix to these values of its axes; ``None``: all. A value that is not
        on its axis is refused.
    resolution
        Run every scene at this mesh resolution instead of its own (:data:`SCENE_SETUPS`): the
        study's resolution axis, one output directory per resolution.
    cell_timeout
        Seconds a cell may run before it is stopped and recorded as ``timeout``.
    progress
        Print one line per finished cell.
    command_line
        The command to state in the summary; by default the one that regenerates this run.

    Returns
    -------
    dict
        ``files``, ``cells``, ``outcomes`` (counts), ``causes`` (counts), ``wall_time_s``.
    """
    check_options(
        scenes=scenes,
        methods=methods,
        poisson_ratios=poisson_ratios,
        youngs_moduli=youngs_moduli,
        time_steps=time_steps,
        resolution=resolution,
        cell_timeout=cell_timeout,
        workers=workers,
    )
    axes = _axes(poisson_ratios, youngs_moduli, time_steps)
    directory = pathlib.Path(output_directory)
    directory.mkdir(parents=True, exist_ok=True)
    cells = [
        dataclasses.replace(cell, resolution=resolution)
        for cell in matrix(quick)
        if (not scenes or cell.scene in scenes)
        and (not methods or cell.method in methods)
        and all(not chosen or getattr(cell, name) in chosen for name, chosen, _ in axes)
    ]
    records_path = directory / "cells.jsonl"
    done: dict[tuple, dict[str, Any]] = {}
    if resume and records_path.exists():
        from dolfinx_invertible.io.step_log import json_ready

        wanted = {cell.key: cell for cell in cells}
        for line in records_path.read_text().splitlines():
            with contextlib.suppress(ValueError, KeyError):
                record = json.loads(line)
                key = (record["scene"], record["method"], record["nu"], record["E"], record["dt"])
                cell = wanted.get(key)
                if cell is not None and record.get("parameters") == json_ready(cell.parameters()):
                    # The causes are read from the data again: the diagnosis may have changed.
                    record["cause"], record["cause_detail"] = diagnose(record)
                    done[key] = record
    todo = [cell for cell in cells if cell.key not in done]
    load_before = _load_average()
    begin = time.perf_counter()
    logs = directory / "logs"
    logs.mkdir(exist_ok=True)
    with records_path.open("a" if resume else "w") as stream:
        for record in done.values():
            if not resume:
                stream.write(json.dumps(record) + "\n")

        def finished(record: dict[str, Any]) -> None:
            record["workers"] = workers
            stream.write(json.dumps(record) + "\n")
            stream.flush()
            if progress:
                print(
                    f"{record['scene']:>14} {method_label(record['method']):>34} "
                    f"ν={record['nu']:<5g} "
                    f"E={record['E']:<7g} dt={record['dt']:<6g} {record.get('outcome'):>17} "
                    f"{record.get('cause') or '':<26} {record.get('wall_time_s') or 0:6.1f} s",
                    flush=True,
                )

        new = run_cells(
            todo,
            workers=workers,
            timeout=cell_timeout,
            log_directory=logs,
            on_result=finished,
        )
    wall_time = time.perf_counter() - begin
    by_key = {**done, **{tuple(_key(record)): record for record in new}}
    records = [by_key[cell.key] for cell in cells if cell.key in by_key]
    if not any(record.get("outcome") == "crashed" for record in records):
        for log in logs.glob("worker-*.log"):
            log.unlink()
        with contextlib.suppress(OSError):
            logs.rmdir()
    files = {"csv": "stability.csv", "summary": "stability.md"}
    write_csv(records, directory / files["csv"])
    for scene in SCENES:
        if any(record["scene"] == scene for record in records):
            name = f"stability_{scene.replace('-', '_')}.png"
            plot_heat_map(records, scene, directory / name)
            files[f"heat_map_{scene}"] = name
    if command_line is None:
        command_line = (
            "python -m dolfinx_invertible report stability"
            + (" --quick" if quick else "")
            + f" --out {directory}"
        )
    lines = summary_lines(
        records,
        quick=quick,
        wall_time=wall_time,
        load=(load_before, _load_average()) if load_before is not None else None,
        command_line=command_line,
    )
    (directory / files["summary"]).write_text("\n".join(lines))
    return {
        "files": files,
        "cells": len(records),
        "outcomes": dict(Counter(display_outcome(record) for record in records)),
        "causes": dict(Counter(record.get("cause") for record in records)),
        "wall_time_s": wall_time,
    }


def _key(record: dict[str, Any]) -> tuple:
    return (record["scene"], record["method"], record["nu"], record["E"], record["dt"])


def _load_average() -> float | None:
    try:
        return os.getloadavg()[0]
    except OSError:
        return None
