"""Every scene at a small size: it runs, writes its output, and shows what it is there to show.

Each check is a property the scene exists for (recovery, inversion or not, the published tip
displacement within discretisation error, energy conservation ordering of the integrators), so
each can fail; and each test also checks that the scene did what it is for (the load reached,
the body moved as prescribed, the relaxation ran from the declared start), so that a run in
which nothing happened (no steps, no displacement) fails it too. Where the paper contrasts
models, the contrasting model runs beside it. The expected values come from the scenes' own
constants. Collapse and scatter also run under MPI.
"""

from __future__ import annotations

import json

from mpi4py import MPI

import numpy as np
import pytest

from dolfinx_invertible.scenes import SCENES, Parameters, RunObserver, get_scene, run_scene
from dolfinx_invertible.scenes.cook_membrane import REFERENCE_TIP_DISPLACEMENT
from dolfinx_invertible.scenes.outcome import REST_TOLERANCE

SUMMARY_KEYS = {
    "scene", "model", "extension", "parameters", "ranks", "dofs", "steps", "completed",
    "converged", "nan_encountered", "final_min_J", "final_inverted", "max_inverted",
    "newton_iterations", "linear_iterations", "wall_time_s", "svd_share", "stepping", "outcome",
    "solver", "failed_attempts", "failed_attempts_wall_time",
}  # fmt: skip


#: How far a pressing plate may leave the depth it prescribes, relative to the body's size
#: (:class:`~dolfinx_invertible.scenes.loading.PressingPlate`: rigid to a fraction of a percent).
PLATE_TOLERANCE = 0.01


def run(name, directory=None, *, observers=(), **overrides):
    scene = get_scene(name)
    values = dict(scene.defaults)
    values.update(overrides)
    return run_scene(scene, Parameters(**values), output=directory, observers=observers)


class Nodes(RunObserver):
    """What ``measure(X, x)`` says of the body at the start and after every step.

    X and x are the reference and the current positions of the displacement's nodes (n × d,
    every rank's owned nodes gathered on every rank, in the same order). Only ``run.u``,
    ``run.mesh`` and ``run.time`` are read.
    """

    def __init__(self, measure):
        self.measure = measure
        self.times: list[float] = []
        self.values: list = []

    def start(self, run):
        space = run.u.function_space
        self._owned = space.dofmap.index_map.size_local
        self._dim = run.mesh.geometry.dim
        self._comm = run.mesh.comm
        coordinates = space.tabulate_dof_coordinates()[: self._owned, : self._dim]
        self._reference = np.concatenate(self._comm.allgather(coordinates))
        self._take(run)

    def step(self, run):
        self._take(run)

    def _take(self, run):
        local = run.u.x.array[: self._owned * self._dim].reshape(-1, self._dim)
        displacement = np.concatenate(self._comm.allgather(local))
        self.times.append(run.time)
        self.values.append(self.measure(self._reference, self._reference + displacement))

    def between(self, start: float, end: float) -> list:
        """Return the values of the steps at times start <= t <= end."""
        return [v for t, v in zip(self.times, self.values, strict=True) if start <= t <= end]


def extent(x, axis):
    """Return the length of the points' span along an axis."""
    return float(x[:, axis].max() - x[:, axis].min())


def signed_singular_values(F):
    """Return the singular values of F, largest first, the sign of det F on the smallest."""
    sigma = np.linalg.svd(F, compute_uv=False)
    sigma[-1] *= np.sign(np.linalg.det(F))
    return sigma


def gradient(X, x):
    """Return F of the affine map taking the d + 1 points X (rows) to x."""
    return (x[1:] - x[0]).T @ np.linalg.inv((X[1:] - X[0]).T)


@pytest.fixture(scope="module")
def armadillo_cache(tmp_path_factory):
    """One mesh cache for the tests of the armadillo-like solid: gmsh meshes it once."""
    return tmp_path_factory.mktemp("armadillo-cache")


def test_every_scene_is_registered_with_a_description():
    for name in SCENES:
        scene = get_scene(name)
        assert scene.name == name and scene.description and scene.figure
    with pytest.raises(ValueError, match="unknown scene"):
        get_scene("no-such-scene")


