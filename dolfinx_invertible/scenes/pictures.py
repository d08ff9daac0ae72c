"""Pictures and animations of a scene's run with its obstacles drawn (ParaView, headless).

A run's directory says which scene ran with which parameters (``summary.json``, or the
checkpoint of a run that has not finished); the scene then makes its obstacles again, and
:func:`~dolfinx_invertible.io.paraview.render` and :func:`~dolfinx_invertible.io.paraview.
animate` draw them where they were at each time shown::

    from dolfinx_invertible.scenes.pictures import animate_run, render_run

    render_run("results/bowl-drop", "bowl-drop.png", time="last")
    animate_run("results/bowl-drop", "bowl-drop.gif")

The command ``dolfinx-invertible paraview inspect|render|animate ...`` (also
``python -m dolfinx_invertible.io.paraview ...``) is :func:`add_arguments` and :func:`command`.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from mpi4py import MPI

from dolfinx_invertible.io.checkpoint import CheckpointError
from dolfinx_invertible.io.paraview import (
    ANIMATION_FRAMES,
    ANIMATION_SIZE,
    IMAGE_SIZE,
    TIME_KEYWORDS,
    ParaViewError,
    animate,
    inspect_xdmf,
    render,
    render_runs,
)
from dolfinx_invertible.scenes.checkpoints import latest_checkpoint
from dolfinx_invertible.scenes.parameters import Parameters

__all__ = ["add_arguments", "animate_run", "command", "render_run", "run_obstacles"]


def _run_scene(directory: Path) -> tuple[str, dict[str, Any]] | None:
    summary = directory / "summary.json"
    if summary.is_file():
        data = json.loads(summary.read_text(encoding="utf-8"))
        return data["scene"], data["parameters"]
    try:
        state = latest_checkpoint(directory)[1]
    except CheckpointError:
        return None
    return state["scene"], state["parameters"]


def run_obstacles(directory: str | Path) -> list:
    """Return what the scene that ran in ``directory`` draws beside its body (may be empty)."""
    from dolfinx_invertible.scenes import get_scene

    found = _run_scene(Path(directory))
    if found is None:
        return []
    name, parameters = found
    return get_scene(name)(Parameters(**parameters), MPI.COMM_SELF).drawn_obstacles()


def _series(directory: Path) -> Path:
    found = _run_scene(directory)
    if found is None:
        raise FileNotFoundError(f"{directory} holds no run (no summary.json, no checkpoint)")
    return directory / f"{found[0]}.xdmf"


def render_run(directory: str | Path, png: str | Path, **options: Any) -> dict[str, Any]:
    """Render the run in ``directory`` with its obstacles; options as :func:`render`'s."""
    directory = Path(directory)
    return render(_series(directory), png, obstacles=run_obstacles(directory), **options)


def animate_run(directory: str | Path, gif: str | Path, **options: Any) -> dict[str, Any]:
    """Animate the run in ``directory`` with its obstacles; options as :func:`animate`'s."""
    directory = Path(directory)
    return animate(_series(directory), gif, obstacles=run_obstacles(directory), **options)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the subcommands ``inspect``, ``render`` and ``animate`` to ``parser``."""
    commands = parser.add_subparsers(dest="paraview_command", required=True, metavar="COMMAND")
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


def command(arguments: argparse.Namespace) -> int:
    """Run the subcommand; return the exit code: 0, 1 if ParaView failed, 2 for bad input."""
    try:
        if arguments.paraview_command == "inspect":
            print(json.dumps(inspect_xdmf(arguments.path), indent=1))
            return 0
        obstacles_of = None if arguments.no_obstacles else run_obstacles
        if arguments.paraview_command == "animate":
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
