"""The command line of ``report error-vs-time``."""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

from dolfinx_invertible.reports import add_output_arguments
from dolfinx_invertible.reports.error_vs_time.outputs import format_value, write_results
from dolfinx_invertible.reports.error_vs_time.runner import run
from dolfinx_invertible.reports.error_vs_time.study import STUDIES

__all__ = ["DEFAULT_OUTPUT", "add_arguments", "command"]

#: Where ``report error-vs-time`` writes by default.
DEFAULT_OUTPUT = pathlib.Path("results/reports/error-vs-time")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``report error-vs-time``."""
    add_output_arguments(
        parser, DEFAULT_OUTPUT, "the small study (about 2 minutes on 2 cores; the tests run it)"
    )
    parser.add_argument(
        "--study",
        action="append",
        choices=list(STUDIES),
        dest="studies",
        help="run only this study (repeatable; default: all)",
    )
    parser.add_argument(
        "--redraw",
        action="store_true",
        help="redo the tables and figures from DIR/summary.json of an earlier run, running nothing",
    )
    parser.add_argument("--verbose", action="store_true", help="show compiler and solver chatter")


def command(arguments: argparse.Namespace) -> int:
    """Run ``report error-vs-time``; print the orders and the cheapest runs."""
    from mpi4py import MPI

    if arguments.redraw:
        path = arguments.out / "summary.json"
        if not path.is_file():
            print(f"error: --redraw needs {path} from an earlier run", file=sys.stderr)
            return 2
        earlier = json.loads(path.read_text())
        result = write_results(
            arguments.out,
            earlier["rows"],
            quick=earlier["quick"],
            ranks=earlier["ranks"],
            seconds=earlier["seconds"],
            load_average=earlier["load_average"],
        )
    else:
        result = run(arguments.out, quick=arguments.quick, studies=arguments.studies, progress=True)
    if MPI.COMM_WORLD.rank == 0:
        for entry in result["orders"]:
            print(
                f"{entry['study']}: {entry['curve']}: {entry['kind']} order "
                f"{format_value(entry['order'])} ({entry['points']} runs)"
            )
        for entry in result["cheapest"]:
            print(
                f"{entry['study']}: {entry['error']} <= {entry['target']:g}: "
                f"{entry['configuration'] or 'not reached'}"
            )
        print(
            f"wrote {arguments.out}/ (runs.csv, summary.md, summary.json, figures) in "
            f"{result['seconds']:.0f} s"
        )
    return 0
