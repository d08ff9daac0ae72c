"""The command line of ``report stability``."""

from __future__ import annotations

import argparse
import sys

from dolfinx_invertible.reports.stability.pool import CELL_TIMEOUT
from dolfinx_invertible.reports.stability.report import check_options, run
from dolfinx_invertible.reports.stability.study import (
    METHODS,
    POISSON_RATIOS,
    SCENES,
    TIME_STEPS,
    YOUNGS_MODULI,
)

__all__ = ["add_arguments", "command"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``report stability``."""
    from dolfinx_invertible.reports import add_output_arguments

    add_output_arguments(
        parser,
        "results/reports/stability",
        "the quick subset: every scene and method at nu = 0.45, E = 1e5, dt = 1e-2, and C2 and "
        "corotated also at E = 1e7, dt = 1e-3 (the same dt c/L)",
    )
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument(
        "--resume", action="store_true", help="reuse finished cells of cells.jsonl in --out"
    )
    parser.add_argument(
        "--scene", action="append", choices=SCENES, help="only this scene (repeatable)"
    )
    parser.add_argument(
        "--method",
        action="append",
        choices=[method.name for method in METHODS],
        help="only this method (repeatable)",
    )
    for flag, values, label in (
        ("--nu", POISSON_RATIOS, "Poisson ratio"),
        ("--E", YOUNGS_MODULI, "Young's modulus"),
        ("--dt", TIME_STEPS, "time step"),
    ):
        parser.add_argument(
            flag,
            action="append",
            type=float,
            choices=values,
            metavar=flag[2:].upper(),
            help=f"only this {label} of the matrix, one of {', '.join(map(str, values))} "
            "(repeatable)",
        )
    parser.add_argument(
        "--resolution",
        type=int,
        help="run every scene at this mesh resolution (the study's resolution axis; default: "
        "each scene's own, 4 for the relaxations, 2 for the driven scenes)",
    )
    parser.add_argument(
        "--cell-timeout",
        type=float,
        default=CELL_TIMEOUT,
        metavar="SECONDS",
        help=f"stop a cell after this many seconds and record it as timed out (default "
        f"{CELL_TIMEOUT:g})",
    )
    parser.add_argument("--quiet", action="store_true", help="no line per finished cell")


def command(arguments: argparse.Namespace) -> int:
    """Run ``report stability``.

    Exit code 1 if a worker crashed or a cell timed out, 2 if an option was refused.
    """
    import signal

    def interrupt(number, frame):
        raise KeyboardInterrupt(f"stopped by {signal.Signals(number).name}")

    signal.signal(signal.SIGTERM, interrupt)
    words = ["python -m dolfinx_invertible report stability"]
    if arguments.quick:
        words.append("--quick")
    words.append(f"--out {arguments.out}")
    for scene in arguments.scene or ():
        words.append(f"--scene {scene}")
    for method in arguments.method or ():
        words.append(f"--method {method}")
    for flag in ("nu", "E", "dt"):
        for value in getattr(arguments, flag) or ():
            words.append(f"--{flag} {value:g}")
    if arguments.resolution is not None:
        words.append(f"--resolution {arguments.resolution}")
    if arguments.cell_timeout != CELL_TIMEOUT:
        words.append(f"--cell-timeout {arguments.cell_timeout:g}")
    options = {
        "scenes": arguments.scene,
        "methods": arguments.method,
        "poisson_ratios": arguments.nu,
        "youngs_moduli": arguments.E,
        "time_steps": arguments.dt,
        "resolution": arguments.resolution,
        "cell_timeout": arguments.cell_timeout,
        "workers": arguments.workers,
    }
    try:
        check_options(**options)
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    result = run(
        arguments.out,
        quick=arguments.quick,
        resume=arguments.resume,
        progress=not arguments.quiet,
        command_line=" ".join(words),
        **options,
    )
    outcomes = ", ".join(f"{name} {count}" for name, count in sorted(result["outcomes"].items()))
    print(
        f"{result['cells']} cells in {result['wall_time_s'] / 60:.1f} min: {outcomes}; "
        f"written to {arguments.out}"
    )
    lost = result["outcomes"].get("crashed", 0) + result["outcomes"].get("timeout", 0)
    return 1 if lost else 0
