"""The README's DOLFINx example is a file of the repository and runs as printed."""

from __future__ import annotations

import json
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
