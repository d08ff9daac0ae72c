"""ParaView as a separate process: read a result series back as users see it, render pictures.

:func:`inspect_xdmf` opens a :class:`~dolfinx_invertible.io.xdmf.ResultWriter` series with
ParaView's XDMF3 reader and reports its time steps, arrays and their ranges; :func:`render`
draws one picture of a run; :func:`render_runs` draws one per run for the gallery. From the
shell::

    python -m dolfinx_invertible.io.paraview inspect output/collapse/point_C2.xdmf
    python -m dolfinx_invertible.io.paraview render output/collapse --output docs/gallery

Why a separate process
----------------------
Every call runs ``pvbatch`` on a script shipped in ``paraview_scripts/``. Debian's ParaView
Python modules do import into the venv's Python (same Python, system site packages), but they
load ParaView's own VTK, HDF5 and MPI libraries, which need not match those of the DOLFINx
build at hand, and ParaView's XDMF reader aborts its process on some errors (a bad HDF5 path).
In a child process neither can harm the caller: an abort becomes a :class:`ParaViewError`.
The child gets ``--no-mpi`` and none of the caller's MPI launcher variables, so that a
DOLFINx process running under ``mpirun`` can call these functions (on one rank).

Displays
--------
Reading needs no display. Rendering does: Debian bookworm's ParaView 5.11 is built for X only
(no EGL, no OSMesa; ``--force-offscreen-rendering`` still aborts without ``DISPLAY``). So each
:func:`render` starts its own ``Xvfb`` (Debian package ``xvfb``), which picks a free display
number itself (``-displayfd``), and runs it with ``-noreset``: without it the server resets
when ParaView's first X connection closes, and the next one fails now and then ("bad X server
connection"), as it does under a plain ``xvfb-run -a``. With no ``Xvfb`` installed, an existing
``DISPLAY`` is used.

Paths
-----
ParaView 5.11 resolves the ``.h5`` file of an XDMF file given by a bare relative name wrongly
(``run.xdmf`` makes it open ``run.xdmfrun.h5``, and the reader aborts): every path handed to
ParaView here is made absolute first.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import select
import shutil
import subprocess
import sys
import tempfile
import time as clock
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

__all__ = [
    "BODY_OPACITY",
    "IMAGE_SIZE",
    "INVERTED_COLOUR",
    "MIN_J_COLOUR_MAP",
    "MIN_J_RANGE",
    "ParaViewError",
    "ParaViewNotFoundError",
    "TIME_KEYWORDS",
    "find_pvbatch",
    "inspect_xdmf",
    "main",
    "render",
    "render_runs",
    "run_files",
]

#: Colour map range of ``min_J`` in :func:`render`, fixed so that pictures of different runs
#: and times compare: 0 (collapsed; the inverted cells, below 0, are drawn red instead) to 2
#: (volume doubled), with the rest state J = 1 in the middle; values beyond 2 are clamped.
MIN_J_RANGE = (0.0, 2.0)
#: ParaView preset of the ``min_J`` colours: perceptually uniform and free of red, which marks
#: the inverted cells.
MIN_J_COLOUR_MAP = "Viridis (matplotlib)"
#: RGB of the inverted cells (``inverted`` = 1, picked by a Threshold), drawn opaque.
INVERTED_COLOUR = (0.9, 0.05, 0.05)
#: Opacity of the body, so that inverted cells inside it show through.
BODY_OPACITY = 0.45
#: Keywords :func:`render` takes for its time.
TIME_KEYWORDS = ("most-inverted", "first", "last")
#: Width and height of a picture in pixels.
IMAGE_SIZE = (1024, 768)

_SCRIPT = Path(__file__).resolve().parent / "paraview_scripts" / "series.py"
_INSTALL_HINT = (
    "install Debian's paraview, python3-paraview and xvfb packages (`make test` and `make demo` "
    "install them)"
)
_XVFB_START_SECONDS = 60.0
_STACK_FRAME = re.compile(r"\s*\d+\s+0x[0-9a-f]+ ")
# Variables by which an MPI launcher hands a process its place in a job: a child that inherits
# them takes itself for a rank of the caller's job.
_MPI_ENVIRONMENT_PREFIXES = ("OMPI_", "PMIX_", "PMI_", "HYDRA_", "I_MPI_")


class ParaViewError(RuntimeError):
    """ParaView failed: the message holds its traceback or the end of its output."""


class ParaViewNotFoundError(ParaViewError):
    """ParaView's ``pvbatch`` (or, for rendering, an X display or ``Xvfb``) is not installed."""


