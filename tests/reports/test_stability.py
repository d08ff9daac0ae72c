"""The stability study: its matrix, its cause diagnosis, and ``report stability --quick``.

The quick report runs as a subprocess of the command line, as a user would; its CSV must have
one row per cell of the quick matrix with the documented columns, every cell that did not come
through must carry a cause, and the Markdown must state it.
"""

from __future__ import annotations

import csv
import math
import os
import pathlib
import subprocess
import sys

import pytest

from dolfinx_invertible.reports import REPORTS, stability
from dolfinx_invertible.reports.stability import diagnosis, outputs, runner, study

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_matrix_is_the_product_of_its_axes():
    cells = stability.matrix()
    assert len(cells) == (
        len(stability.SCENES)
        * len(stability.METHODS)
        * len(stability.POISSON_RATIOS)
        * len(stability.YOUNGS_MODULI)
        * len(stability.TIME_STEPS)
    )
    assert len({cell.key for cell in cells}) == len(cells)
    quick = stability.matrix(quick=True)
    assert {cell.key for cell in quick} <= {cell.key for cell in cells}
    assert {cell.scene for cell in quick} == set(stability.SCENES)
    assert {cell.method for cell in quick} == {method.name for method in stability.METHODS}
    assert "stability" in REPORTS


def test_cell_parameters_are_dimensionless_in_size_and_time():
    for cell in stability.matrix():
        parameters = cell.parameters()
        c = math.sqrt(parameters["E"] / parameters["density"])
        unit = parameters["size"] / c
        assert parameters["size"] == stability.SIZE and parameters["density"] == stability.DENSITY
        assert cell.dimensionless_step == pytest.approx(parameters["dt"] / unit)
        # At least the minimum number of steps, and the scene's end time in L/c otherwise.
        steps = parameters["t_end"] / parameters["dt"]
        assert steps >= study.MINIMUM_STEPS * (1 - 1e-12)
        setup = stability.SCENE_SETUPS[cell.scene]
        if setup.end_time is not None:
            expected = max(setup.end_time, study.MINIMUM_STEPS * cell.dimensionless_step)
            assert parameters["t_end"] / unit == pytest.approx(expected)
    # The same dimensionless step for two (E, dt) pairs: identical scene parameters but for
    # the scales E, dt and t_end.
    first = stability.Cell("collapse", "nh-c2", 0.45, 1.0e5, 1.0e-2).parameters()
    second = stability.Cell("collapse", "nh-c2", 0.45, 1.0e7, 1.0e-3).parameters()
    assert first["t_end"] / first["dt"] == pytest.approx(second["t_end"] / second["dt"])
    differing = {name for name in first if first[name] != second[name]}
    assert differing == {"E", "dt", "t_end"}


def _failure(**values):
    record = {
        "scene": "stretch-bar",
        "method": "corotated",
        "outcome": "failed",
        "failed_stage": "iteration cap",
        "snes_reason": "DIVERGED_MAX_IT",
        "failed_time_star": 2.0,
        "retry_step": 1.0e-6,
        "step_floor": 2.0e-6,
        "retry": "iteration cap",
    }
    record.update(values)
    return record


@pytest.mark.parametrize(
    ("values", "cause"),
    [
        ({"kink_gap": 1.0e-9, "retry": "converged"}, "kink σ₂+σ₃=0"),
        ({"kink_gap": 0.2, "cap_last": 1.0e-6, "method": "nh-inversion-free"}, "inversion-free"),
        ({"kink_gap": 0.2, "residual_drop_last10": 0.1}, "iteration cap while converging"),
        ({"kink_gap": 0.2, "residual_drop_last10": 2.0, "retry": "converged"}, "step-size floor"),
        ({"retry": "converged", "retry_step": 1.0e-3}, "cut budget"),
        (
            {"failed_stage": "linear solve", "tangent_condition": 1.0e16, "method": "nh-ife"},
            "nearly singular tangent",
        ),
        ({"residual_drop_last10": 2.0}, "solver (iteration cap)"),
    ],
)
def test_failures_are_told_apart_by_their_data(values, cause):
    found, detail = stability.diagnose(_failure(**values))
    assert found.startswith(cause)
    assert "t = 2 L/c" in detail
    # A clause the record has no data for is left out, not left empty.
    assert "; ;" not in detail


