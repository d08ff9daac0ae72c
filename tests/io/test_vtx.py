"""VTX output: a P2 run's displacement at its P2 nodes, read back by ParaView's ADIOS2 reader.

Where DOLFINx has ADIOS2 (the 0.9 and 0.11 lanes) a P2 collapse is written with ``--format
both`` and ParaView (headless) reads the ``.bp`` files: every time of the step log, the P2
nodes (more than the vertices the XDMF file holds), the displacement's range at the last step
as the run's own final state has it, the cell diagnostics. Where it has not (Debian
bookworm's 0.5.2), the option is refused before the run with a message that says why.
"""

from __future__ import annotations

import json

import dolfinx
import numpy as np
import pytest

from dolfinx_invertible.io.paraview import inspect_vtx
from dolfinx_invertible.io.vtx import VTX_AVAILABLE
from dolfinx_invertible.scenes import Parameters, get_scene, run_scene


def _collapse(folder, output_format):
    scene = get_scene("collapse")
    parameters = Parameters(**{**scene.defaults, "resolution": 2, "degree": 2, "t_end": 0.05})
    return run_scene(scene, parameters, output=folder, output_format=output_format)


def test_vtx_output_where_dolfinx_has_adios2(tmp_path):
    if not VTX_AVAILABLE:
        with pytest.raises(ValueError, match="VTX output needs DOLFINx built with ADIOS2"):
            _collapse(tmp_path / "run", "vtx")
        assert not (tmp_path / "run" / "summary.json").exists()
        assert dolfinx.__version__.startswith("0.5")  # the one supported DOLFINx without it
        return
    folder = tmp_path / "run"
    summary = _collapse(folder, "both")
    log = [json.loads(line) for line in (folder / "collapse.jsonl").read_text().splitlines()]
    assert len(log) == summary["steps"] + 1
    displacement = inspect_vtx(folder / "collapse.bp")
    cells = inspect_vtx(folder / "collapse-cells.bp")
    assert displacement["times"] == pytest.approx([line["time"] for line in log])
    assert cells["times"] == displacement["times"]
    # P2 on 2 x 2 x 2 cubes: 5³ nodes, against the 3³ vertices of the XDMF series.
    assert displacement["number_of_points"] == 125 and displacement["number_of_cells"] == 48
    last = displacement["steps"][-1]["point_data"]["displacement"]["component_ranges"]
    first = displacement["steps"][0]["point_data"]["displacement"]["component_ranges"]
    # The collapse starts at u = (0.05 − 1)(x − centre): ±0.475 in every direction.
    assert np.allclose(first, [[-0.475, 0.475]] * 3, atol=1e-12)
    assert np.all(np.abs(np.asarray(last)) < 0.475)
    assert {"min_J", "inverted"} <= set(cells["steps"][0]["cell_data"])
    min_j = cells["steps"][-1]["cell_data"]["min_J"]["range"]
    assert min_j[0] == pytest.approx(log[-1]["min_J"], rel=1e-12)


def test_vtx_output_cannot_be_resumed(tmp_path):
    scene = get_scene("collapse")
    parameters = Parameters(**{**scene.defaults, "resolution": 2})
    with pytest.raises(ValueError, match="VTX|--format"):
        run_scene(scene, parameters, output=tmp_path, resume=True, output_format="vtx")
    with pytest.raises(ValueError, match="--format must be one of xdmf, vtx, both"):
        run_scene(scene, parameters, output=tmp_path, output_format="vtk")
