"""The scenes with contact between bodies (cubes-in-bowl) and self-contact (``--self-contact``).

No two surface triangles cross on any written step: checked on the written XDMF with a NumPy
edge–triangle test (tests/contact/surface_crossings.py), independent of the barrier and of IPC
Toolkit. The summaries and step logs carry ``min_distance`` and ``intersections``.
"""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

from dolfinx_invertible.contact import SurfaceIntersectionError
from dolfinx_invertible.meshes.blocks import cubes_mesh
from dolfinx_invertible.scenes import Parameters, Scene, get_scene, run_scene

sys.path.insert(0, str(Path(__file__).parents[1] / "contact"))
sys.path.insert(0, str(Path(__file__).parents[1]))
from dolfinx_helpers import read_series  # noqa: E402
from surface_crossings import boundary_triangles, crossing_pairs  # noqa: E402


def run(name, comm=MPI.COMM_WORLD, directory=None, **overrides):
    scene = get_scene(name)
    values = dict(scene.defaults)
    values.update(overrides)
    return run_scene(scene, Parameters(**values), output=directory, comm=comm)


def check_written_surfaces(directory, name, comm=MPI.COMM_WORLD):
    """No crossing surface triangles on any written step; the log has the contact columns."""
    if comm.rank == 0:
        points, cells, steps = read_series(Path(directory) / f"{name}.xdmf")
        triangles = boundary_triangles(cells[0].data)
        assert len(steps) > 2
        for time, point_data, _ in steps:
            positions = points + point_data["displacement"][:, : points.shape[1]]
            assert crossing_pairs(positions, triangles) == 0, f"surfaces cross at t = {time}"
        log = [json.loads(line) for line in (Path(directory) / f"{name}.jsonl").open()]
        assert len(log) == len(steps)
        assert all(row["intersections"] == 0 and row["min_distance"] > 0 for row in log)
        return log
    return None


@pytest.mark.mpi
def test_cubes_in_bowl_pile_up_without_crossing(directory):
    summary = run("cubes-in-bowl", directory=directory, resolution=1, t_end=0.7)
    assert summary["completed"] and summary["converged"], summary.get("reason")
    assert summary["intersections"] == 0 and summary["min_distance"] > 0.0
    assert summary["penetrations"] == 0 and summary["min_gap"] > 0.0
    log = check_written_surfaces(directory, "cubes-in-bowl")
    if MPI.COMM_WORLD.rank == 0:
        # The cubes did meet: their surfaces came far closer than at the start.
        assert min(row["min_distance"] for row in log) < 0.05 * log[0]["min_distance"]
        # κ never falls and at most doubles a step, within IPC's bound of 100 times its start;
        # the summary reports the last.
        stiffness = [row["body_barrier_stiffness"] for row in log]
        pairs = itertools.pairwise(stiffness)
        assert all(earlier <= later <= 2.0 * earlier for earlier, later in pairs)
        assert stiffness[-1] <= 100.0 * stiffness[0]
        assert summary["body_barrier_stiffness"] == stiffness[-1]


@pytest.mark.mpi
def test_cubes_in_bowl_distributed_equals_serial_through_the_first_impacts():
    # Through the first impacts (from t = 0.42 s on), before the cuts of a later pile-up step.
    options = dict(resolution=1, t_end=0.5)
    distributed = run("cubes-in-bowl", comm=MPI.COMM_WORLD, **options)
    serial = run("cubes-in-bowl", comm=MPI.COMM_SELF, **options)
    assert distributed["steps"] == serial["steps"]
    assert distributed["newton_iterations"] == serial["newton_iterations"]
    assert distributed["min_distance"] == pytest.approx(serial["min_distance"], rel=1e-6)
    np.testing.assert_allclose(distributed["final_centre"], serial["final_centre"], atol=1e-9)


@pytest.mark.mpi
def test_links_catch_each_other_without_crossing(directory):
    summary = run("links", directory=directory, t_end=0.3)
    assert summary["completed"] and summary["converged"], summary.get("reason")
    assert summary["intersections"] == 0 and summary["min_distance"] > 0.0
    check_written_surfaces(directory, "links")
    # Each ring falls its clearance, is caught by the one above and bounces (about 8 cm at
    # the lowest); one that slipped through would have fallen freely by 0.44 m at t = 0.3 s.
    assert summary["final_lowest"] > summary["initial_lowest"] - 0.15


@pytest.mark.mpi
def test_collapse_with_self_contact_recovers_without_crossing(directory):
    summary = run("collapse", directory=directory, resolution=3, self_contact=True)
    assert summary["recovered"], summary
    assert summary["intersections"] == 0 and summary["min_distance"] > 0.0
    check_written_surfaces(directory, "collapse")


def test_self_contact_off_writes_no_contact_figures():
    summary = run("collapse", resolution=2, t_end=0.02)
    assert "min_distance" not in summary and "intersections" not in summary


def test_scatter_refuses_self_contact_with_the_reason():
    with pytest.raises(ValueError, match="--self-contact: .* already passing through itself"):
        run("scatter", resolution=2, self_contact=True)
    completed = subprocess.run(
        [sys.executable, "-m", "dolfinx_invertible", "run", "scatter", "--self-contact",
         "--quiet", "--out", "unused"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert completed.returncode == 2 and "already passing through itself" in completed.stderr


def test_one_body_scenes_refuse_a_count():
    with pytest.raises(ValueError, match="--count: the collapse scene has one body"):
        run("collapse", count=3)


def test_cubes_that_do_not_fit_the_bowl_are_refused():
    with pytest.raises(ValueError, match="do not fit into the bowl"):
        run("cubes-in-bowl", count=60)


class _Overlapping(Scene):
    """Two cubes that intersect at the start."""

    name = "overlapping"
    several_bodies = True

    def create_mesh(self):
        return cubes_mesh(self.comm, np.array([[0, 0, 0], [0.3, 0.2, 0.8]]), 1.0, 2)


@pytest.mark.mpi
def test_bodies_crossing_at_the_start_are_refused_before_the_first_step(directory):
    output = Path(directory) / "overlapping"
    with pytest.raises(SurfaceIntersectionError, match=r"at t = 0: body [01]'s surface facet"):
        run_scene(_Overlapping, Parameters(t_end=0.02), output=output)
    assert not (output / "summary.json").exists()


def test_cubes_in_bowl_with_friction_pile_without_crossing(directory):
    summary = run("cubes-in-bowl", directory=directory, resolution=1, t_end=0.6, friction=0.3)
    assert summary["completed"] and summary["converged"], summary.get("reason")
    assert summary["intersections"] == 0 and summary["min_distance"] > 0.0
    check_written_surfaces(directory, "cubes-in-bowl")