@pytest.mark.parametrize(
    "values",
    [
        {},
        # The converged long retry decides over the failed attempt's own evidence.
        {"kink_gap": 1.0e-9, "residual_drop_last10": 0.85},
        {"residual_drop_last10": 0.1, "failed_stage": "line search"},
    ],
)
def test_a_long_retry_that_converges_makes_the_iteration_cap_the_cause(values):
    record = _failure(long_retry="converged", long_retry_iterations=137, **values)
    cause, detail = stability.diagnose(record)
    assert cause == "iteration cap"
    assert "converges in 137 iterations" in detail
    assert "t = 2 L/c" in detail and "; ;" not in detail
    assert cause in diagnosis.CAUSES


@pytest.mark.parametrize(
    ("values", "cause", "long_retry"),
    [
        (
            {"long_retry": "iteration cap", "residual_drop_last10": 0.1},
            "iteration cap while converging",
            "that cut stops at the larger cap too",
        ),
        (
            {"long_retry": "line search", "residual_drop_last10": 2.0},
            "solver (iteration cap)",
            "that cut fails (line search)",
        ),
        (
            {"long_retry": "iteration cap", "kink_gap": 1.0e-9},
            "kink σ₂+σ₃=0",
            "that cut stops at the larger cap too",
        ),
        # Not run: the evidence of the failed attempt alone.
        ({"residual_drop_last10": 0.1}, "iteration cap while converging", None),
    ],
)
def test_a_long_retry_that_fails_leaves_the_cause_to_the_other_evidence(values, cause, long_retry):
    found, detail = stability.diagnose(_failure(**values))
    assert found == cause
    assert "one more cut fails too (iteration cap)" in detail
    if long_retry is None:
        assert "allowed more Newton iterations" not in detail
    else:
        assert f"allowed more Newton iterations, {long_retry}" in detail


def test_the_csv_reports_the_retries(tmp_path):
    columns = ("retry", "long_retry", "long_retry_iterations")
    assert all(stability.COLUMNS.count(name) == 1 for name in columns)
    records = [
        {**_failure(long_retry="converged", long_retry_iterations=137), "nu": 0.3},
        {**_failure(long_retry="iteration cap"), "nu": 0.45},
        {**_failure(retry="converged"), "nu": 0.49},
    ]
    path = tmp_path / "stability.csv"
    outputs.write_csv(records, path)
    with path.open() as stream:
        rows = list(csv.DictReader(stream))
    assert [tuple(row[name] for name in columns) for row in rows] == [
        ("iteration cap", "converged", "137"),
        ("iteration cap", "iteration cap", ""),
        ("converged", "", ""),
    ]


def _continued(inverted, distance):
    return {"continued": "completed", "continued_inverted": inverted,
            "continued_rest_distance": distance}  # fmt: skip


@pytest.mark.parametrize(
    ("continued", "cause"),
    [
        (_continued(0, 1.0e-5), "end time too short"),
        (_continued(3, 0.5), "inverted equilibrium"),
        (_continued(0, 0.3), "distorted equilibrium"),
        ({**_continued(0, 0.3), "continued_overlap": 12}, "self-overlapping equilibrium"),
        ({**_continued(5, 0.5), "largest_singular_value": 1e-6}, "collapsed equilibrium"),
        ({**_continued(5, 9.0), "inverted_energy_min": -3.0}, "energy below rest when inverted"),
        ({**_continued(5, 0.5), "inverted_energy_min": -3.0}, "inverted equilibrium"),
        ({"continued": "failed (line search)"}, "continuation failed"),
    ],
)
def test_relaxations_that_did_not_recover_are_told_apart_by_their_continuation(continued, cause):
    record = {"scene": "scatter", "method": "nh-c2", "outcome": "stalled_inverted"}
    record.update(final_inverted=2, t_end_star=6.0)
    record["rest_distance"] = continued.get("continued_rest_distance", 0.4)
    record.update(continued)
    assert stability.diagnose(record)[0] == cause