def find_pvbatch(executable: str | Path | None = None) -> Path:
    """Return the ``pvbatch`` to run: ``executable``, else ``$PVBATCH``, else the one on PATH.

    Whether it can import ParaView's Python modules shows only when it runs (Debian ships them
    in ``python3-paraview``, a mere recommendation of ``paraview``); the functions that run it
    raise :class:`ParaViewNotFoundError` then.

    Raises
    ------
    ParaViewNotFoundError
        If there is none.
    """
    name = executable or os.environ.get("PVBATCH") or "pvbatch"
    found = shutil.which(str(name))
    if found is None:
        raise ParaViewNotFoundError(f"ParaView's {name} was not found: {_INSTALL_HINT}")
    return Path(found)


def inspect_xdmf(
    path: str | Path,
    *,
    executable: str | Path | None = None,
    timeout: float = 600.0,
) -> dict[str, Any]:
    """Open an XDMF file with ParaView's XDMF3 reader and summarise what it reads.

    Parameters
    ----------
    path
        The ``.xdmf`` file (its HDF5 files next to it).
    executable
        The ``pvbatch`` to run (see :func:`find_pvbatch`).
    timeout
        Seconds before ParaView is stopped.

    Returns
    -------
    dict
        ``path`` (absolute), ``reader`` (the proxy name, ``Xdmf3ReaderS``),
        ``paraview_version``, ``times`` (the time steps, empty for a file without any),
        ``point_arrays`` and ``cell_arrays`` (names the reader offers), ``number_of_points``
        and ``number_of_cells`` (of the first step), and ``steps``: one dict per time step
        (a single one with ``time`` None for a file without time steps) with ``time``,
        ``number_of_points``, ``number_of_cells``, ``bounds`` (x, y, z minimum and maximum of
        the undeformed points), ``cell_types`` (VTK class names), ``point_data`` and
        ``cell_data`` (array name to ``components``, ``data_type`` as ParaView holds it,
        ``range`` -- of the magnitude for vectors -- and ``component_ranges``), and
        ``inverted_cells`` (cells with ``inverted`` > 0.5, None without that array).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If ``path`` does not end in ``.xdmf``.
    ParaViewNotFoundError
        If ParaView is not installed.
    ParaViewError
        If ParaView fails to read the file.
    """
    return _run_script(
        {"command": "inspect", "path": str(_existing_xdmf(path))},
        executable,
        timeout=timeout,
        display=False,
    )


def render(
    path: str | Path,
    png: str | Path,
    *,
    time: float | str | None = None,
    size: tuple[int, int] = IMAGE_SIZE,
    min_J_range: tuple[float, float] = MIN_J_RANGE,
    warp_scale: float = 1.0,
    body_opacity: float = BODY_OPACITY,
    title: str | None = None,
    executable: str | Path | None = None,
    timeout: float = 600.0,
) -> dict[str, Any]:
    """Render a picture of a run: the warped body coloured by ``min_J``, inverted cells red.

    The mesh is warped by the point array ``displacement`` (ParaView's ``WarpByVector``). The
    cells with ``inverted`` = 1 (a ``Threshold`` on that cell array) are drawn opaque in
    :data:`INVERTED_COLOUR`; the others with their edges, translucent (so that inverted cells
    inside show through), coloured by the cell array ``min_J`` over the fixed range
    ``min_J_range`` (colour map :data:`MIN_J_COLOUR_MAP`, with a scalar bar). A label names
    the run, the time, the size of the warped body's bounding box and the number of inverted
    cells. The camera looks from a fixed oblique direction (straight down the z axis for a
    flat, 2D body), in parallel projection, and fits the warped body into the picture, whatever
    its size: the label tells the size.

    Parameters
    ----------
    path
        The ``.xdmf`` file of the run.
    png
        The picture to write; missing parent directories are created.
    time
        The time step to show: a number (the nearest step), ``"first"``, ``"last"`` or
        ``"most-inverted"`` (the first step with the most inverted cells, or the last step if
        none has any); None means ``"most-inverted"``.
    size
        Width and height in pixels.
    min_J_range
        The ``min_J`` values at the two ends of the colour map (values outside are clamped).
    warp_scale
        Factor on the displacement (1: the deformed body as computed).
    body_opacity
        Opacity of the body, in (0, 1].
    title
        First line of the label; None: the file's name without its suffix.
    executable
        The ``pvbatch`` to run (see :func:`find_pvbatch`).
    timeout
        Seconds before ParaView is stopped.

    Returns
    -------
    dict
        ``png`` (absolute), ``time`` (the time step shown), ``inverted_cells`` at that time
        (None without an ``inverted`` array), ``bounds`` of the warped body,
        ``paraview_version`` and ``seconds`` (wall time of the ParaView process).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If ``path`` does not end in ``.xdmf`` or ``png`` in ``.png``, an option is out of
        range, the run has no time steps, or ``time`` lies outside them (these two checks
        happen in ParaView, which knows the time steps; they are re-raised here).
    ParaViewNotFoundError
        If ParaView, or both ``Xvfb`` and an X display, are missing.
    ParaViewError
        If ParaView fails.
    """
    source = _existing_xdmf(path)
    width, height = (int(value) for value in size)
    if width != size[0] or height != size[1] or not (16 <= width <= 8192 and 16 <= height <= 8192):
        raise ValueError(f"size must be two whole numbers of pixels in [16, 8192], got {size}")
    low, high = (float(value) for value in min_J_range)
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise ValueError(f"min_J_range must be two finite numbers, low < high, got {min_J_range}")
    if not math.isfinite(warp_scale):
        raise ValueError(f"warp_scale must be finite, got {warp_scale}")
    if not 0.0 < body_opacity <= 1.0:
        raise ValueError(f"body_opacity must lie in (0, 1], got {body_opacity}")
    if time is None:
        time = "most-inverted"
    elif isinstance(time, str):
        if time not in TIME_KEYWORDS:
            raise ValueError(f"time must be a number or one of {TIME_KEYWORDS}, got {time!r}")
    elif not math.isfinite(time):
        raise ValueError(f"time must be finite, got {time}")
    else:
        time = float(time)
    png = Path(png).resolve()
    if png.suffix.lower() != ".png":
        raise ValueError(f"png must end in .png, got {str(png)!r}")
    png.parent.mkdir(parents=True, exist_ok=True)
    name = source.stem if title is None else title
    request = {
        "command": "render",
        "path": str(source),
        "png": str(png),
        "time": time,
        "size": [width, height],
        "displacement": "displacement",
        "warp_scale": float(warp_scale),
        "colour_array": "min_J",
        "colour_title": "min J",
        "colour_map": MIN_J_COLOUR_MAP,
        "colour_range": [low, high],
        "body_opacity": float(body_opacity),
        "inverted_colour": list(INVERTED_COLOUR),
        # Braces of the name must not reach str.format in the script.
        "label": name.replace("{", "{{").replace("}", "}}")
        + "\nt = {time:.6g}\nsize {extent}\ninverted cells (red): {inverted}",
    }
    started = clock.perf_counter()
    result = _run_script(request, executable, timeout=timeout, display=True)
    result["seconds"] = clock.perf_counter() - started
    return result


