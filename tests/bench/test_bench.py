"""Smoke tests of the benchmark tools at tiny sizes: their reports have the fields the README and
the table printers rely on, and the UFL and kernel routes agree. Nothing here asserts a timing.

Collective, so they also run under mpirun; the ones that launch child processes (mpirun
themselves) are serial only.
"""

from __future__ import annotations

import json
import pathlib

import pytest

from benchmarks import assembly as bench_assembly
from benchmarks import common as bench_common
from benchmarks import compile as bench_compile
from benchmarks import contact as bench_contact
from benchmarks import memory as bench_memory
from benchmarks import points as bench_points
from benchmarks import scaling as bench_scaling
from benchmarks import scenes as bench_scenes
from benchmarks import solve as bench_solve
from dolfinx_invertible.scenes import get_scene
from dolfinx_invertible.solvers.options import DEFAULT_OPTIONS_PREFIX

OPERATIONS = ("residual", "tangent", "newton_step")


@pytest.mark.mpi
def test_assembly_report_has_every_case_and_the_newton_step():
    report = bench_assembly.run(cells=2, repeats=1)
    json.dumps(report)
    assert set(report["meshes"]) == {"P1", "P2"}
    for mesh in report["meshes"].values():
        assert set(mesh["ratios"]) == set(OPERATIONS)
        for operation in OPERATIONS:
            assert set(mesh["ratios"][operation]) == {"b/a", "r/a", "c/a", "c/d"}
        assert mesh["ratios"]["newton_step"]["c/d"] is None  # no Newton step of a zero matrix
        assert mesh["median_seconds"]["d_zero"]["newton_step"] is None
        for name in ("a_ufl", "b_fast", "b_random", "c_svd"):
            assert mesh["krylov_iterations"][name]["converged"]
            assert mesh["median_seconds"][name]["newton_step"] > 0.0
        assert mesh["extension_share"]["b_fast"] == 0.0
        assert mesh["extension_share"]["b_random"] == 0.0
        assert mesh["extension_share"]["c_svd"] == 1.0
    assert bench_assembly.table(report)


@pytest.mark.mpi
def test_solve_routes_agree():
    report = bench_solve.run(cells=4, thickness_cells=1, steps=2, repeats=1)
    json.dumps(report)
    assert report["relative_displacement_difference"] <= 1.0e-6
    assert report["agreement_ok"]
    assert report["tip_vertical_displacement"] > 1.0  # the load does something
    for route in report["routes"].values():
        assert route["newton_iterations"] >= route["load_steps_taken"] == 2
        assert len(route["all_seconds"]) == 1
    assert report["ratio_ours_over_ufl"] > 0.0
    assert bench_solve.table(report)


@pytest.mark.mpi
def test_inverted_scene_runs_through_the_extension():
    report = bench_solve.run_inverted(cells=2, steps=2, repeats=1)
    json.dumps(report)
    assert report["initial_inverted_cells"] > 0
    assert report["newton_iterations"] >= report["time_steps"] == 2
    assert 0.0 < report["svd_share"]["residual"] <= 1.0
    assert bench_solve.inverted_table(report)


@pytest.mark.mpi
def test_scaling_measurement():
    result = bench_scaling.measure(cells=3, repeats=1)
    json.dumps(result)
    assert result["dofs"] == 4**3 * 3
    for name in bench_scaling.DEFAULT_CASES:
        assert set(result["median_seconds"][name]) == set(OPERATIONS)


@pytest.mark.mpi
def test_compile_first_assembly_is_reproducible():
    phases, first = bench_compile.first_assembly(cells=3)
    _, second = bench_compile.first_assembly(cells=3)
    assert list(phases) == ["python_started", "imported", "forms_built", "assembled"]
    # Two meshes built one after the other may be partitioned differently under MPI, which
    # changes the order of the ghost sums: equal to round-off, not bitwise.
    assert bench_compile.relative_difference(first, second) <= 1.0e-12


@pytest.mark.mpi
def test_memory_measurement():
    result = bench_memory.measure(cells=3)
    json.dumps(result)
    assert result["krylov_converged"]
    assert set(result["seconds_since_start"]) == set(bench_memory.STAGES)


