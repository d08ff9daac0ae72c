"""The command line of ``report contours``."""

from __future__ import annotations

import argparse
import pathlib
import sys

from dolfinx_invertible.reports import add_output_arguments
from dolfinx_invertible.reports.contours.report import run

__all__ = ["DEFAULT_OUTPUT", "add_arguments", "command"]

#: Where ``report contours`` writes by default.
DEFAULT_OUTPUT = pathlib.Path("results/reports/contours")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``report contours``."""
    add_output_arguments(
        parser,
        DEFAULT_OUTPUT,
        "coarser tracing grid, shorter trajectories, lower resolution (what the tests run)",
    )
    parser.add_argument(
        "--mattress",
        type=pathlib.Path,
        action="append",
        metavar="DIR",
        help="output directory of a mattress-2d run (with trajectories.npy): "
        "its element trajectories replace the stand-ins of the stretch figure "
        "(repeatable: one panel per run)",
    )
    parser.add_argument(
        "--triangles",
        type=pathlib.Path,
        action="append",
        metavar="DIR",
        help="output directory of a triangles-2d run: its trajectories replace "
        "the stand-ins of the relaxation figure (repeatable)",
    )


def command(arguments: argparse.Namespace) -> int:
    """Run ``report contours``; print the figures written."""
    try:
        result = run(
            arguments.out,
            quick=arguments.quick,
            mattress=arguments.mattress,
            triangles=arguments.triangles,
        )
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    for kind in ("stretch", "relaxation"):
        for entry in result[kind].get("scene_runs", []):
            print(
                f"{kind}: {entry['elements']} elements × {entry['steps']} steps from "
                f"{entry['directory']} ({entry['inverted_elements']} inverted on the way)"
            )
    print(
        f"wrote {arguments.out}/ ({', '.join(result['figures'].values())}) in "
        f"{result['seconds']:.1f} s"
    )
    return 0
