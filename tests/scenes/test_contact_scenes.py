"""The contact scenes at a small size: each runs without a boundary vertex ever inside an
obstacle, keeps a positive gap, and shows what it is there for (the cube settles at the bowl's
bottom; the ball inverts cells that recover; the body passes the funnel's throat; the body gets
past the cylinders).
"""

from __future__ import annotations

import json
import math

from mpi4py import MPI

import numpy as np
import pytest

from dolfinx_invertible.scenes import Parameters, get_scene, run_scene


def run(name, comm=MPI.COMM_WORLD, directory=None, **overrides):
    scene = get_scene(name)
    values = dict(scene.defaults)
    values.update(overrides)
    return run_scene(scene, Parameters(**values), output=directory, comm=comm)


def check_contact(summary):
    assert summary["completed"] and summary["converged"], summary.get("reason")
    assert summary["penetrations"] == 0
    assert summary["min_gap"] > 0.0
    # The body did touch: some step came within the barrier distance.
    assert summary["min_gap"] < summary["barrier_distance"]


# -- the scenes ------------------------------------------------------------------------------
def test_bowl_drop_settles_at_the_bottom(directory):
    summary = run("bowl-drop", directory=directory / "bowl", resolution=2, dt=0.02, t_end=2.0)
    check_contact(summary)
    size = summary["parameters"]["size"]
    centre = np.array(summary["final_centre"])
    # At rest: the centre half a side above the bowl's bottom (z = −1), give or take the
    # sphere's curvature under its bottom face; below where a rigid cube would rest on its
    # bottom corners, as the soft one sags into the bowl.
    assert centre[2] == pytest.approx(-1.0 + 0.5 * size, abs=0.05)
    assert centre[2] < summary["rest_centre_height"]
    np.testing.assert_allclose(centre[:2], 0.0, atol=0.01)
    assert summary["final_kinetic_energy"] < 1e-4 * summary["peak_kinetic_energy"]
    # It started in the middle: the corners √3·size/2 from the centre of the bowl.
    history = np.load(directory / "bowl" / "contact.npy")
    assert history[0, 1] == pytest.approx(1.0 - math.sqrt(3.0) * 0.5 * size)
    assert len(history) == summary["steps"] + 1


def test_ball_hit_inverts_cells_that_recover_after_it_left():
    summary = run("ball-hit", resolution=4, dt=0.004, t_end=0.16)
    check_contact(summary)
    assert summary["max_inverted_during_hit"] > 0
    assert summary["final_inverted"] == 0
    assert summary["time"] > summary["ball_leaves"]


def test_tight_tube_pushes_the_body_past_the_throat():
    summary = run("tight-tube", resolution=2, dt=0.005)
    check_contact(summary)
    # Every node of the body lies beyond the throat, which is a third of its width.
    assert summary["final_low"][0] > summary["throat_x"]
    assert summary["throat_radius"] == pytest.approx(summary["parameters"]["size"] / 6.0)
    assert summary["time"] > summary["push_time"]
    # Squeezed through inversion on the way. (Whether the body then finds its shape again
    # depends on the path at this coarse size, where the throat is less than two cells
    # across; at the default size it does.)
    assert summary["max_inverted"] > 0


def test_gap_squeeze_gets_the_body_past_the_cylinders():
    summary = run("gap-squeeze", resolution=3, dt=0.004, t_end=0.1)
    check_contact(summary)
    # Every node lies below the plane of the cylinders' axes, the nip.
    assert summary["final_high"][2] < 0.0
    assert summary["max_inverted"] > 0 and summary["final_inverted"] == 0


@pytest.mark.mpi
def test_bowl_drop_distributed_equals_serial():
    options = dict(resolution=3, dt=0.02, t_end=0.6)
    distributed = run("bowl-drop", comm=MPI.COMM_WORLD, **options)
    serial = run("bowl-drop", comm=MPI.COMM_SELF, **options)
    assert distributed["ranks"] == MPI.COMM_WORLD.size and serial["ranks"] == 1
    assert distributed["penetrations"] == serial["penetrations"] == 0
    assert distributed["min_gap"] == pytest.approx(serial["min_gap"], rel=1e-6)
    np.testing.assert_allclose(distributed["final_centre"], serial["final_centre"], atol=1e-8)
    assert distributed["steps"] == serial["steps"]


def test_contact_scenes_write_their_record(directory):
    summary = run("gap-squeeze", directory=directory / "gap", resolution=2, dt=0.004, t_end=0.02)
    if MPI.COMM_WORLD.rank == 0:
        written = json.loads((directory / "gap" / "summary.json").read_text())
        assert written["min_gap"] == summary["min_gap"]
        history = np.load(directory / "gap" / "contact.npy")
        assert history.shape == (summary["steps"] + 1, 7)
        assert np.min(history[:, 1]) == pytest.approx(summary["min_gap"])


def test_gap_squeeze_rollers_pull_the_body_through_by_friction():
    """The rollers turn down through the nip: with friction the body leaves faster and lower."""
    options = dict(resolution=4, t_end=0.1)
    frictionless = run("gap-squeeze", comm=MPI.COMM_SELF, **options)
    gripped = run("gap-squeeze", comm=MPI.COMM_SELF, friction=0.5, **options)
    for summary in (frictionless, gripped):
        check_contact(summary)
    assert gripped["final_centre"][2] < frictionless["final_centre"][2] - 0.02
    assert gripped["final_kinetic_energy"] > frictionless["final_kinetic_energy"]


def test_friction_needs_contact():
    with pytest.raises(ValueError, match="--friction: the collapse scene has no contact"):
        run("collapse", friction=0.3)
