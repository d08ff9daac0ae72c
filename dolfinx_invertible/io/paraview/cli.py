"""The command line ``python -m dolfinx_invertible.io.paraview inspect|render|animate ...``."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from dolfinx_invertible.io.paraview.process import ParaViewError
from dolfinx_invertible.io.paraview.series import (
    ANIMATION_FRAMES,
    ANIMATION_SIZE,
    IMAGE_SIZE,
    TIME_KEYWORDS,
    inspect_xdmf,
    render_runs,
)

__all__ = ["main"]


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``inspect PATH`` prints JSON, ``render|animate PATH... --output DIRECTORY``.

    Returns the process exit code: 0, 1 if ParaView failed or is missing, 2 for bad arguments.
    """
    parser = argparse.ArgumentParser(
        prog="python -m dolfinx_invertible.io.paraview",
        description="Read or render ResultWriter XDMF series with ParaView (pvbatch).",
    )
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    inspect_parser = commands.add_parser(
        "inspect", help="time steps, arrays and ranges as ParaView reads them (JSON)"
    )
    inspect_parser.add_argument("path", type=Path, help="an .xdmf file")
    render_parser = commands.add_parser(
        "render", help="one PNG per run: warped body coloured by min_J, inverted cells red"
    )
    render_parser.add_argument("paths", type=Path, nargs="+", help="run directories or .xdmf files")
    render_parser.add_argument(
        "--output", type=Path, required=True, help="directory of the pictures"
    )
    render_parser.add_argument(
        "--time",
        type=_time_argument,
        default=None,
        help="time step to show: a number (the nearest step), or first, last, most-inverted "
        "(default: the first step with the most inverted cells, else the last)",
    )
    render_parser.add_argument(
        "--size", type=int, nargs=2, default=IMAGE_SIZE, metavar=("WIDTH", "HEIGHT")
    )
    render_parser.add_argument("--warp-scale", type=float, default=1.0)
    animate_parser = commands.add_parser(
        "animate", help="one animated GIF per run, the same picture at up to --frames steps"
    )
    animate_parser.add_argument(
        "paths", type=Path, nargs="+", help="run directories or .xdmf files"
    )
    animate_parser.add_argument(
        "--output", type=Path, required=True, help="directory of the animations"
    )
    animate_parser.add_argument("--frames", type=int, default=ANIMATION_FRAMES)
    animate_parser.add_argument(
        "--size", type=int, nargs=2, default=ANIMATION_SIZE, metavar=("WIDTH", "HEIGHT")
    )
    for subparser in (render_parser, animate_parser):
        subparser.add_argument(
            "--no-obstacles", action="store_true", help="do not draw the scene's obstacles"
        )
    arguments = parser.parse_args(argv)
    try:
        if arguments.command == "inspect":
            print(json.dumps(inspect_xdmf(arguments.path), indent=1))
            return 0
        obstacles_of = None
        if not arguments.no_obstacles:
            # The scenes know their obstacles; loaded only here, for the command line.
            from dolfinx_invertible.scenes.pictures import run_obstacles as obstacles_of
        if arguments.command == "animate":
            results = render_runs(
                arguments.paths,
                arguments.output,
                obstacles_of=obstacles_of,
                animation=True,
                frames=arguments.frames,
                size=tuple(arguments.size),
            )
            for result in results:
                print(f"{result['gif']}: {result['frames']} frames, {result['bytes']} bytes, "
                      f"{result['seconds']:.1f} s")  # fmt: skip
            return 0
        results = render_runs(
            arguments.paths,
            arguments.output,
            obstacles_of=obstacles_of,
            time=arguments.time,
            size=tuple(arguments.size),
            warp_scale=arguments.warp_scale,
        )
    except (FileNotFoundError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except ParaViewError as error:
        print(f"ParaView failed: {error}", file=sys.stderr)
        return 1
    for result in results:
        inverted = result["inverted_cells"]
        print(
            f"{result['png']}: t = {result['time']:.6g}, inverted cells "
            f"{'-' if inverted is None else inverted}, {result['seconds']:.1f} s"
        )
    return 0


def _time_argument(text: str) -> float | str:
    if text in TIME_KEYWORDS:
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a number or one of {', '.join(TIME_KEYWORDS)}, got {text!r}"
        ) from None
