"""``report error-vs-time --quick`` from the command line: its CSV, its orders, its summary.

The report runs once, a child process of the command line: two minutes on one machine, 14 on
a slower one that also ran it past 10 minutes beside another test worker. The tests read what
it wrote and check it against the plan and against each other: one row per planned run, finite
orders, cheapest runs that are the cheapest rows of the CSV, and facts that must hold whatever
the timings (the same discrete problem assembled two ways gives the same error; BDF2 is more
accurate than backward Euler at the same step).
"""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from dolfinx_invertible.reports import error_vs_time

pytestmark = pytest.mark.study

REPOSITORY = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("error-vs-time")
    environment = dict(os.environ)
    environment["PYTHONPATH"] = os.pathsep.join(
        [str(REPOSITORY)] + [part for part in [environment.get("PYTHONPATH")] if part]
    )
    completed = subprocess.run(
        [sys.executable, "-m", "dolfinx_invertible", "report", "error-vs-time", "--quick",
         "--out", str(out)],
        capture_output=True, text=True, env=environment, timeout=1800, check=False,
    )  # fmt: skip
    assert completed.returncode == 0, completed.stderr[-3000:]
    with open(out / "runs.csv") as stream:
        rows = list(csv.DictReader(stream))
    summary = json.loads((out / "summary.json").read_text())
    return {"out": out, "rows": rows, "summary": summary, "stdout": completed.stdout}


def _number(text: str) -> float:
    return float(text) if text not in ("", None) else math.nan


def test_one_row_per_planned_run(report):
    planned = error_vs_time.plan(quick=True)
    rows = report["rows"]
    assert [row["name"] for row in rows] == [case.name for case in planned]
    assert len(report["summary"]["rows"]) == len(planned)
    for row in rows:
        assert _number(row["wall_time_s"]) > 0.0
        assert row["ranks"] == "1"
        assert int(row["dofs"]) > 0
        assert row["completed"] in ("True", "False")
        if row["completed"] == "True":
            assert int(row["newton_iterations"]) >= 1
            assert int(row["krylov_iterations"]) >= int(row["newton_iterations"])
    # Every run with a reference has an error against it (C1's runs have none: C1 is another
    # material than the reference's C2).
    for row in rows:
        if row["extension"] == "c1":
            assert row["reference"] == ""
        if row["reference"] and row["completed"] == "True":
            assert math.isfinite(_number(row["error"])), row["name"]
        if row["sweep"] == "dt" and row["completed"] == "True":
            assert math.isfinite(_number(row["time_error"])), row["name"]
    # The progress lines name every run.
    assert report["stdout"].count("] ") >= len(planned)


def test_orders_are_finite_and_order_the_methods(report):
    orders = report["summary"]["orders"]
    assert orders
    for entry in orders:
        assert entry["order"] is not None and math.isfinite(entry["order"]), entry
        assert entry["points"] >= 2
    by_curve = {(entry["study"], entry["curve"]): entry["order"] for entry in orders}
    kinds = {entry["kind"] for entry in orders}
    assert kinds == {"space", "time"}
    # P2 converges faster than locking P1 on the nearly incompressible membrane.
    assert by_curve["cook-membrane", "P2, kernels"] > by_curve["cook-membrane", "P1, kernels"] + 1
    # BDF2 faster than backward Euler wherever both were swept.
    for study, curve in by_curve:
        if "backward Euler" in curve:
            assert by_curve[study, curve.replace("backward Euler", "BDF2")] > by_curve[study, curve]


def test_summary_names_the_cheapest_runs_of_the_csv(report):
    rows = report["rows"]
    markdown = (report["out"] / "summary.md").read_text()
    entries = report["summary"]["cheapest"]
    assert {entry["study"] for entry in entries} == set(error_vs_time.STUDIES)
    assert any(entry["run"] is not None for entry in entries)
    for entry in entries:
        candidates = [
            row for row in rows
            if row["study"] == entry["study"] and row["role"] == "run" and row["start"] == "scene"
            and row["completed"] == "True" and _number(row[entry["error"]]) <= entry["target"]
        ]  # fmt: skip
        if entry["run"] is None:
            assert not candidates
            continue
        fastest = min(candidates, key=lambda row: _number(row["wall_time_s"]))
        assert entry["run"] == fastest["name"]
        assert entry["configuration"] in markdown
    for study in error_vs_time.STUDIES:
        assert error_vs_time.STUDIES[study] in markdown
    assert markdown.count("| error | target | cheapest run |") == len(error_vs_time.STUDIES)
    assert "6.9083" in markdown


def test_same_problem_two_ways_and_integrators_compare_as_they_must(report):
    rows = {row["name"]: row for row in report["rows"]}
    compared = 0
    for name, row in rows.items():
        twin = name.replace("kernels", "DOLFINx UFL")
        if twin != name and twin in rows and row["completed"] == "True":
            # The kernels and the UFL route assemble one discrete energy: one solution.
            assert _number(rows[twin]["error"]) == pytest.approx(_number(row["error"]), rel=1e-4)
            compared += 1
    assert compared >= 6
    compared = 0
    for name, row in rows.items():
        if "BDF2 | dt" in name and row["completed"] == "True":
            backward = rows[name.replace("BDF2", "backward Euler")]
            assert _number(row["time_error"]) < _number(backward["time_error"])
            compared += 1
    assert compared >= 6
    # Loose and tight linear tolerances: Newton's own test decides, so the solution agrees,
    # where the steps agree: a dynamic run whose linear solves failed and were cut took other
    # time steps, and so has another discretisation error.
    iterative = [row for row in rows.values() if row["linear_solver"] == "iterative"]
    direct = {
        row["study"]: row for row in rows.values()
        if row["sweep"] == "ksp_rtol" and row["linear_solver"] == "auto"
    }  # fmt: skip
    assert len(iterative) >= 4 and set(direct) == {"cook-membrane", "twisting-column"}
    compared_studies = set()
    for row in iterative:
        twin = direct[row["study"]]
        assert (row["degree"], row["resolution"], row["dt"]) == (
            twin["degree"], twin["resolution"], twin["dt"]
        )  # fmt: skip
        same_steps = (row["time_steps"], row["cuts"]) == (twin["time_steps"], twin["cuts"])
        if row["completed"] == "True" and same_steps:
            assert _number(row["error"]) == pytest.approx(_number(twin["error"]), rel=1e-3)
            compared_studies.add(row["study"])
    assert compared_studies == {"cook-membrane", "twisting-column"}


def test_reference_beside_the_published_value_and_figures(report):
    cook = report["summary"]["studies"]["cook-membrane"]
    assert cook["published_tip_displacement"] == 6.9083
    # The quick reference (P2, 32 cells a side) is within 2 % of the converged value.
    assert abs(cook["reference_vs_published"]) < 0.02
    for study, name in report["summary"]["figures"].items():
        assert study in error_vs_time.STUDIES
        assert (report["out"] / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(report["summary"]["figures"]) == len(error_vs_time.STUDIES)
