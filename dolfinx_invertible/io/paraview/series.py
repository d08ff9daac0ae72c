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
import tempfile
import time as clock
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dolfinx_invertible.io.paraview.obstacles import (
    body_bounds,
    resolve_time,
    sample_groups,
    split_obstacles,
    step_table,
)
from dolfinx_invertible.io.paraview.process import run_script

__all__ = [
    "ANIMATION_FRAMES",
    "ANIMATION_SIZE",
    "BODY_OPACITY",
    "IMAGE_SIZE",
    "INVERTED_COLOUR",
    "MIN_J_COLOUR_MAP",
    "MIN_J_RANGE",
    "OBSTACLE_COLOUR",
    "OBSTACLE_OPACITY",
    "TIME_KEYWORDS",
    "VIEW_DIRECTION",
    "animate",
    "inspect_vtx",
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
#: Width and height of an animation's frames, and their largest number.
ANIMATION_SIZE = (480, 360)
ANIMATION_FRAMES = 40
#: RGB and opacity of the obstacles (translucent: the body inside a bowl or tube shows).
OBSTACLE_COLOUR = (0.62, 0.55, 0.45)
OBSTACLE_OPACITY = 0.35
#: Where the camera looks from, towards a body that is not flat (a flat one: from +z).
VIEW_DIRECTION = (1.6, -2.2, 1.3)


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


def inspect_vtx(
    path: str | Path,
    *,
    executable: str | Path | None = None,
    timeout: float = 600.0,
) -> dict[str, Any]:
    """Open a VTX (ADIOS2 ``.bp``) file with ParaView's ADIOS2 VTX reader and summarise it.

    Returns what :func:`inspect_xdmf` returns (``times``, ``number_of_points``,
    ``number_of_cells``, ``steps`` with each array's ranges), the reader's pieces merged into
    one grid. Needs a ParaView built with ADIOS2 (5.13 on Debian trixie is; 5.11 on bookworm
    is not).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ParaViewError
        If ParaView cannot read it (or has no ADIOS2 reader).
    """
    source = Path(path)
    if source.suffix != ".bp":
        raise ValueError(f"expected a .bp folder, got {str(path)!r}")
    if not source.exists():
        raise FileNotFoundError(f"no such VTX file: {str(path)!r}")
    return run_script(
        {"command": "inspect_vtx", "path": str(source.resolve())},
        executable,
        timeout=timeout,
        display=False,
        mpi=True,
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
    obstacles: Sequence[Any] = (),
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
    obstacles
        Analytic obstacles (objects with ``gap(x, t)``, e.g. a contact scene's ``obstacles()``)
        drawn where they are at the time shown, translucent, in a box around the body's whole
        path, cut away on the camera's side of the path's middle (see :mod:`.obstacles`);
        needs the run's step log next to ``path``.
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
    request = _picture_request(source, size, min_J_range, warp_scale, body_opacity, title)
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
    request.update(command="render", png=str(png), time=time)
    started = clock.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        if obstacles:
            times, inverted = step_table(source)
            step = resolve_time(times, inverted, time)
            request["time"] = times[step]
            # Around the body's whole path (50 steps of it at most): the scene, not only where
            # the body is at that time (a cube in the middle of its bowl, say).
            path_steps = np.linspace(0, len(times) - 1, min(50, len(times))).round().astype(int)
            bounds = body_bounds(source, sorted(set(path_steps) | {step}))
            groups = split_obstacles(obstacles, times[step], *bounds, VIEW_DIRECTION)
            request["obstacles"] = [
                sample_groups(groups, times[step], *bounds, Path(folder) / "gap")
            ]
            request["cutaway_origin"] = (0.5 * (bounds[0] + bounds[1])).tolist()
        result = run_script(request, executable, timeout=timeout, display=True)
    result["seconds"] = clock.perf_counter() - started
    return result


def animate(
    path: str | Path,
    gif: str | Path,
    *,
    frames: int = ANIMATION_FRAMES,
    frame_seconds: float = 0.1,
    size: tuple[int, int] = ANIMATION_SIZE,
    min_J_range: tuple[float, float] = MIN_J_RANGE,
    body_opacity: float = BODY_OPACITY,
    title: str | None = None,
    obstacles: Sequence[Any] = (),
    executable: str | Path | None = None,
    timeout: float = 1800.0,
) -> dict[str, Any]:
    """Write an animated GIF of a run: :func:`render`'s picture at up to ``frames`` steps.

    The steps are spread evenly over the run (its step log next to ``path``: every step if
    there are no more than ``frames``); the camera stays fixed, framing the body (and the
    obstacles near it) at every one of them. Moving obstacles are sampled at every frame.

    Returns
    -------
    dict
        ``gif`` (absolute), ``times`` (of the frames), ``frames``, ``bytes`` and ``seconds``.
    """
    source = _existing_xdmf(path)
    request = _picture_request(source, size, min_J_range, 1.0, body_opacity, title)
    gif = Path(gif).resolve()
    if gif.suffix.lower() != ".gif":
        raise ValueError(f"gif must end in .gif, got {str(gif)!r}")
    if int(frames) != frames or frames < 2:
        raise ValueError(f"frames must be a whole number >= 2, got {frames}")
    if not (math.isfinite(frame_seconds) and frame_seconds > 0.0):
        raise ValueError(f"frame_seconds must be a number > 0, got {frame_seconds}")
    gif.parent.mkdir(parents=True, exist_ok=True)
    times, _ = step_table(source)
    steps = sorted(set(np.linspace(0, len(times) - 1, min(frames, len(times))).round().astype(int)))
    request.update(command="animate", times=[times[step] for step in steps])
    started = clock.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        request["png_pattern"] = str(Path(folder) / "frame-{index:04d}.png")
        if obstacles:
            moving = any(getattr(obstacle, "motion", None) is not None for obstacle in obstacles)
            bounds = body_bounds(source, steps)
            # Grouped at the first frame for all frames: a surface keeps its pipeline.
            groups = split_obstacles(obstacles, times[steps[0]], *bounds, VIEW_DIRECTION)
            request["obstacles"] = [
                sample_groups(groups, times[step], *bounds, Path(folder) / f"gap-{index}")
                for index, step in enumerate(steps if moving else steps[:1])
            ]
            request["cutaway_origin"] = (0.5 * (bounds[0] + bounds[1])).tolist()
        result = run_script(request, executable, timeout=timeout, display=True)
        _write_gif(result["pngs"], gif, frame_seconds)
    return {
        "gif": str(gif),
        "times": result["times"],
        "frames": len(result["pngs"]),
        "bytes": gif.stat().st_size,
        "seconds": clock.perf_counter() - started,
    }


def _write_gif(pngs: Sequence[str], gif: Path, frame_seconds: float) -> None:
    from PIL import Image

    images = [Image.open(png).convert("RGB") for png in pngs]
    # One palette for every frame, made from all of them (the red of cells inverted in a few
    # frames only included): no flicker between frames, no colour lost.
    width, height = images[0].size
    montage = Image.new("RGB", (width, height * len(images)))
    for index, image in enumerate(images):
        montage.paste(image, (0, index * height))
    palette = montage.quantize(colors=255, method=Image.Quantize.MEDIANCUT)
    frames = [image.quantize(palette=palette, dither=Image.Dither.NONE) for image in images]
    frames[0].save(
        gif,
        save_all=True,
        append_images=frames[1:],
        duration=round(1000 * frame_seconds),
        loop=0,
        optimize=True,
    )


def _picture_request(
    source: Path,
    size: tuple[int, int],
    min_J_range: tuple[float, float],
    warp_scale: float,
    body_opacity: float,
    title: str | None,
) -> dict[str, Any]:
    """Check the picture's options; return the request's common part."""
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
    name = source.stem if title is None else title
    return {
        "path": str(source),
        "size": [width, height],
        "displacement": "displacement",
        "warp_scale": float(warp_scale),
        "colour_array": "min_J",
        "colour_title": "min J",
        "colour_map": MIN_J_COLOUR_MAP,
        "colour_range": [low, high],
        "body_opacity": float(body_opacity),
        "inverted_colour": list(INVERTED_COLOUR),
        "obstacle_colour": list(OBSTACLE_COLOUR),
        "obstacle_opacity": OBSTACLE_OPACITY,
        "view_direction": list(VIEW_DIRECTION),
        # Braces of the name must not reach str.format in the script.
        "label": name.replace("{", "{{").replace("}", "}}")
        + "\nt = {time:.6g}\nsize {extent}\ninverted cells (red): {inverted}",
    }


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
    paths: Sequence[str | Path],
    output_directory: str | Path,
    *,
    obstacles_of: Callable[[Path], Sequence[Any]] | None = None,
    animation: bool = False,
    **options: Any,
) -> list[dict[str, Any]]:
    """Render one picture per run into ``output_directory/<run directory name>/<run name>.png``.

    Parameters
    ----------
    paths
        Run directories or ``.xdmf`` files (see :func:`run_files`).
    output_directory
        Where the pictures go, one subdirectory per directory of runs, so that runs of the same
        name in different directories (``results/<scene>/``) do not overwrite each other.
    obstacles_of
        Returns the obstacles to draw for a run's directory (e.g.
        :func:`dolfinx_invertible.scenes.pictures.run_obstacles`); None draws none.
    animation
        An animated GIF (:func:`animate`) instead of a picture (``<run name>.gif``).
    **options
        Keyword options of :func:`render` (or :func:`animate`).

    Returns
    -------
    list of dict
        What :func:`render` (:func:`animate`) returned for each run, in order.
    """
    output_directory = Path(output_directory)
    results = []
    for path in run_files(paths):
        obstacles = obstacles_of(path.parent) if obstacles_of is not None else ()
        target = output_directory / path.resolve().parent.name / path.stem
        if animation:
            results.append(animate(path, target.with_suffix(".gif"), obstacles=obstacles,
                                   **options))  # fmt: skip
        else:
            results.append(render(path, target.with_suffix(".png"), obstacles=obstacles,
                                  **options))  # fmt: skip
    return results


def _existing_xdmf(path: str | Path) -> Path:
    path = Path(path)
    if path.suffix != ".xdmf":
        raise ValueError(f"expected an .xdmf file, got {str(path)!r}")
    if not path.is_file():
        raise FileNotFoundError(f"no such XDMF file: {str(path)!r}")
    # Absolute: ParaView 5.11 misplaces the .h5 file of a bare relative name (module docstring).
    return path.resolve()