def test_scaling_and_memory_in_child_processes():
    scaling = bench_scaling.run(cells=3, repeats=1, ranks=(1,), cases=("b_fast",))
    assert scaling["speed_up"]["b_fast/tangent"]["1"] == 1.0
    assert bench_scaling.table(scaling)
    memory = bench_memory.run(cells=3)
    peaks = [memory["peak_rss_bytes_total"][name] for name in bench_memory.STAGES]
    assert peaks == sorted(peaks) and peaks[0] > 0  # ru_maxrss never decreases
    assert bench_memory.table(memory)


def test_scene_rows_pair_the_kernels_with_dolfinx_ufl_route():
    # The twisting column never leaves the Neo-Hookean region (no extension), so our kernels and
    # FFCx's UFL Neo-Hookean minimise the same energy: the same Newton iterations, the same
    # outcome, on the path the benchmark forces.
    report = bench_scenes.run(
        ["twisting-column"], [1], [1], ["iterative"], 2, "gamg", 600.0, ("kernels", "ufl")
    )
    json.dumps(report)
    kernels, ufl = report["rows"]
    assert (kernels["elastic"], ufl["elastic"]) == ("kernels", "ufl")
    for row in (kernels, ufl):
        assert row["path"] == "iterative" and row["cut_short"] and row["steps"] == 2
        assert row["seconds_per_newton"] > 0.0 and row["krylov_per_newton"] > 0.0
    assert kernels["outcome"] == ufl["outcome"]
    assert kernels["newton"] == ufl["newton"] and kernels["unknowns"] == ufl["unknowns"]
    assert "s/Newton" in bench_scenes.table(report)


def test_scene_rows_pair_the_globalizations_on_the_iterative_path_only():
    report = bench_scenes.run(
        ["collapse"], [2], [1], ["direct", "iterative"], 2, "gamg", 600.0, ("kernels",),
        ("auto", "trust-region"),
    )  # fmt: skip
    rows = [(row["path"], row["globalization"]) for row in report["rows"]]
    # "auto" is the line search on the direct path and the trust region on the iterative one.
    assert rows == [
        ("direct", "line-search"), ("iterative", "trust-region"), ("iterative", "trust-region")
    ]  # fmt: skip
    assert all(row["steps"] == 2 and row["newton"] > 0 for row in report["rows"])
    assert "trust-region" in bench_scenes.table(report)


def test_a_stopped_scene_row_says_how_far_the_run_got(tmp_path):
    # The worker's progress file after its last step carries the counts of the finished row, so
    # the row of a run stopped there (timed out) reports the same steps, time and iterations.
    progress = str(tmp_path / "row.json.progress")
    finished = bench_scenes.measure(
        "twisting-column", 1, "iterative", 2, "gamg", "kernels", progress=progress
    )
    started = {"scene": "twisting-column", "process_wall_seconds": 12.0}
    stopped = bench_scenes._unfinished_row(started, "timed out", "", progress)
    assert stopped["outcome"] == "timed out" and finished["steps"] == stopped["steps"] == 2
    assert stopped["attempts"] == 2 and stopped["last_failure"] is None  # no step was cut
    for key in ("cells", "unknowns", "newton", "krylov", "newton_per_step", "krylov_per_newton"):
        assert stopped[key] == finished[key], key
    dt = get_scene("twisting-column").defaults["dt"]
    assert stopped["reached_time"] == pytest.approx(2 * dt) == stopped["stop_time"]
    text = bench_scenes._row_text(stopped)
    assert f"timed out after 12 s at t = {2 * dt:.4g} of {2 * dt:.4g}: 2 steps" in text
    nothing = bench_scenes._unfinished_row({}, "error", "why", str(tmp_path / "absent"))
    assert nothing == {"outcome": "error", "reason": "why"}


def test_a_child_past_its_time_limit_loses_every_process_it_started(tmp_path):
    # mpirun's ranks are its children: ending mpirun alone would leave them running.
    marker = tmp_path / "grandchild.pid"
    command = ["sh", "-c", f"sleep 120 & echo $! > {marker}; wait"]
    with pytest.raises(bench_common.ChildTimeoutError, match="did not finish within 2 s"):
        bench_common.run_child(command, {}, 2.0)
    status = pathlib.Path(f"/proc/{int(marker.read_text())}/status")
    # Gone, or a zombie waiting for init to reap it: not running either way.
    assert not status.exists() or "\nState:\tZ" in status.read_text()