@pytest.mark.mpi
@pytest.mark.parametrize("name", ["collapse", "scatter"])
def test_relaxation_scenes_recover_and_write_their_output(name, directory):
    import meshio

    from dolfinx_invertible.scenes.collapse import SCALE
    from dolfinx_invertible.scenes.scatter import BOX

    t_end = 0.5
    summary = run(name, directory / name, resolution=3, t_end=t_end)
    assert SUMMARY_KEYS <= set(summary)
    assert summary["ranks"] == MPI.COMM_WORLD.size
    assert summary["completed"] and summary["converged"] and not summary["nan_encountered"]
    assert summary["steps"] > 0 and summary["time"] == pytest.approx(t_end)
    assert summary["outcome"] == "recovered", summary
    assert summary["recovered"] and summary["rest_distance"] < REST_TOLERANCE
    assert summary["final_inverted"] == 0
    if name == "scatter":
        assert summary["max_inverted"] > 0  # it started tangled
    else:
        assert summary["min_J_reached"] == pytest.approx(SCALE**3)  # it started collapsed
    MPI.COMM_WORLD.barrier()
    if MPI.COMM_WORLD.rank == 0:
        folder = directory / name
        written = json.loads((folder / "summary.json").read_text())
        assert written["outcome"] == summary["outcome"]
        lines = (folder / f"{name}.jsonl").read_text().splitlines()
        assert len(lines) == summary["steps"] + 1  # the initial state too
        # Every cut is a failed attempt, logged with the step that followed it.
        failed = [a for line in lines for a in json.loads(line).get("failed_attempts", [])]
        assert len(failed) == summary["failed_attempts"] == summary["stepping"]["cuts"]
        assert sum(a["wall_time"] for a in failed) == pytest.approx(
            summary["failed_attempts_wall_time"]
        )
        assert summary["failed_attempts_wall_time"] < summary["wall_time_s"]
        if name == "scatter":
            assert failed and all(a["stage"] and a["step_size"] > 0 for a in failed)
        first, last = json.loads(lines[0]), json.loads(lines[-1])
        assert first["time"] == 0.0 and last["time"] == pytest.approx(t_end)
        assert last["inverted_cells"] == 0
        if name == "scatter":
            assert first["inverted_cells"] > 0
        else:
            assert first["min_J"] == pytest.approx(SCALE**3)  # F = SCALE I in every cell
        assert (folder / f"{name}.xdmf").exists() and (folder / f"{name}.h5").exists()
        with meshio.xdmf.TimeSeriesReader(str(folder / f"{name}.xdmf")) as reader:
            points, _ = reader.read_points_cells()
            assert reader.num_steps == summary["steps"] + 1
            time_first, start, _ = reader.read_data(0)
            time_last, end, _ = reader.read_data(reader.num_steps - 1)
        assert time_first == 0.0 and time_last == pytest.approx(t_end)
        size = summary["parameters"]["size"]
        # The written start is the scene's: the cube shrunk by SCALE about its centre, or every
        # vertex thrown into the box of edge BOX.
        scattered = points + start["displacement"][:, :3]
        spans = np.ptp(scattered, axis=0)
        if name == "scatter":
            assert (spans <= BOX * size + 1e-12).all()
        else:
            assert spans == pytest.approx(SCALE * size)
        # The written end is the rest shape up to a rigid motion: every distance between two
        # nodes as at rest, to twice the rest distance (each node is within it of its place).
        relaxed = points + end["displacement"][:, :3]
        diameter = np.linalg.norm(np.ptp(points, axis=0))
        at_rest = np.linalg.norm(points[:, None] - points[None], axis=-1)
        now = np.linalg.norm(relaxed[:, None] - relaxed[None], axis=-1)
        assert np.abs(now - at_rest).max() <= 2.0 * summary["rest_distance"] * diameter + 1e-12


def test_armadillo_like_solid_is_a_few_thousand_tetrahedra_with_a_hole(
    armadillo_cache, monkeypatch
):
    monkeypatch.setenv("DOLFINX_INVERTIBLE_CACHE", str(armadillo_cache))
    from dolfinx_invertible.meshes import armadillo_like

    mesh = armadillo_like.mesh(MPI.COMM_WORLD, resolution=3)
    cells = mesh.topology.index_map(3).size_global
    assert 1000 < cells < 10000
    # The through hole: no vertex lies on the hole's axis inside the torso.
    x = mesh.geometry.x
    on_axis = (np.abs(x[:, 0] - x[:, 0].mean()) < 0.02) & (np.abs(x[:, 2] - x[:, 2].mean()) < 0.02)
    assert cells and not on_axis[np.abs(x[:, 1] - x[:, 1].mean()) < 0.05].any()
    again = armadillo_like.mesh(MPI.COMM_WORLD, resolution=3)  # from the cache
    assert again.topology.index_map(3).size_global == cells


