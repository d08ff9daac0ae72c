"""Obstacles sampled for ParaView and the steps a picture shows, against independent values.

The gaps of a sphere and a plane are written out here (|x − c| − r, n·x − o), the step chosen
for each keyword is worked out by hand from a small step log, and the box of a deformed body
from a series whose displacement is known.
"""

from __future__ import annotations

import json

from mpi4py import MPI

import dolfinx
import numpy as np
import pytest

from dolfinx_invertible import vector_function_space
from dolfinx_invertible.contact import HalfSpace, RigidMotion, Sphere
from dolfinx_invertible.io.paraview.obstacles import (
    body_bounds,
    resolve_time,
    sample_obstacles,
    step_table,
)
from dolfinx_invertible.io.xdmf import ResultWriter


def _grid_points(grid):
    axes = [
        origin + spacing * np.arange(count)
        for origin, spacing, count in zip(
            grid["origin"], grid["spacing"], grid["dimensions"], strict=True
        )
    ]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)


def test_the_sampled_gap_is_the_nearest_obstacle_at_that_time(tmp_path):
    centre = np.array([0.3, -0.2, 1.5])
    # The ball moves up by t along z; the ground z = 0 stays.
    motion = RigidMotion(3, translation=lambda t: (0.0, 0.0, t))
    obstacles = [Sphere(centre, 0.4, motion=motion), HalfSpace((0.0, 0.0, 1.0), 0.0)]
    low, high = np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.5, 2.0])
    for time in (0.0, 0.7):
        grid = sample_obstacles(obstacles, time, low, high, tmp_path / f"gap-{time}.npy", points=21)
        values = np.load(grid["values"])
        assert list(values.shape) == grid["dimensions"]
        x = _grid_points(grid)
        moved = centre + [0.0, 0.0, time]
        expected = np.minimum(np.linalg.norm(x - moved, axis=-1) - 0.4, x[..., 2])
        assert np.allclose(values, np.minimum(expected, values.max()), atol=1e-12)
        # The box reaches beyond the body on every side, by the same margin.
        start, stop = x.reshape(-1, 3).min(axis=0), x.reshape(-1, 3).max(axis=0)
        assert np.all(start < low) and np.all(stop >= high - 1e-12)
        assert np.allclose(low - start, (low - start)[0])


def test_the_step_shown_is_chosen_as_paraview_chooses_it(tmp_path):
    log = tmp_path / "run.jsonl"
    records = [(0.0, 0), (0.1, 2), (0.2, 5), (0.3, 5), (0.4, 1)]
    log.write_text(
        "".join(
            json.dumps({"step": i, "time": t, "inverted_cells": n}) + "\n"
            for i, (t, n) in enumerate(records)
        )  # fmt: skip
    )
    times, inverted = step_table(tmp_path / "run.xdmf")
    assert times == [0.0, 0.1, 0.2, 0.3, 0.4] and inverted == [0, 2, 5, 5, 1]
    assert resolve_time(times, inverted, "most-inverted") == 2  # the first of the most
    assert resolve_time(times, inverted, "first") == 0
    assert resolve_time(times, inverted, "last") == 4
    assert resolve_time(times, inverted, 0.26) == 3
    assert resolve_time(times, [0] * 5, "most-inverted") == 4  # none inverted: the last
    with pytest.raises(ValueError, match="outside the time steps"):
        resolve_time(times, inverted, 0.5)
    with pytest.raises(FileNotFoundError, match="no step log"):
        step_table(tmp_path / "other.xdmf")


def test_the_body_box_follows_the_displacement(tmp_path):
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_SELF, 2, 2, 2)
    u = dolfinx.fem.Function(vector_function_space(mesh, 1))
    path = tmp_path / "run.xdmf"
    with ResultWriter(path, mesh) as writer:
        for step, shift in enumerate([(0.0, 0.0, 0.0), (0.5, 0.0, -1.0), (0.0, 2.0, 0.0)]):
            u.interpolate(lambda x, s=shift: np.stack([s[0] + 0 * x[0], s[1] + 0 * x[0],
                                                       s[2] + 0.5 * x[2]]))  # fmt: skip
            writer.write(float(step), u)
    low, high = body_bounds(path, [1])
    assert np.allclose(low, [0.5, 0.0, -1.0]) and np.allclose(high, [1.5, 1.0, 0.5])
    low, high = body_bounds(path, [1, 2])
    assert np.allclose(low, [0.0, 0.0, -1.0]) and np.allclose(high, [1.5, 3.0, 1.5])