@pytest.mark.mpi
def test_points_report_covers_every_stage_and_the_paths_taken():
    report = bench_points.run(points=200, repeats=1)
    json.dumps(report)
    fast, rest, extension = (report["stages"][state] for state in bench_points.STRETCHES)
    assert set(fast) == set(rest) == set(extension)
    assert all(entry["nanoseconds_per_point"] > 0.0 for entry in fast.values())
    # Away from the threshold nothing needs the SVD (near rest the projected tangent clamps its
    # twist stiffnesses without it). Inside it (J ≈ 0.86 ± 0.02 against ε = 0.9) nearly every
    # point does, the same points for every stage.
    for stage in (
        "point energy",
        "point stress",
        "point tangent, exact",
        "point tangent, projected",
    ):
        assert fast[stage]["svd_share"] == 0.0
        assert rest[stage]["svd_share"] == 0.0
        assert extension[stage]["svd_share"] == extension["point energy"]["svd_share"] > 0.95
    assert bench_points.table(report)


def test_interleaved_jobs_follow_their_own_kind_and_rotate_the_cases():
    """A Newton step must not sit before one case's assembly only (it evicts the caches)."""
    calls = []
    cases, operations = ("a", "b", "c"), ("residual", "tangent", "newton_step")
    jobs = {
        (case, operation): (lambda key=(case, operation): calls.append(key))
        for case in cases
        for operation in operations
        if (case, operation) != ("c", "newton_step")
    }
    samples = bench_common.interleaved(jobs, repeats=6)
    assert all(len(values) == 6 for values in samples.values())
    repeats = [calls[start : start + len(jobs)] for start in range(0, len(calls), len(jobs))]
    for repeat in repeats:
        kinds = [operations.index(operation) for _, operation in repeat]
        assert kinds == sorted(kinds)  # all residuals, then all tangents, then the steps
    assert sorted(repeat[0][0] for repeat in repeats) == sorted(cases * 2)


def test_scene_rows_take_a_budget_of_cuts(monkeypatch):
    # One Newton iteration an attempt (PETSc's options from the environment, read by the child
    # under the solver's prefix): the scatter's first step cannot pass, and without a cut the
    # run stops there.
    monkeypatch.setenv("PETSC_OPTIONS", f"-{DEFAULT_OPTIONS_PREFIX}snes_max_it 1")
    report = bench_scenes.run(["scatter"], [4], [1], ["direct"], 1, "gamg", 600.0, max_cuts=0)
    (row,) = report["rows"]
    assert (row["max_cuts"], row["outcome"], row["steps"]) == (0, "failed", 0)
    assert row["cuts"] >= 1 and row["attempts"] == row["cuts"]


def test_the_contact_clock_counts_each_category_without_the_ones_it_calls():
    import time

    class Work:
        def outer(self):
            time.sleep(0.02)
            self.inner()

        def inner(self):
            time.sleep(0.03)

    clock = bench_contact._Clock()
    clock.wrap(Work, "outer", "outer")
    clock.wrap(Work, "inner", "inner")
    Work().outer()
    assert 0.02 <= clock.seconds["outer"] < 0.03 <= clock.seconds["inner"] < 0.045


def test_contact_rows_count_the_pile_and_share_its_time():
    """The 8 cubes of resolution 2 in a child: 8 × (3³ − 1³) surface vertices (a cube's grid
    points but its one interior point), the counts of the run, shares that add up to at most
    the run's time, and contact work measured."""
    report = bench_contact.run(["cubes-in-bowl"], [2], [1], ["direct"], None, 600.0)
    (row,) = report["rows"]
    assert (row["cells"], row["surface_vertices"], row["ranks"]) == (384, 8 * (27 - 1), 1)
    assert row["outcome"] == "completed" and row["intersections"] == 0
    assert row["newton_per_step"] == pytest.approx(row["newton"] / row["steps"])
    shares = row["shares"]
    assert set(shares) == set(bench_contact.SHARES) and all(v >= 0.0 for v in shares.values())
    assert sum(shares.values()) <= 1.0
    assert min(shares["candidates"], shares["CCD"], shares["barrier"], shares["obstacles"]) > 0.0
    assert shares["elastic"] > 0.0 and shares["linear"] > 0.0
    assert "candidates" in bench_contact.table(report)