def test_scatter_runs_on_the_armadillo_like_solid(armadillo_cache, monkeypatch):
    monkeypatch.setenv("DOLFINX_INVERTIBLE_CACHE", str(armadillo_cache))
    # Its smallest cells are thrown across the whole box: the first steps must be tiny.
    t_end = 5e-5
    summary = run("scatter", mesh="armadillo-like", resolution=2, t_end=t_end, dt=1e-5)
    assert summary["completed"] and summary["max_inverted"] > 0
    # It ran to the end, and the relaxation began: released at rest, it moves, and fewer cells
    # are inverted than at the start.
    assert summary["time"] == pytest.approx(t_end) and summary["steps"] >= 5
    assert summary["kinetic_energy_final"] > 0.0
    assert summary["final_inverted"] < summary["max_inverted"]


def bar_shape(X, x):
    """Return the bar's length and its mid-section's width along y and z."""
    along = np.abs(X[:, 0] - 0.5 * np.ptp(X[:, 0]) - X[:, 0].min())
    section = np.isclose(along, along.min())
    return extent(x, 0), extent(x[section], 1), extent(x[section], 2)


@pytest.fixture(scope="module")
def stretch_bar():
    """The stretch bar with Neo-Hookean + C2 at resolution 2: its summary and its shape."""
    shape = Nodes(bar_shape)
    summary = run("stretch-bar", resolution=2, t_end=0.6, observers=[shape])
    return summary, shape


def test_stretch_bar_keeps_a_square_section_with_the_extension(stretch_bar):
    from dolfinx_invertible.scenes.stretch_bar import SLENDERNESS, STRETCH

    summary, shape = stretch_bar
    assert summary["completed"] and summary["max_inverted"] == 0
    assert abs(summary["cross_section_ratio"] - 1.0) < 0.1
    # The load was reached: the ends pulled to STRETCH times the length (over 5/6 of t_end).
    parameters = summary["parameters"]
    assert summary["time"] == pytest.approx(parameters["t_end"])
    length, width_y, width_z = shape.values[-1]
    assert shape.values[0][0] == pytest.approx(parameters["size"])
    assert length == pytest.approx(STRETCH * parameters["size"])
    # ... and the section thinned with it: at ν = 0.45 nearly keeping the volume, to within
    # 10 % of the width of an incompressible bar, width / √STRETCH; square, so both ways.
    incompressible = SLENDERNESS * parameters["size"] / np.sqrt(STRETCH)
    assert width_y == pytest.approx(incompressible, rel=0.1)
    assert width_z == pytest.approx(incompressible, rel=0.1)
    assert summary["min_J_reached"] > 0.0


def test_stretch_bar_corotated_inverts_where_the_extension_does_not(stretch_bar):
    # The paper's control (Fig. 6): plain corotated, whose primary contour Σ(σᵢ − 1) = 0
    # crosses into inversion as the bar stretches; the C2 extension has no effect on it (the
    # Taylor expansion of an energy quadratic in σ is the energy), so it runs without one.
    # Its solver stops soon after the section inverts (observed: t ≈ 0.30 of 0.6, the bar at
    # 2.96 its length, the section collapsed); two cuts end the run sooner than the default six.
    extended, _ = stretch_bar
    corotated = run("stretch-bar", model="corotated", extension="none", resolution=2,
                    t_end=0.6, max_cuts=2)  # fmt: skip
    assert corotated["max_inverted"] > 0 and corotated["min_J_reached"] < 0.0
    assert extended["max_inverted"] == 0 and extended["min_J_reached"] > 0.0


def test_a_run_stopped_early_follows_the_whole_run_schedule():
    # The ends move apart over 5/6 of t_end; a run stopped at t_stop is the whole run's start.
    from dolfinx_invertible.scenes.loading import smooth_ramp
    from dolfinx_invertible.scenes.stretch_bar import STRETCH

    scene = get_scene("stretch-bar")
    values = dict(scene.defaults) | {"resolution": 1, "t_stop": 0.02}
    reached = []

    def record(run):
        reached.append((run.time, run.u.x.array[0::3].max()))

    parameters = Parameters(**values)
    summary = run_scene(scene, parameters, output=None, on_step=record)
    assert summary["completed"] and reached[-1][0] == pytest.approx(0.02)
    pull_time = 5.0 / 6.0 * parameters.t_end
    shift = 0.5 * (STRETCH - 1.0) * parameters.size * smooth_ramp(0.02, pull_time)
    local = reached[-1][1]
    assert MPI.COMM_WORLD.allreduce(local, op=MPI.MAX) == pytest.approx(shift, rel=1e-9)
    assert Parameters(t_end=0.5, t_stop=0.8).stop_time == 0.5


