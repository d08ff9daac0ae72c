"""A run killed with SIGKILL at a random step and resumed ends where the uninterrupted run ends.

The runs are separate processes (``dolfinx-invertible run``, under ``mpirun`` for two ranks),
killed with SIGKILL (mpirun and every rank) once the step log has reached a step drawn at
random, and continued with ``--resume`` from the last step every rank wrote its part of. The
final states are compared node by node through the final checkpoints (nodes matched by
coordinates, so runs on different rank counts compare too) and through the written XDMF series.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time

from mpi4py import MPI

import dolfinx
import meshio
import numpy as np
import pytest

from dolfinx_invertible import vector_function_space
from dolfinx_invertible.io import paraview
from dolfinx_invertible.io.checkpoint import (
    CheckpointError,
    read_checkpoint,
    write_checkpoint,
    write_checkpoint_part,
)
from dolfinx_invertible.scenes import Parameters, get_scene, run_scene
from dolfinx_invertible.scenes.checkpoints import latest_checkpoint

COMMAND = [sys.executable, "-m", "dolfinx_invertible", "run", "collapse", "--quiet"]
#: The collapse at resolution 4: 40 steps, a checkpoint every 3.
RUN = ["--resolution", "4", "--checkpoint-every", "3"]
MPIRUN = ["mpirun", "-n", "2"]
MPIRUN_RANKS = {"serial": 1, "two": 2}
#: Python's own copy of the environment: once this process has started MPI (as a singleton),
#: the C environment holds its variables, and an mpirun that inherits them exits at once.
ENVIRONMENT = dict(os.environ)


def _descendants(pid: int) -> list[int]:
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as file:
                    parent = int(file.read().rsplit(")", 1)[1].split()[1])
            except (OSError, ValueError, IndexError):
                continue
            children.setdefault(parent, []).append(int(entry))
    found, pending = [], [pid]
    while pending:
        current = pending.pop()
        found.append(current)
        pending.extend(children.get(current, []))
    return found


def run_and_kill(folder, launcher, at_line: int, command=(*COMMAND, *RUN)) -> int:
    """Start the run, SIGKILL it (and every rank) once its log has ``at_line`` lines."""
    process = subprocess.Popen(
        [*launcher, *command, "--out", str(folder)], start_new_session=True, env=ENVIRONMENT
    )
    log = folder / f"{command[command.index('run') + 1]}.jsonl"
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and process.poll() is None:
        if log.exists() and len(log.read_text().splitlines()) >= at_line:
            break
        time.sleep(0.002)
    assert process.poll() is None, "the run ended before it could be killed"
    for pid in reversed(_descendants(process.pid)):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    process.wait()
    return len(log.read_text().splitlines())


def left_a_running_summary(folder, written: int) -> dict:
    """The summary a killed run leaves: marked running, one step behind its log at most.

    ``written`` lines of the step log: the initial state and ``written - 1`` steps; the kill may
    land between a step's log line and its summary.
    """
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["running"] is True and summary["completed"] is False
    assert written - 2 <= summary["steps"] <= written - 1
    if summary["steps"]:
        assert summary["time"] > 0.0 and summary["newton_iterations"]["total"] > 0
    return summary


def final_displacement(folder, end: float = 0.4) -> tuple[np.ndarray, np.ndarray]:
    """Return the displacement nodes (sorted by coordinates) and values of the last checkpoint."""
    with np.load(folder / "checkpoint.npz") as data:
        coordinates = data["displacement.coordinates"]
        values = data["displacement.values"]
        state = json.loads(str(data["state"]))
    assert state["stepper"]["time"] == pytest.approx(end)
    order = np.lexsort(np.round(coordinates, 12).T[::-1])
    return coordinates[order], values[order]


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    folders = {}
    for name, launcher in (("serial", []), ("two", MPIRUN)):
        folder = tmp_path_factory.mktemp(f"uninterrupted-{name}")
        completed = subprocess.run(
            [*launcher, *COMMAND, *RUN, "--out", str(folder)],
            capture_output=True,
            timeout=600,
            env=ENVIRONMENT,
        )
        assert completed.returncode == 0, completed.stderr
        folders[name] = folder
    return folders


@pytest.mark.parametrize(
    "killed_on, resumed_on", [("serial", "serial"), ("two", "two"), ("serial", "two")]
)
def test_a_killed_run_resumes_to_the_end_of_the_same_run(
    tmp_path, uninterrupted, killed_on, resumed_on
):
    launchers = {"serial": [], "two": MPIRUN}
    folder = tmp_path / "run"
    at_line = random.Random().randint(5, 36)  # the initial state and 4..35 steps
    written = run_and_kill(folder, launchers[killed_on], at_line)
    left_a_running_summary(folder, written)
    resumed_from = latest_checkpoint(folder)[1]["steps_written"]
    # Every rank's part after every step, two generations: at most the step in flight is lost.
    assert written - 2 <= resumed_from <= written

    completed = subprocess.run(
        [*launchers[resumed_on], *COMMAND, "--resume", str(folder)],
        capture_output=True,
        text=True,
        timeout=600,
        env=ENVIRONMENT,
    )
    assert completed.returncode == 0, completed.stderr
    reference = uninterrupted[resumed_on]
    summary = json.loads((folder / "summary.json").read_text())
    expected = json.loads((reference / "summary.json").read_text())
    assert summary["outcome"] == expected["outcome"] == "recovered"
    assert summary["steps"] == expected["steps"] and summary["ranks"] == MPIRUN_RANKS[resumed_on]
    assert summary["newton_iterations"] == expected["newton_iterations"]
    assert summary["stepping"] == expected["stepping"]

    nodes, values = final_displacement(folder)
    reference_nodes, reference_values = final_displacement(reference)
    assert np.allclose(nodes, reference_nodes, rtol=0.0, atol=1e-12)
    # Round-off against the motion's scale, the body's size (1 m; the cube started collapsed by
    # 0.95 of it): the same operations on one rank, MUMPS's sums in another order on two.
    assert np.abs(values - reference_values).max() <= 1e-10

    lines = [json.loads(line) for line in (folder / "collapse.jsonl").read_text().splitlines()]
    assert [line["step"] for line in lines] == list(range(summary["steps"] + 1))
    assert np.all(np.diff([line["time"] for line in lines]) > 0)
    if "two" in (killed_on, resumed_on):
        # The continued steps carry the mesh as this partition numbers it (two ranks number it
        # otherwise than one): ParaView reads every step with its own mesh.
        resumed, whole = (
            paraview.inspect_xdmf(path / "collapse.xdmf") for path in (folder, reference)
        )
        assert resumed["times"] == pytest.approx(whole["times"], abs=1e-12)
        for step, expected_step in zip(resumed["steps"], whole["steps"]):
            assert step["number_of_points"] == expected_step["number_of_points"]
            ranges = step["point_data"]["displacement"]["component_ranges"]
            expected_ranges = expected_step["point_data"]["displacement"]["component_ranges"]
            assert np.allclose(ranges, expected_ranges, rtol=0.0, atol=1e-10)
    else:  # serial: one numbering, and meshio, which reads one mesh for the series, reads it
        written, reference_written = (
            _last_step(path / "collapse.xdmf", summary["steps"] + 1) for path in (folder, reference)
        )
        assert np.abs(written - reference_written).max() <= 1e-10


def _last_step(path, steps: int, end: float = 0.4) -> np.ndarray:
    with meshio.xdmf.TimeSeriesReader(str(path)) as reader:
        reader.read_points_cells()
        assert reader.num_steps == steps
        t, point_data, _ = reader.read_data(reader.num_steps - 1)
    assert t == pytest.approx(end)
    return point_data["displacement"]


#: Cook's membrane in six load steps, a whole checkpoint every two: a quasi-static run.
COOK = [sys.executable, "-m", "dolfinx_invertible", "run", "cook-membrane", "--quiet", "--steps",
        "6", "--checkpoint-every", "2"]  # fmt: skip


def test_a_killed_quasi_static_run_resumes_to_the_end_of_the_same_run(tmp_path):
    reference = tmp_path / "whole"
    whole = subprocess.run([*COOK, "--out", str(reference)], capture_output=True, text=True,
                           timeout=600, env=ENVIRONMENT)  # fmt: skip
    assert whole.returncode == 0, whole.stderr
    folder = tmp_path / "run"
    # The initial state and 2..4 of the 6 load steps: after the first step's log line its
    # checkpoint part is still being written, and a kill there leaves no checkpoint yet.
    at_line = random.Random().randint(3, 5)
    written = run_and_kill(folder, [], at_line, command=COOK)
    left_a_running_summary(folder, written)
    state = latest_checkpoint(folder)[1]
    assert written - 2 <= state["steps_written"] <= written
    assert 0.0 < state["stepper"]["time"] < 1.0  # a pseudo-time part of the way

    resumed = subprocess.run(
        [*COOK[:5], "--resume", str(folder)], capture_output=True, text=True, timeout=600,
        env=ENVIRONMENT,
    )  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr
    summary, expected = (
        json.loads((path / "summary.json").read_text()) for path in (folder, reference)
    )
    assert summary["outcome"] == expected["outcome"] == "completed"
    assert summary["steps"] == expected["steps"] == 6
    assert summary["newton_iterations"] == expected["newton_iterations"]
    assert summary["tip_displacement"] == pytest.approx(expected["tip_displacement"], abs=1e-10)
    # The tip moved: the load was applied, in full, by both runs.
    assert expected["relative_difference"] == pytest.approx(0.0, abs=0.05)
    lines = [json.loads(line) for line in (folder / "cook-membrane.jsonl").read_text().splitlines()]
    assert [line["step"] for line in lines] == list(range(7))
    assert [line["time"] for line in lines] == pytest.approx([k / 6 for k in range(7)])
    written, reference_written = (
        _last_step(path / "cook-membrane.xdmf", 7, end=1.0) for path in (folder, reference)
    )
    assert np.abs(written - reference_written).max() <= 1e-10


#: Eight cubes falling into a bowl until they land on it and on each other (t = 0.45–0.6 s).
BOWL = [sys.executable, "-m", "dolfinx_invertible", "run", "cubes-in-bowl", "--quiet",
        "--t-end", "0.6", "--checkpoint-every", "7"]  # fmt: skip


def test_a_killed_contact_run_resumes_to_the_end_of_the_same_run(tmp_path):
    """Body contact keeps its state over a restart: the adapted κ, the smallest distance so far
    and the crossing count come back with the displacement, and the run ends as the
    uninterrupted one does."""
    reference = tmp_path / "whole"
    whole = subprocess.run([*BOWL, "--out", str(reference)], capture_output=True, text=True,
                           timeout=600, env=ENVIRONMENT)  # fmt: skip
    assert whole.returncode == 0, whole.stderr
    folder = tmp_path / "run"
    # Killed while the cubes land: the barrier acts from about step 46 on.
    written = run_and_kill(folder, [], random.Random().randint(48, 58), command=BOWL)
    left_a_running_summary(folder, written)
    completed = subprocess.run([*BOWL[:5], "--resume", str(folder)], capture_output=True,
                               text=True, timeout=600, env=ENVIRONMENT)  # fmt: skip
    assert completed.returncode == 0, completed.stderr
    summary = json.loads((folder / "summary.json").read_text())
    expected = json.loads((reference / "summary.json").read_text())
    assert summary["outcome"] == expected["outcome"] == "completed"
    for key in ("steps", "newton_iterations", "stepping", "intersections", "penetrations",
                "barrier_stiffness", "max_contact_vertices"):  # fmt: skip
        assert summary[key] == expected[key], key
    assert (
        expected["intersections"] == 0 and expected["min_distance"] < expected["barrier_distance"]
    )
    for key in ("min_distance", "min_gap"):
        assert summary[key] == pytest.approx(expected[key], rel=1e-8), key
    nodes, values = final_displacement(folder, end=0.6)
    reference_nodes, reference_values = final_displacement(reference, end=0.6)
    assert np.allclose(nodes, reference_nodes, rtol=0.0, atol=1e-12)
    assert np.abs(values - reference_values).max() <= 1e-10


def test_a_run_killed_before_its_first_whole_checkpoint_resumes_from_its_parts(tmp_path):
    folder = tmp_path / "run"
    process = subprocess.Popen(
        [*COMMAND, "--resolution", "4", "--checkpoint-every", "1000", "--out", str(folder)],
        start_new_session=True,
        env=ENVIRONMENT,
    )
    log = folder / "collapse.jsonl"
    while process.poll() is None and not (log.exists() and len(log.read_text().splitlines()) >= 8):
        time.sleep(0.002)
    process.kill()
    process.wait()
    assert not (folder / "checkpoint.npz").exists()
    completed = subprocess.run(
        [*COMMAND, "--resume", str(folder)], capture_output=True, text=True, timeout=600,
        env=ENVIRONMENT,
    )  # fmt: skip
    assert completed.returncode == 0, completed.stderr
    assert json.loads((folder / "summary.json").read_text())["outcome"] == "recovered"


def test_resume_refuses_what_it_cannot_continue(tmp_path, uninterrupted):
    def run(*arguments):
        return subprocess.run([*COMMAND, *arguments], capture_output=True, text=True, timeout=600)

    missing = run("--resume", str(tmp_path))
    assert missing.returncode == 2 and "no checkpoint at" in missing.stderr
    changed = run("--resume", str(uninterrupted["serial"]), "--E", "2000")
    assert changed.returncode == 2 and "drop --E" in changed.stderr
    finished = run("--resume", str(uninterrupted["serial"]))
    assert finished.returncode == 2 and "at t = 0.4 already" in finished.stderr


@pytest.mark.mpi
@pytest.mark.parametrize("degree", [1, 2])
def test_a_checkpoint_reads_back_on_any_partition(directory, degree):
    comm = MPI.COMM_WORLD
    mesh = dolfinx.mesh.create_unit_cube(comm, 3, 2, 2)
    space = vector_function_space(mesh, degree)
    field = dolfinx.fem.Function(space)
    field.interpolate(lambda x: np.stack([x[0] ** 2, x[1] * x[2], np.sin(x[0] + x[2])]))
    path = directory / f"p{degree}.npz"
    size = write_checkpoint(path, {"u": field}, {"note": "test", "t": 0.25}, comm)
    assert size == path.stat().st_size > 0
    # Read back on one rank (another partition and numbering) and on all.
    for reader in (MPI.COMM_SELF, comm):
        other = dolfinx.mesh.create_unit_cube(reader, 3, 2, 2)
        back = dolfinx.fem.Function(vector_function_space(other, degree))
        state = read_checkpoint(path, {"u": back}, reader)
        assert state == {"note": "test", "t": 0.25}
        expected = dolfinx.fem.Function(back.function_space)
        expected.interpolate(lambda x: np.stack([x[0] ** 2, x[1] * x[2], np.sin(x[0] + x[2])]))
        # Equal up to the round-off of the nodes' coordinates (tabulated per partition).
        assert np.allclose(back.x.array, expected.x.array, rtol=0.0, atol=1e-14)
    coarser = dolfinx.mesh.create_unit_cube(comm, 2, 2, 2)
    wrong = dolfinx.fem.Function(vector_function_space(coarser, degree))
    with pytest.raises(CheckpointError, match="made on another mesh: no 'u' node at"):
        read_checkpoint(path, {"u": wrong}, comm)


def _part(folder, generation, rank, size, steps_written):
    state = {"version": 1, "steps_written": steps_written}
    nodes = {"u": (np.zeros((1, 3)), np.zeros((1, 3)))}
    write_checkpoint_part(
        folder / f"checkpoint-part-{generation}-{rank}-of-{size}.npz", nodes, state, sync=False
    )


def test_the_newest_complete_set_of_parts_is_taken(tmp_path):
    whole = {"version": 1, "steps_written": 10}
    write_checkpoint(tmp_path / "checkpoint.npz", {}, whole, MPI.COMM_SELF)
    assert latest_checkpoint(tmp_path)[1]["steps_written"] == 10
    for rank in range(2):  # two ranks: steps 13 and 14 complete
        _part(tmp_path, 1, rank, 2, 13)
        _part(tmp_path, 0, rank, 2, 14)
    files, state = latest_checkpoint(tmp_path)
    assert state["steps_written"] == 14 and [f.name for f in files] == [
        "checkpoint-part-0-0-of-2.npz", "checkpoint-part-0-1-of-2.npz"]  # fmt: skip
    _part(tmp_path, 1, 0, 2, 15)  # killed while rank 1 wrote its part of step 15
    assert latest_checkpoint(tmp_path)[1]["steps_written"] == 14
    (tmp_path / "checkpoint-part-0-1-of-2.npz").write_bytes(b"half a file")
    assert latest_checkpoint(tmp_path)[1]["steps_written"] == 10  # 13 was overwritten by 15
    for generation, steps in ((0, 16), (1, 17)):  # resumed on three ranks, further on
        for rank in range(3):
            _part(tmp_path, generation, rank, 3, steps)
    files, state = latest_checkpoint(tmp_path)
    assert state["steps_written"] == 17 and len(files) == 3


def test_a_run_stopped_by_steps_resumes_and_keeps_a_schedule_timed_by_its_end(tmp_path):
    # The stretch bar pulls over 5/6 of t_end: a resumed run may stop elsewhere, but a new
    # t_end would change the loading half-way through.
    stretch = [sys.executable, "-m", "dolfinx_invertible", "run", "stretch-bar", "--quiet"]
    folder = tmp_path / "bar"
    arguments = ["--resolution", "1", "--checkpoint-every", "1"]
    first = subprocess.run([*stretch, *arguments, "--steps", "2", "--out", str(folder)],
                           capture_output=True, text=True, timeout=600)  # fmt: skip
    assert first.returncode == 0, first.stderr
    assert latest_checkpoint(folder)[1]["stepper"]["time"] == pytest.approx(0.02)
    later = subprocess.run([*stretch, "--resume", str(folder), "--t-end", "2.4"],
                           capture_output=True, text=True, timeout=600)  # fmt: skip
    assert later.returncode == 2 and "timed by the end time" in later.stderr
    assert latest_checkpoint(folder)[1]["stepper"]["time"] == pytest.approx(0.02)
    # Resumed as it was, it goes on to its end (where --steps stopped it does not carry over).
    rest = subprocess.run([*stretch, "--resume", str(folder)], capture_output=True, text=True,
                          timeout=600)  # fmt: skip
    assert rest.returncode == 0, rest.stderr
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["time"] == pytest.approx(summary["parameters"]["t_end"]) and summary["completed"]


def test_a_run_whose_cuts_ran_out_resumes_with_a_larger_budget(tmp_path):
    # Three Newton iterations a solve and no cut: the press stops the compress block within
    # its first quarter; the run keeps its last completed step, and goes on from it with cuts.
    press = [sys.executable, "-m", "dolfinx_invertible", "run", "compress-block", "--quiet"]
    folder = tmp_path / "block"
    options = ["--petsc-option", "snes_max_it=3"]
    first = subprocess.run([*press, "--resolution", "2", "--max-cuts", "0", *options,
                            "--out", str(folder)], capture_output=True, text=True,
                           timeout=600)  # fmt: skip
    assert first.returncode == 1 and "the next cut would take the step below" in first.stdout
    assert f"run compress-block --resume {folder} --max-cuts 4" in first.stdout  # the way on
    stopped = json.loads((folder / "summary.json").read_text())
    assert stopped["outcome"] == "failed" and stopped["parameters"]["max_cuts"] == 0
    assert 0.0 < stopped["time"] < stopped["failed_time"] < stopped["parameters"]["t_end"]
    state = latest_checkpoint(folder)[1]
    assert state["stepper"]["time"] == pytest.approx(stopped["time"])
    assert state["steps_written"] == stopped["steps"] + 1  # with the initial state
    refused = subprocess.run([*press, "--resume", str(folder), "--max-cuts", "6", "--E", "2e3"],
                             capture_output=True, text=True, timeout=600)  # fmt: skip
    assert refused.returncode == 2 and "drop --E" in refused.stderr
    rest = subprocess.run([*press, "--resume", str(folder), "--max-cuts", "6", *options],
                          capture_output=True, text=True, timeout=600)  # fmt: skip
    assert rest.returncode == 0, rest.stderr
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["completed"] and summary["parameters"]["max_cuts"] == 6
    assert summary["time"] == pytest.approx(summary["parameters"]["t_end"])
    assert summary["stepping"]["cuts"] > stopped["stepping"]["cuts"]


def test_run_scene_takes_its_output_directory_as_a_string(tmp_path):
    # As a FEniCS script passes it: a str, for a run and for its resumption.
    scene = get_scene("collapse")
    folder = str(tmp_path / "collapse")
    values = {**scene.defaults, "resolution": 1}
    first = run_scene(scene, Parameters(**values, t_stop=0.02), output=folder, checkpoint_every=1)
    assert first["time"] == pytest.approx(0.02)
    later = run_scene(scene, Parameters(**values, t_stop=0.04), output=folder, resume=True)
    assert later["time"] == pytest.approx(0.04) and later["steps"] == 4
    assert json.loads((tmp_path / "collapse" / "summary.json").read_text())["steps"] == 4
