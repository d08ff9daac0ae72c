"""A result series seen through ParaView: what its reader reads, and pictures of it.

:func:`inspect_xdmf` opens a :class:`~dolfinx_invertible.io.xdmf.ResultWriter` series with
ParaView's XDMF3 reader and reports its time steps, arrays and their ranges; :func:`render`
draws one picture of a run; :func:`render_runs` draws one per run for the gallery. Each call
runs ``pvbatch`` in a separate process (:mod:`~dolfinx_invertible.io.paraview.process`) on the
script ``paraview_scripts/series.py``, which answers these requests.

Paths
-----
ParaView 5.11 resolves the ``.h5`` file of an XDMF file given by a bare relative name wrongly
(``run.xdmf`` makes it open ``run.xdmfrun.h5``, and the reader aborts): every path handed to
ParaView here is made absolute first.
"""

from __future__ import annotations

import math
import time as clock
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from dolfinx_invertible.io.paraview.process import run_script

__all__ = [
    "BODY_OPACITY",
    "IMAGE_SIZE",
    "INVERTED_COLOUR",
    "MIN_J_COLOUR_MAP",
    "MIN_J_RANGE",
    "TIME_KEYWORDS",
    "inspect_xdmf",
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
    return run_script(
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
    result = run_script(request, executable, timeout=timeout, display=True)
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


def _existing_xdmf(path: str | Path) -> Path:
    path = Path(path)
    if path.suffix != ".xdmf":
        raise ValueError(f"expected an .xdmf file, got {str(path)!r}")
    if not path.is_file():
        raise FileNotFoundError(f"no such XDMF file: {str(path)!r}")
    # Absolute: ParaView 5.11 misplaces the .h5 file of a bare relative name (module docstring).
    return path.resolve()