def smooth_tet_amplitude(t_end: float, dt: float) -> float:
    """Return the oscillation amplitude of the tet's prescribed stretch itself.

    The largest singular value follows the top's height, 1 + (STRETCH − 1) r(t) with the
    smooth ramp r = (1 − cos(π t / t_end)) / 2; its largest second difference, at the start,
    is (STRETCH − 1) cos a (1 − cos a) with a = π dt / t_end; the amplitude is a quarter of it.
    """
    from dolfinx_invertible.scenes.tet_stretch import STRETCH

    a = np.pi * dt / t_end
    return (STRETCH - 1.0) * np.cos(a) * (1.0 - np.cos(a)) / 4.0


def test_tet_stretch_c2_moves_smoothly():
    from dolfinx_invertible.scenes.tet_stretch import STRETCH, VERTICES

    top = Nodes(lambda X, x: x[np.argmax(X[:, 2]), 2])
    summary = run("tet-stretch", t_end=1.0, dt=0.02, observers=[top])
    assert summary["completed"] and summary["max_inverted"] == 0
    # The load was reached: the top vertex at STRETCH times its height at the end.
    size = summary["parameters"]["size"]
    assert summary["time"] == pytest.approx(1.0)
    assert top.values[0] == pytest.approx(VERTICES[3, 2] * size)
    assert top.values[-1] == pytest.approx(STRETCH * VERTICES[3, 2] * size)
    # The base contracted: the volume grew (ν < 1/2) but by less than the stretch (J = STRETCH
    # times the base's area ratio).
    assert 1.0 < summary["final_min_J"] < STRETCH
    # Smooth: the singular values bend no more than the prescribed stretch does (and as much:
    # they move), not the step-to-step zigzag of the corotated kink.
    assert summary["oscillation_amplitude"] == pytest.approx(
        smooth_tet_amplitude(1.0, 0.02), rel=0.05
    )


def test_tet_stretch_corotated_inverts_where_c2_does_not():
    # Figs. 3 and 4's control: corotated draws the section to its kink σ₂ + σ₃ = 0 and through
    # it (inverted), where the singular values jump. Its solver stops there (observed at t ≈
    # 0.83 of 1.0, σ = (4.8, 0.10, −0.10)); two cuts end the run sooner than the default six.
    summary = run("tet-stretch", model="corotated", extension="none", t_end=1.0, dt=0.02,
                  max_cuts=2)  # fmt: skip
    assert summary["max_inverted"] == 1 and summary["min_J_reached"] < 0.0
    assert summary["oscillation_amplitude"] > 2.0 * smooth_tet_amplitude(1.0, 0.02)


def test_mattress_corotated_elements_invert_along_the_primary_contour(directory):
    from dolfinx_invertible.scenes.mattress_2d import STRETCH

    widths = [Nodes(lambda X, x: extent(x, 0)) for _ in range(2)]
    summary = run("mattress-2d", directory / "mattress", model="corotated", extension="none",
                  resolution=4, steps=10, nu=0.45, observers=[widths[0]])  # fmt: skip
    assert summary["completed"] and summary["max_inverted"] > 0
    if MPI.COMM_WORLD.rank == 0:
        trajectories = np.load(directory / "mattress" / "trajectories.npy")
        assert trajectories.shape == (32, 11, 2)
        assert np.allclose(trajectories[:, 0], 1.0)  # every element starts at rest
        assert (trajectories[:, -1, 1] < 0.0).any()  # some end inverted
        assert (trajectories[:, -1, 0] > 1.0).all()  # every one stretched
    summary = run("mattress-2d", resolution=4, steps=10, nu=0.45, observers=[widths[1]])
    assert summary["completed"] and summary["max_inverted"] == 0
    # Both were pulled to STRETCH times the width (the whole load, pseudo-time 1).
    assert summary["time"] == pytest.approx(1.0) and summary["steps"] == 10
    for width in widths:
        assert width.values[0] == pytest.approx(summary["parameters"]["size"])
        assert width.values[-1] == pytest.approx(STRETCH * summary["parameters"]["size"])