def test_overlap_count_finds_a_body_folded_through_itself():
    from mpi4py import MPI

    import dolfinx
    import numpy as np

    from dolfinx_invertible import _compat

    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_SELF, 3, 3, 3)
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))
    u.interpolate(lambda x: np.stack([0.3 * x[0] * x[1], 0.1 * x[2], np.zeros_like(x[0])]))
    assert runner.overlapping_cells(u) == 0
    # A rigid rotation moves every cell and overlaps nothing.
    u.interpolate(lambda x: np.stack([-x[1] - x[0], x[0] - x[1], np.zeros_like(x[0])]))
    assert runner.overlapping_cells(u) == 0
    # Fold the half x > 1/2 back over the other: its cells lie on the first half's.
    u.interpolate(
        lambda x: np.stack([np.where(x[0] > 0.5, 1.0 - 2.0 * x[0], 0.0), 0 * x[1], 0 * x[2]])
    )
    assert runner.overlapping_cells(u) > 0


def test_overlap_count_equals_the_test_of_every_pair_on_a_tangled_body(monkeypatch):
    from mpi4py import MPI

    import dolfinx
    import numpy as np

    from dolfinx_invertible import _compat

    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_SELF, 4, 4, 4)
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))
    # Vertices thrown into a box of half the body's size: cells of every size cross.
    u.x.array[:] = np.random.default_rng(7).uniform(-0.5, 0.5, u.x.array.size)
    cells = _compat.cell_dofs(u.function_space)[:, :4]
    simplices = (u.function_space.tabulate_dof_coordinates() + u.x.array.reshape(-1, 3))[cells]
    centroids = simplices.mean(axis=1)
    inside_any = np.zeros(len(cells), dtype=bool)
    for index, simplex in enumerate(simplices):
        edges = (simplex[1:] - simplex[0]).T
        barycentric = np.linalg.solve(edges, (centroids - simplex[0]).T).T
        inside = (barycentric > 1e-9).all(axis=1) & (barycentric.sum(axis=1) < 1 - 1e-9)
        shares = np.isin(cells, cells[index]).any(axis=1)
        inside_any |= inside & ~shares
    expected = int(np.count_nonzero(inside_any))
    assert expected > 10
    assert runner.overlapping_cells(u) == expected
    # Chunks of a few pairs at a time count the same.
    monkeypatch.setattr(runner, "_OVERLAP_PAIRS", 50)
    assert runner.overlapping_cells(u) == expected


def test_inverted_energy_minimum_finds_the_energies_below_rest():
    from dolfinx_invertible.scenes.parameters import Parameters

    def lowest(method, nu):
        cell = stability.Cell("collapse", method, nu, 1.0e5, 1.0e-2)
        return runner.inverted_energy_minimum(Parameters(**cell.parameters()))

    # Neo-Hookean + C1 with k = 20 E: inverted states below rest from λ/μ ≈ 49 on.
    assert lowest("nh-c1", 0.45) > 0.0 and lowest("nh-c1", 0.499) < -1.0e3
    assert all(lowest("nh-c2", nu) > 0.0 for nu in stability.POISSON_RATIOS)
    assert lowest("nh-ife", 0.45) is None and lowest("nh-ufl", 0.45) is None


