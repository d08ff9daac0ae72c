"""The command line as a user meets it: listing, help, bad input, failures, signals.

Every run is a child process of ``python -m dolfinx_invertible``, as from a shell.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from dolfinx_invertible.scenes import SCENES, get_scene

COMMAND = [sys.executable, "-m", "dolfinx_invertible"]
# A collapse run small enough for seconds.
SMALL = ["--resolution", "2", "--quiet"]


def cli(*arguments, timeout=600, **kwargs):
    return subprocess.run(
        [*COMMAND, *arguments], capture_output=True, text=True, timeout=timeout, **kwargs
    )


def test_list_names_every_scene_with_its_figure():
    completed = cli("list")
    assert completed.returncode == 0, completed.stderr
    for name in SCENES:
        line = next(line for line in completed.stdout.splitlines() if line.startswith(name))
        assert get_scene(name).figure in line


def test_scene_help_shows_units_and_this_scene_defaults():
    completed = cli("run", "cook-membrane", "--help")
    assert completed.returncode == 0
    text = " ".join(completed.stdout.split())
    assert "Young's modulus [Pa] (default: 240.565)" in text
    assert "(default: 0.4999)" in text and "load steps (default: 2)" in text
    assert "--dt" not in text  # quasi-static: no time step
    dynamic = " ".join(cli("run", "collapse", "--help").stdout.split())
    assert "largest time step [s] (default: 0.01)" in dynamic


def test_every_command_prints_its_help():
    """Every parser's help formats: argparse reads "%" in a help text as a format."""
    import argparse

    from dolfinx_invertible.cli import parser

    pending, seen = [parser()], 0
    while pending:
        current = pending.pop()
        assert current.format_help()
        seen += 1
        for action in current._actions:
            if isinstance(action, argparse._SubParsersAction):
                pending.extend(action.choices.values())
    assert seen > len(SCENES)
    assert cli("run", "--help").returncode == 0


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--nu", "0.5"], "--nu must lie in (-1, 0.5)"),
        (["--dt", "0"], "--dt must be a finite number > 0"),
        (["--resolution", "0"], "--resolution must be an integer >= 1"),
        (["--steps", "0"], "--steps must be an integer >= 1"),
        (["--extension", "ife", "-dolfinx_invertible_snes_linesearch_type", "bt"], "no energy"),
        (["--elastic", "ufl"], "plain Neo-Hookean only"),
        (["--globalization", "trust-region", "--linear-solver", "direct"], "needs --linear-solver"),
        (["--petsc-option", "ksp_type=notakrylov"], "--petsc-option ksp_type=notakrylov: PETSc"),
        (["--petsc-option", "snes_rtol=abc"], "--petsc-option snes_rtol=abc: PETSc"),
        (["-dolfinx_invertible_pc_type", "nopc"], "pc_type=nopc: PETSc"),
    ],
)
def test_bad_values_give_one_clear_line_and_no_output(tmp_path, arguments, message):
    completed = cli("run", "collapse", *SMALL, "--out", str(tmp_path / "run"), *arguments)
    assert completed.returncode == 2
    lines = completed.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], lines
    assert not (tmp_path / "run" / "summary.json").exists()