def test_triangles_corotated_takes_the_stretched_one_through_inversion():
    from dolfinx_invertible.scenes.triangles_2d import DEFORMATIONS

    def per_triangle(X, x):
        # Three nodes each, the triangles side by side along x in the order of DEFORMATIONS.
        order = np.argsort(X[:, 0], kind="stable").reshape(3, 3)
        return [signed_singular_values(gradient(X[k], x[k])) for k in order]

    watched = {"corotated": Nodes(per_triangle), "c2": Nodes(per_triangle)}
    corotated = run("triangles-2d", model="corotated", extension="none", t_end=0.2,
                    observers=[watched["corotated"]])  # fmt: skip
    extended = run("triangles-2d", t_end=0.2, observers=[watched["c2"]])
    assert corotated["inverted_on_the_way"] == [False, True, False]
    assert extended["inverted_on_the_way"] == [False, False, False]
    assert corotated["min_J_per_triangle"][0] < 0.0  # the first one starts inverted
    # They relaxed: from the declared starts, the inverted one uninverted, every triangle's
    # singular values within a tenth of their starting distance from rest.
    start = [signed_singular_values(F) for F in DEFORMATIONS]
    for summary, watch in ((corotated, watched["corotated"]), (extended, watched["c2"])):
        assert summary["completed"] and summary["time"] == pytest.approx(0.2)
        assert summary["final_inverted"] == 0
        for k in range(3):
            assert watch.values[0][k] == pytest.approx(start[k])
            away = np.linalg.norm(start[k] - 1.0)
            assert np.linalg.norm(watch.values[-1][k] - 1.0) < 0.1 * away


@pytest.mark.parametrize("dimension", [2, 3])
def test_cook_membrane_tip_displacement_in_two_load_steps(dimension):
    summary = run("cook-membrane", resolution=8 if dimension == 2 else 4, dimension=dimension)
    # 2 = the scene's default load steps, none cut. The cuts: regression pin: observed 0 in 2D
    # and 3D on 2026-12-04 (a5eadce) with pytest tests/scenes/test_scenes.py -k cook_membrane
    assert summary["completed"] and summary["stepping"]["steps"] == 2
    tip = summary["tip_displacement"]
    if dimension == 2:
        # Coarse P2 in plane strain: within 10 % of the converged value, below it (stiffer).
        assert 0.9 * REFERENCE_TIP_DISPLACEMENT < tip < REFERENCE_TIP_DISPLACEMENT
    else:
        # Free faces instead of plane strain: a little softer, the same order.
        assert 0.9 * REFERENCE_TIP_DISPLACEMENT < tip < 1.1 * REFERENCE_TIP_DISPLACEMENT


def tip_angle(X, x):
    """Return the angle the column's free end has turned about the axis, from y towards z."""
    tip = np.isclose(X[:, 0], X[:, 0].max())
    before = X[tip, 1:] - X[tip, 1:].mean(axis=0)
    after = x[tip, 1:] - x[tip, 1:].mean(axis=0)
    turned = before[:, 0] * after[:, 1] - before[:, 1] * after[:, 0]
    return float(np.arctan2(turned.sum(), (before * after).sum()))


def test_twisting_column_bdf2_loses_less_energy_than_backward_euler():
    from dolfinx_invertible.scenes.twisting_column import OMEGA

    turns = [Nodes(tip_angle) for _ in range(2)]
    euler = run("twisting-column", resolution=1, t_end=0.1, dt=0.01, observers=[turns[0]])
    bdf2 = run("twisting-column", resolution=1, t_end=0.1, dt=0.01, scheme="bdf2",
               observers=[turns[1]])  # fmt: skip
    exact = euler["energy_initial_exact"]
    assert euler["energy_initial"] == pytest.approx(exact, rel=0.05)
    assert 0.0 < bdf2["energy_loss"] < euler["energy_loss"]
    # Both ran to the end, and the column twisted: its free end, spun at OMEGA sin(π/2) =
    # OMEGA, turned the spin's way by more than half a step of that spin.
    for summary, turn in zip((euler, bdf2), turns, strict=True):
        assert summary["completed"] and summary["time"] == pytest.approx(0.1)
        assert turn.values[0] == 0.0
        assert max(np.unwrap(turn.values)) > 0.5 * OMEGA * 0.01