@pytest.mark.study
def test_quick_report_from_the_command_line(tmp_path):
    out = tmp_path / "stability"
    environment = dict(os.environ)
    environment["PYTHONPATH"] = os.pathsep.join(
        [str(ROOT), *filter(None, [environment.get("PYTHONPATH")])]
    )
    completed = subprocess.run(
        [sys.executable, "-m", "dolfinx_invertible", "report", "stability", "--quick"]
        + ["--out", str(out), "--quiet"],
        capture_output=True,
        text=True,
        timeout=1800,
        env=environment,
        cwd=tmp_path,
    )
    assert completed.returncode == 0, completed.stdout[-3000:] + completed.stderr[-3000:]
    with (out / "stability.csv").open() as stream:
        reader = csv.DictReader(stream)
        assert tuple(reader.fieldnames) == stability.COLUMNS
        rows = list(reader)
    cells = stability.matrix(quick=True)
    keys = {
        (row["scene"], row["method"], float(row["nu"]), float(row["E"]), float(row["dt"]))
        for row in rows
    }
    assert len(rows) == len(cells) and keys == {cell.key for cell in cells}
    assert all(row["outcome"] in outputs._DISPLAY for row in rows)
    markdown = (out / "stability.md").read_text()
    assert "--quick" in markdown and "## Every cell that did not come through" in markdown
    labels = {method.name: method.label for method in stability.METHODS}
    failure_lines = [line for line in markdown.splitlines() if line.startswith("| ")]
    for row in rows:
        if row["outcome"] in ("recovered", "completed"):
            continue
        assert row["cause"], row
        assert row["cause_detail"] or row["outcome"] == "does_not_apply", row
        matching = [
            line
            for line in failure_lines
            if line.startswith(f"| {row['scene']} | {labels[row['method']]} | ")
            and f"| {float(row['nu']):g} | {float(row['E']):g} | {float(row['dt']):g} |" in line
        ]
        assert len(matching) == 1, row
        assert f"**{row['cause']}**" in matching[0]
    for scene in stability.SCENES:
        figure = out / f"stability_{scene.replace('-', '_')}.png"
        assert figure.stat().st_size > 10_000
    # No NaN anywhere; no lost cells.
    assert not any(row["outcome"] in ("nan", "crashed", "timeout") for row in rows)
    assert not any(row["nan"] == "True" for row in rows)
    # The quick matrix has the same dimensionless problem twice (dt·c/L = 1): the same outcome
    # and Newton iterations within 3 % (E and dt differ by factors that are not powers of two,
    # so the two runs round differently, and a solve that ends at its tolerance may take one
    # iteration more).
    by_problem = {}
    for row in rows:
        key = (row["scene"], row["method"], row["nu"], round(float(row["dt_star"]), 9))
        by_problem.setdefault(key, []).append(row)
    pairs = [group for group in by_problem.values() if len(group) == 2]
    assert pairs
    for first, second in pairs:
        assert first["outcome"] == second["outcome"], (first, second)
        newton = int(first["newton_total"]), int(second["newton_total"])
        assert abs(newton[0] - newton[1]) <= 0.03 * max(newton), (first, second)


def test_resolution_axis_runs_the_chosen_cells_at_the_chosen_resolution(tmp_path):
    from dolfinx_invertible.reports.stability.report import run

    result = run(
        tmp_path,
        workers=1,
        scenes=["collapse"],
        methods=["nh-c2"],
        poisson_ratios=[0.45],
        youngs_moduli=[1.0e5],
        time_steps=[1.0e-2],
        resolution=2,
    )
    assert result["cells"] == 1
    with (tmp_path / "stability.csv").open() as stream:
        (row,) = list(csv.DictReader(stream))
    assert (row["scene"], row["method"], float(row["nu"])) == ("collapse", "nh-c2", 0.45)
    # Resolution 2 is not the scene's own (4): the run took the axis' value.
    assert stability.SCENE_SETUPS["collapse"].resolution != 2
    assert int(row["resolution"]) == 2
    assert row["outcome"] in outputs._DISPLAY
    assert "| collapse | 2 |" in (tmp_path / "stability.md").read_text()