def run_files(paths: Sequence[str | Path]) -> list[Path]:
    """Return the XDMF files of runs: each path an ``.xdmf`` file or a directory of them.

    Directories are not searched recursively; their files come sorted by name.

    Raises
    ------
    FileNotFoundError
        If a path does not exist, or a directory holds no ``.xdmf`` file.
    ValueError
        If a file is not an ``.xdmf`` file.
    """
    files = []
    for given in paths:
        path = Path(given)
        if path.is_dir():
            found = sorted(path.glob("*.xdmf"))
            if not found:
                raise FileNotFoundError(f"no .xdmf file in the directory {str(path)!r}")
            files.extend(found)
        else:
            files.append(_existing_xdmf(path))
    return files


def render_runs(
    paths: Sequence[str | Path], output_directory: str | Path, **options: Any
) -> list[dict[str, Any]]:
    """Render one picture per run into ``output_directory/<run directory name>/<run name>.png``.

    Parameters
    ----------
    paths
        Run directories or ``.xdmf`` files (see :func:`run_files`).
    output_directory
        Where the pictures go, one subdirectory per directory of runs, so that runs of the same
        name in different directories (``results/<scene>/``) do not overwrite each other.
    **options
        Keyword options of :func:`render`.

    Returns
    -------
    list of dict
        What :func:`render` returned for each run, in order.
    """
    output_directory = Path(output_directory)
    return [
        render(path, output_directory / path.resolve().parent.name / f"{path.stem}.png", **options)
        for path in run_files(paths)
    ]


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``inspect PATH`` prints JSON, ``render PATH... --output DIRECTORY``.

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
    arguments = parser.parse_args(argv)
    try:
        if arguments.command == "inspect":
            print(json.dumps(inspect_xdmf(arguments.path), indent=1))
            return 0
        results = render_runs(
            arguments.paths,
            arguments.output,
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


def _existing_xdmf(path: str | Path) -> Path:
    path = Path(path)
    if path.suffix != ".xdmf":
        raise ValueError(f"expected an .xdmf file, got {str(path)!r}")
    if not path.is_file():
        raise FileNotFoundError(f"no such XDMF file: {str(path)!r}")
    # Absolute: ParaView 5.11 misplaces the .h5 file of a bare relative name (module docstring).
    return path.resolve()


def _child_environment() -> dict[str, str]:
    environment = {
        name: value
        for name, value in os.environ.items()
        if not name.startswith(_MPI_ENVIRONMENT_PREFIXES)
        # pvbatch embeds the system Python: a venv's PYTHONHOME would break it.
        and name != "PYTHONHOME"
    }
    return environment


@contextmanager
def _x_display(environment: dict[str, str], log: Path) -> Iterator[dict[str, str]]:
    """Yield ``environment`` with ``DISPLAY`` set to a private Xvfb (or the existing one)."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        if environment.get("DISPLAY"):
            yield environment
            return
        raise ParaViewNotFoundError(
            f"rendering needs an X display, and neither Xvfb nor DISPLAY is there: {_INSTALL_HINT}"
        )
    read_end, write_end = os.pipe()
    try:
        # A file, not a pipe: a pipe nobody reads would stall the server once full.
        with open(log, "wb") as log_stream:
            server = subprocess.Popen(
                [xvfb, "-displayfd", str(write_end), "-noreset", "-nolisten", "tcp"]
                + ["-screen", "0", "1280x1024x24"],
                pass_fds=(write_end,),
                stdin=subprocess.DEVNULL,
                stdout=log_stream,
                stderr=subprocess.STDOUT,
            )
    except BaseException:
        os.close(read_end)
        raise
    finally:
        os.close(write_end)
    try:
        number = _read_display_number(read_end, _XVFB_START_SECONDS)
        if number is None:
            raise ParaViewError(
                f"Xvfb did not start within {_XVFB_START_SECONDS} s; its output:\n"
                + _tail(log.read_text(errors="replace"))
            )
        yield dict(environment, DISPLAY=f":{number}")
    finally:
        if server.poll() is None:
            server.terminate()
            try:
                server.wait(timeout=30)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait()


def _read_display_number(descriptor: int, timeout: float) -> str | None:
    """Return the number Xvfb writes once it accepts connections; None if it dies or hangs."""
    deadline = clock.monotonic() + timeout
    text = b""
    try:
        while not text.endswith(b"\n"):
            remaining = deadline - clock.monotonic()
            if remaining <= 0 or not select.select([descriptor], [], [], remaining)[0]:
                return None
            chunk = os.read(descriptor, 64)
            if not chunk:  # the server exited
                return None
            text += chunk
    finally:
        os.close(descriptor)
    number = text.strip().decode(errors="replace")
    return number if number.isdigit() else None


def _run_script(
    request: dict[str, Any], executable: str | Path | None, *, timeout: float, display: bool
) -> dict[str, Any]:
    pvbatch = find_pvbatch(executable)
    with tempfile.TemporaryDirectory(prefix="dolfinx_invertible_paraview_") as directory:
        request_path = Path(directory) / "request.json"
        result_path = Path(directory) / "result.json"
        request_path.write_text(json.dumps(request), encoding="utf-8")
        command = [str(pvbatch), "--no-mpi", str(_SCRIPT), str(request_path), str(result_path)]
        environment = _child_environment()
        try:
            if display:
                with _x_display(environment, Path(directory) / "xvfb.log") as environment:
                    completed = _run(command, environment, timeout)
            else:
                completed = _run(command, environment, timeout)
        except subprocess.TimeoutExpired as error:
            raise ParaViewError(f"{pvbatch} did not finish within {timeout} s") from error
        result = None
        if result_path.is_file():
            result = json.loads(result_path.read_text(encoding="utf-8"))
    if result is None:
        output = (completed.stdout + completed.stderr).strip()
        if "No module named 'paraview'" in output:
            raise ParaViewNotFoundError(
                f"{pvbatch} cannot import ParaView's Python modules: {_INSTALL_HINT}"
            )
        raise ParaViewError(
            f"{pvbatch} exited with code {completed.returncode} without a result; the end of "
            f"its output:\n{_tail(output)}"
        )
    if "error" in result:
        message = result["error"].rstrip()
        last_line = message.splitlines()[-1] if message else ""
        if last_line.startswith("ValueError:"):
            raise ValueError(last_line.removeprefix("ValueError:").strip())
        raise ParaViewError(f"ParaView raised:\n{message}")
    return result


def _run(command: list[str], environment: dict[str, str], timeout: float):
    return subprocess.run(
        command,
        env=environment,
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        errors="replace",
        timeout=timeout,
    )


def _tail(text: str, lines: int = 40) -> str:
    # Without the native stack trace ParaView prints when it aborts: the messages before it
    # (HDF5's, VTK's "ERR|" lines) say what went wrong.
    kept = [line for line in text.splitlines() if not _STACK_FRAME.match(line)]
    return "\n".join(kept[-lines:])


if __name__ == "__main__":
    sys.exit(main())
