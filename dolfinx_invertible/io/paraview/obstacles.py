"""The analytic obstacles of a run, sampled for ParaView, and the run's steps as its log has them.

ParaView draws an obstacle as the zero contour of the smallest gap to any obstacle, sampled on
a grid around the body (:func:`sample_obstacles`): one construction for every shape (a bowl,
a ball, planes, cylinders, a funnel) and for moving ones, at the time shown. The obstacles are
objects with ``gap(x, t)`` (:mod:`dolfinx_invertible.contact`); which time a picture shows is
decided here from the run's step log (:func:`step_table`, :func:`resolve_time`), so that a
moving obstacle is sampled where it was at that step.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "body_bounds",
    "hides_the_body",
    "resolve_time",
    "sample_groups",
    "sample_obstacles",
    "split_obstacles",
    "step_table",
]

#: Grid points along the longest side of the sampled box.
GRID_POINTS = 64
#: The sampled box reaches this share of the body's largest extent beyond the body.
MARGIN = 0.6


def step_table(xdmf: Path) -> tuple[list[float], list[int]]:
    """Return the time and the inverted cells of every step in the run's step log.

    The log is ``xdmf`` with the suffix ``.jsonl`` (:class:`~dolfinx_invertible.io.xdmf.
    ResultWriter`'s); ``FileNotFoundError`` if it is missing.
    """
    log = xdmf.with_suffix(".jsonl")
    if not log.is_file():
        raise FileNotFoundError(f"no step log {log} next to {xdmf} (needed to place obstacles)")
    records = [json.loads(line) for line in log.read_text(encoding="utf-8").splitlines()]
    return [float(r["time"]) for r in records], [int(r.get("inverted_cells") or 0) for r in records]


def resolve_time(times: Sequence[float], inverted: Sequence[int], wanted: float | str) -> int:
    """Return the index of the step to show, as ParaView's side chooses it.

    ``wanted``: a number (the nearest step), ``"first"``, ``"last"`` or ``"most-inverted"``
    (the first step with the most inverted cells, the last if none has any).
    """
    if wanted == "first":
        return 0
    if wanted == "last":
        return len(times) - 1
    if wanted == "most-inverted":
        most = max(inverted)
        return inverted.index(most) if most > 0 else len(times) - 1
    slack = 1e-9 * max(1.0, abs(times[0]), abs(times[-1]))
    if not times[0] - slack <= wanted <= times[-1] + slack:
        raise ValueError(f"time {wanted} lies outside the time steps, {times[0]} to {times[-1]}")
    return int(np.argmin(np.abs(np.asarray(times) - wanted)))


def body_bounds(xdmf: Path, steps: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """Return a box around the deformed body at the given steps (reference box + displacement).

    The reference points' box widened by the displacement's component ranges: independent of
    the order of the nodes, so also right for the steps of a resumed run, which carry their own
    mesh numbering.
    """
    import meshio

    with meshio.xdmf.TimeSeriesReader(str(xdmf)) as reader:
        points, _ = reader.read_points_cells()
        low, high = points.min(axis=0), points.max(axis=0)
        shift_low, shift_high = np.full(3, np.inf), np.full(3, -np.inf)
        for step in steps:
            _, point_data, _ = reader.read_data(step)
            displacement = np.asarray(point_data["displacement"])
            shift_low = np.minimum(shift_low, displacement.min(axis=0))
            shift_high = np.maximum(shift_high, displacement.max(axis=0))
    return low + shift_low, high + shift_high


def sample_obstacles(
    obstacles: Sequence[Any],
    time: float,
    low: np.ndarray,
    high: np.ndarray,
    path: Path,
    *,
    points: int = GRID_POINTS,
) -> dict[str, Any]:
    """Write the smallest gap to the obstacles at ``time`` on a grid around [low, high].

    Returns the grid as the ParaView script reads it: ``origin``, ``spacing``, ``dimensions``
    and ``values``, the ``.npy`` file at ``path`` (an array indexed by the x, y, z points).
    """
    extent = float(np.max(high - low))
    margin = MARGIN * max(extent, 1e-12)
    start, stop = low - margin, high + margin
    spacing = float(np.max(stop - start)) / (points - 1)
    dimensions = [int(np.ceil((b - a) / spacing)) + 1 for a, b in zip(start, stop, strict=True)]
    axes = [a + spacing * np.arange(n) for a, n in zip(start, dimensions, strict=True)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    gap = np.full(len(grid), np.inf)
    for obstacle in obstacles:
        gap = np.minimum(gap, obstacle.gap(grid, time))
    # Far from every obstacle the gap is large; a finite cap keeps the contour filter happy.
    gap = np.minimum(gap, 2.0 * float(np.max(stop - start)))
    np.save(path, gap.reshape(dimensions))
    return {
        "origin": [float(value) for value in start],
        "spacing": [spacing] * 3,
        "dimensions": dimensions,
        "values": str(path),
    }


def hides_the_body(
    obstacle: Any, time: float, low: np.ndarray, high: np.ndarray, view_direction: np.ndarray
) -> bool:
    """Return whether the obstacle's surface lies between the camera and the body's path.

    Along the ray from the middle of the box [low, high] towards the camera, out to the
    sampled box's edge, the gap changes sign where the ray passes the surface (out of a bowl
    or a tube; a ball the ray misses, the ground below, never).
    """
    centre = 0.5 * (low + high)
    direction = np.asarray(view_direction, dtype=float)
    direction = direction / np.linalg.norm(direction)
    reach = (0.5 + MARGIN) * float(np.linalg.norm(high - low)) + 1e-12
    ray = centre + np.linspace(0.0, reach, 201)[:, None] * direction
    gap = obstacle.gap(ray, time)
    return bool(np.any(np.sign(gap[1:]) != np.sign(gap[:-1])))


def split_obstacles(
    obstacles: Sequence[Any],
    time: float,
    low: np.ndarray,
    high: np.ndarray,
    view_direction: np.ndarray,
) -> dict[str, list]:
    """Return the obstacles in two groups: ``"cut"`` (hiding the body) and ``"whole"``."""
    groups: dict[str, list] = {"cut": [], "whole": []}
    for obstacle in obstacles:
        hidden = hides_the_body(obstacle, time, low, high, view_direction)
        groups["cut" if hidden else "whole"].append(obstacle)
    return {name: members for name, members in groups.items() if members}


def sample_groups(
    groups: dict[str, list],
    time: float,
    low: np.ndarray,
    high: np.ndarray,
    stem: Path,
    *,
    points: int = GRID_POINTS,
) -> dict[str, dict[str, Any]]:
    """Sample each group (:func:`sample_obstacles`) into ``stem`` + ``-<group>.npy``."""
    return {
        name: sample_obstacles(
            members, time, low, high, Path(f"{stem}-{name}.npy"), points=points
        )  # fmt: skip
        for name, members in groups.items()
    }