@pytest.mark.parametrize(
    "options, message",
    [
        ({"poisson_ratios": [0.4]}, "nu = 0.4 is not on the study's axis"),
        ({"time_steps": [0.5]}, "dt = 0.5 is not on the study's axis"),
        ({"resolution": 0}, "resolution must be a positive integer"),
        ({"cell_timeout": 0.0}, "cell_timeout must be a number of seconds > 0"),
        ({"workers": 0}, "workers must be a positive integer"),
    ],
)
def test_values_off_the_study_axes_are_refused(tmp_path, options, message):
    from dolfinx_invertible.reports.stability.report import run

    with pytest.raises(ValueError, match=message):
        run(tmp_path / "out", scenes=["collapse"], methods=["nh-c2"], **options)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "option, message",
    [
        (["--resolution", "0"], "resolution must be a positive integer, got 0"),
        (["--cell-timeout", "-1"], "cell_timeout must be a number of seconds > 0, got -1.0"),
        (["--workers", "0"], "workers must be a positive integer, got 0"),
    ],
)
def test_the_command_refuses_an_option_with_the_api_message(tmp_path, capsys, option, message):
    from dolfinx_invertible.cli import main

    out = tmp_path / "out"
    assert main(["report", "stability", "--scene", "collapse", "--out", str(out), *option]) == 2
    assert f"error: {message}" in capsys.readouterr().err
    assert not out.exists()


def test_a_cell_reports_how_far_it_got_after_every_step():
    """``run_cell``'s progress: one record a stored step, the steps counted up to the last,
    whose time is the cell's end time."""
    cell = study.Cell("collapse", "nh-c2", 0.45, 1.0e5, 1.0e-2, resolution=2)
    reports = []
    record = runner.run_cell(cell, progress=reports.append)
    assert record["steps"] == len(reports) > 0
    assert [report["steps"] for report in reports] == list(range(1, len(reports) + 1))
    assert reports[-1]["time_star"] == pytest.approx(record["t_end_star"])
    assert reports[-1]["t_end_star"] == pytest.approx(record["t_end_star"])
    assert reports[-1]["newton_total"] == record["newton_total"]


_SLOW_WORKER = """
import sys, time
sys.stdin.readline()
for steps in (1, 2, 3):
    print('STABILITY-PROGRESS {"time_star": %g, "t_end_star": 6.0, "steps": %d, '
          '"failed_attempts": 1, "newton_total": %d}' % (0.5 * steps, steps, 4 * steps),
          flush=True)
time.sleep(60)
"""


@pytest.mark.parametrize("reports", [True, False])
def test_a_timed_out_cell_says_how_far_it_got(tmp_path, monkeypatch, reports):
    """A worker that reports three steps and then hangs: the timed-out cell's record keeps the
    last report (time, steps, Newton iterations); one that never reports says so."""
    from dolfinx_invertible.reports.stability import pool

    script = _SLOW_WORKER if reports else "import sys, time\nsys.stdin.readline()\ntime.sleep(60)"
    monkeypatch.setattr(pool, "_worker_command", lambda: [sys.executable, "-c", script])
    cell = study.Cell("scatter", "nh-c2", 0.45, 1.0e5, 1.0e-2)
    (record,) = pool.run_cells([cell], workers=1, timeout=3.0, log_directory=tmp_path)
    assert record["outcome"] == record["cause"] == "timeout"
    if reports:
        assert (record["steps"], record["newton_total"]) == (3, 12)
        assert record["time_reached_star"] == pytest.approx(1.5)
        assert (
            "at t = 1.5 L/c of 6 after 3 steps, 1 failed attempts and 12 Newton"
            in (record["reason"])
        )
    else:
        assert "steps" not in record and record["reason"].endswith("before its first step")