def test_twisting_column_newmark_keeps_its_energy_to_second_order():
    """Newmark's average acceleration has no numerical damping: the energy it loses shrinks
    at its order (halving the step divides it by about 4) and stays far below BDF2's."""
    losses = {}
    for dt in (0.005, 0.0025):
        for scheme in ("newmark", "bdf2"):
            summary = run("twisting-column", resolution=1, t_end=0.1, dt=dt, scheme=scheme)
            assert summary["completed"] and summary["time"] == pytest.approx(0.1)
            losses[scheme, dt] = summary["energy_loss"]
    coarse, fine = abs(losses["newmark", 0.005]), abs(losses["newmark", 0.0025])
    assert 3.0 < coarse / fine < 5.0, losses
    for dt in (0.005, 0.0025):
        assert abs(losses["newmark", dt]) < 0.25 * losses["bdf2", dt], losses


def test_compress_block_inverts_under_the_plate_and_recovers():
    from dolfinx_invertible.scenes.compress_block import DEPTH, PRESS, RELEASE

    def pressed_face(X, x):
        # The middle quarter of the top face, where the plate presses.
        centre, top = 0.5 * (X.min(axis=0) + X.max(axis=0)), X[:, 2].max()
        half = 0.25 * np.ptp(X[:, 0]) + 1e-12
        face = np.isclose(X[:, 2], top) & (np.abs(X[:, :2] - centre[:2]) <= half).all(axis=1)
        return x[face, 2]

    heights = Nodes(pressed_face)
    summary = run("compress-block", resolution=2, observers=[heights])
    assert summary["max_inverted"] > 0 and summary["min_J_reached"] < 0.0
    assert summary["outcome"] == "recovered", summary
    # The plate travelled DEPTH of the height: the face under it held there from the end of
    # the press to the release (the plate lets go once t > RELEASE t_end).
    p = summary["parameters"]
    assert summary["time"] == pytest.approx(p["t_end"])
    height = 0.5 * p["size"]
    assert heights.values[0] == pytest.approx(height)
    held = heights.between(PRESS * p["t_end"], RELEASE * p["t_end"])
    assert held and all(
        np.abs(face - (1.0 - DEPTH) * height).max() < PLATE_TOLERANCE * p["size"] for face in held
    )


def test_square_inversion_free_never_inverts():
    from dolfinx_invertible.scenes.square_inv_free import DEPTH, PRESS, RELEASE

    top = Nodes(lambda X, x: x[np.isclose(X[:, 1], X[:, 1].max()), 1])
    summary = run("square-inv-free", resolution=4, t_end=0.3, observers=[top])
    assert summary["completed"] and summary["max_inverted"] == 0
    assert summary["min_J_reached"] > 0.0
    # It was squashed: the plate travelled DEPTH of the height and held the top edge there
    # until the release; released, the square sprang back more than half way.
    p = summary["parameters"]
    assert summary["time"] == pytest.approx(p["t_end"])
    assert top.values[0] == pytest.approx(p["size"])
    held = top.between(PRESS * p["t_end"], RELEASE * p["t_end"])
    assert held and all(
        np.abs(edge - (1.0 - DEPTH) * p["size"]).max() < PLATE_TOLERANCE * p["size"]
        for edge in held
    )
    assert top.values[-1].min() > (1.0 - 0.5 * DEPTH) * p["size"]


def test_a_signal_during_a_write_waits_for_the_step_to_be_complete(tmp_path, monkeypatch):
    import os
    import signal

    import meshio

    from dolfinx_invertible.io.xdmf import ResultWriter
    from dolfinx_invertible.scenes.runner import RunInterrupted

    original = ResultWriter._merge_step_into_series
    calls = []

    def merge_with_a_signal(self):
        calls.append(1)
        if len(calls) == 3:  # the third step: the signal arrives in the middle of its write
            os.kill(os.getpid(), signal.SIGTERM)
        original(self)

    monkeypatch.setattr(ResultWriter, "_merge_step_into_series", merge_with_a_signal)
    with pytest.raises(RunInterrupted, match="SIGTERM"):
        run("collapse", tmp_path, resolution=2, t_end=1.0)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["reason"] == "interrupted by SIGTERM"
    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "collapse.xdmf")) as reader:
        reader.read_points_cells()
        assert reader.num_steps == 3  # the interrupted write finished; nothing after it
        for step in range(reader.num_steps):
            reader.read_data(step)
