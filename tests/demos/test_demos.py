"""The README's DOLFINx example is a file of the repository and runs as printed."""

from __future__ import annotations

import json
import os
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.mark.mpi
def test_readme_example_is_the_demo_file():
    readme = (ROOT / "README.md").read_text()
    demo = (ROOT / "demos" / "cantilever.py").read_text()
    blocks = re.findall(r"```python\n(.*?)```", readme, re.S)
    assert demo in blocks


def test_cantilever_demo_runs_and_writes_four_steps(tmp_path):
    completed = subprocess.run(
        [sys.executable, str(ROOT / "demos" / "cantilever.py")],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert completed.returncode == 0, completed.stderr[-2000:]
    lines = (tmp_path / "output" / "cantilever.jsonl").read_text().splitlines()
    records = [json.loads(line) for line in lines]
    assert [record["time"] for record in records] == [0.25, 0.5, 0.75, 1.0]
    assert all(record["inverted_cells"] == 0 for record in records)
    # The traction does work: the potential energy decreases as the load grows.
    energies = [record["energy"] for record in records]
    assert all(later < earlier for earlier, later in zip(energies, energies[1:]))
    assert (tmp_path / "output" / "cantilever.xdmf").exists()


def _run_demo(name, cwd, *arguments, ranks=1, timeout=900):
    command = [sys.executable, str(ROOT / "demos" / name), *arguments]
    if ranks > 1:
        command = ["mpirun", "-n", str(ranks), *command]
    environment = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    return subprocess.run(
        command, cwd=cwd, capture_output=True, text=True, timeout=timeout, env=environment
    )


def test_constitutive_demo_runs(tmp_path):
    completed = _run_demo("constitutive.py", tmp_path)
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert (tmp_path / "output" / "constitutive").is_dir()


@pytest.mark.demo_job
def test_collapse_demo_under_two_ranks_recovers_with_c2(tmp_path):
    completed = _run_demo("collapse.py", tmp_path, ranks=2)
    assert completed.returncode == 0, completed.stderr[-2000:]
    lines = [line.split() for line in completed.stdout.splitlines()]
    outcomes = {(line[0], line[1]): line[-1] for line in lines if line and line[0] in
                ("collapse", "scatter")}  # fmt: skip
    assert outcomes[("collapse", "c2")] == outcomes[("scatter", "c2")] == "recovered"
    for name in ("collapse-c2", "scatter-ife"):
        summary = json.loads((tmp_path / "output" / "collapse" / name / "summary.json").read_text())
        assert summary["ranks"] == 2


def test_ported_tutorial_takes_no_more_newton_iterations_than_dolfinx(tmp_path):
    completed = _run_demo("port_tutorial.py", tmp_path, "--mesh", "p1-hexahedron")
    assert completed.returncode == 0, completed.stderr[-2000:]
    rows = {}
    for line in completed.stdout.splitlines():
        words = line.split()
        if words and words[0] in ("dolfinx", "drop-in", "minimiser"):
            iterations = [int(word) for word in words[1 : words.index("total")]]
            rows[words[0]] = (iterations, float(words[words.index("u_z") + 1]))
    assert set(rows) == {"dolfinx", "drop-in", "minimiser"}, completed.stdout
    (plain, tip), (drop_in, drop_in_tip), (ours, our_tip) = (
        rows[name] for name in ("dolfinx", "drop-in", "minimiser")
    )
    assert len(plain) == len(ours) == 9  # the tutorial's nine load steps (LOADS)
    assert drop_in == plain and drop_in_tip == tip  # the same iterates as DOLFINx's own forms
    assert all(mine <= theirs for mine, theirs in zip(ours, plain)), (ours, plain)
    assert abs(our_tip - tip) <= 1e-6 * abs(tip)