def test_a_petsc_option_no_solver_read_is_named_at_the_end(tmp_path):
    options = ["--petsc-option", "ksp_rtoll=1e-8", "--petsc-option", "snes_max_it=40"]
    completed = cli("run", "collapse", *SMALL, "--t-end", "0.02", "--out", str(tmp_path), *options)
    assert completed.returncode == 0, completed.stderr
    warnings = [line for line in completed.stderr.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1 and "ksp_rtoll" in warnings[0], completed.stderr
    assert "snes_max_it" not in warnings[0]  # read, so not named


def test_steps_stop_a_dynamic_run_without_changing_its_schedule(tmp_path):
    # The stretch bar pulls its ends over 5/6 of t_end: two steps of a 1.2 s run, not a whole
    # run of two steps.
    folder = tmp_path / "run"
    completed = cli("run", "stretch-bar", "--resolution", "1", "--steps", "2", "--quiet",
                    "--out", str(folder))  # fmt: skip
    assert completed.returncode == 0, completed.stderr
    summary = json.loads((folder / "summary.json").read_text())
    parameters = summary["parameters"]
    assert parameters["t_end"] == get_scene("stretch-bar").defaults["t_end"]
    assert parameters["t_stop"] == pytest.approx(2 * parameters["dt"])
    assert summary["steps"] >= 2 and summary["completed"]


def test_a_trust_region_run_recovers_and_says_so_in_its_summary(tmp_path):
    folder = tmp_path / "run"
    completed = cli("run", "collapse", *SMALL, "--linear-solver", "iterative",
                    "--globalization", "trust-region", "--out", str(folder))  # fmt: skip
    assert completed.returncode == 0, completed.stderr
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["parameters"]["globalization"] == "trust-region"
    assert summary["solver"] == {"linear_solver": "iterative", "globalization": "trust-region"}
    assert summary["outcome"] == "recovered"


def test_unknown_scene_or_option_is_refused():
    assert cli("run", "no-such-scene").returncode == 2
    completed = cli("run", "collapse", "--bogus", "1")
    assert completed.returncode == 2 and "--bogus" in completed.stderr


def test_output_directory_that_cannot_be_written(tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    completed = cli("run", "collapse", *SMALL, "--out", str(blocker / "run"))
    assert completed.returncode == 2
    assert "cannot write to the output directory" in completed.stderr


def test_a_failing_run_says_where_and_leaves_a_readable_output(tmp_path):
    folder = tmp_path / "run"
    completed = cli(
        "run", "collapse", *SMALL, "--t-end", "0.05", "--out", str(folder),
        "-dolfinx_invertible_snes_max_it", "0",
    )  # fmt: skip
    # No Newton iteration at all: not even the escalation to blended tangents can help (with one
    # iteration per step, blended Newton creeps on in steps of microseconds).
    assert completed.returncode == 1
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["completed"] is False and summary["converged"] is False
    assert summary["outcome"] == "failed" and summary["failed_stage"] == "iteration cap"
    assert "time step 1 from t = 0" in summary["reason"] and "DIVERGED_MAX_IT" in summary["reason"]
    assert summary["reason"] in completed.stdout
    # Every attempt of the step that did not pass is in the summary, with what it cost.
    attempts = summary["unfinished_step_attempts"]
    assert len(attempts) == summary["failed_attempts"] == summary["stepping"]["cuts"] > 0
    assert all(a["stage"] == "iteration cap" and a["newton_iterations"] == 0 for a in attempts)
    assert summary["failed_attempts_wall_time"] == pytest.approx(
        sum(a["wall_time"] for a in attempts)
    )
    steps = _readable_steps(folder / "collapse.xdmf")
    assert steps == summary["steps"] + 1 == 1  # the initial state


def test_progress_bar_unless_quiet(tmp_path):
    completed = cli("run", "collapse", "--resolution", "2", "--t-end", "0.02", "--out",
                    str(tmp_path))  # fmt: skip
    assert completed.returncode == 0
    assert "newton=" in completed.stderr and "inverted=" in completed.stderr
    assert "running build_ext" not in completed.stderr + completed.stdout  # no compiler chatter


def _start(folder, *arguments):
    return subprocess.Popen(
        [*COMMAND, "run", "scatter", *SMALL, "--t-end", "10", "--out", str(folder), *arguments],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


def _wait_for_steps(process, log, count, timeout=300):
    start = time.time()
    while time.time() - start < timeout:
        if log.exists() and len(log.read_text().splitlines()) >= count:
            return
        if process.poll() is not None:
            raise AssertionError(process.stderr.read())
        time.sleep(0.2)
    raise AssertionError("the run wrote too few steps")


def _readable_steps(path) -> int:
    import meshio

    with meshio.xdmf.TimeSeriesReader(str(path)) as reader:
        reader.read_points_cells()
        for step in range(reader.num_steps):
            reader.read_data(step)
        return reader.num_steps


@pytest.mark.parametrize("sent", [signal.SIGTERM, signal.SIGINT])
def test_interrupted_run_writes_its_summary(tmp_path, sent):
    process = _start(tmp_path)
    _wait_for_steps(process, tmp_path / "scatter.jsonl", 3)
    process.send_signal(sent)
    process.wait(timeout=120)
    assert process.returncode == 130, process.stderr.read()[-3000:]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["completed"] is False and summary["interrupted"] is True
    assert "running" not in summary
    assert summary["reason"] == f"interrupted by {sent.name}"
    assert summary["steps"] >= 2
    assert _readable_steps(tmp_path / "scatter.xdmf") >= summary["steps"] + 1


def test_killed_run_leaves_an_xdmf_readable_up_to_its_last_step(tmp_path):
    (tmp_path / "summary.json").write_text("{}")  # a previous run's: removed when a run starts
    process = _start(tmp_path)
    _wait_for_steps(process, tmp_path / "scatter.jsonl", 3)
    os.kill(process.pid, signal.SIGKILL)
    process.wait(timeout=60)
    logged = len((tmp_path / "scatter.jsonl").read_text().splitlines())
    assert _readable_steps(tmp_path / "scatter.xdmf") >= logged - 1
    # This run's summary so far, which does not look complete: running, no outcome.
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["running"] is True and summary["completed"] is False
    assert "outcome" not in summary and summary["scene"] == "scatter"
    assert logged - 2 <= summary["steps"] <= logged - 1
