"""``report contours`` on the command line, with the trajectories of mattress-2d and triangles-2d.

The scenes run small, in-process, through the same command line; the report must draw exactly
the trajectories the scenes wrote (elements × steps × 2, the IFE convention) on the contour of
the material each scene ran with, and refuse missing or malformed data with a clear message.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from dolfinx_invertible.cli import main, parser
from dolfinx_invertible.reports.contours import figures


@pytest.fixture(scope="module")
def scene_runs(tmp_path_factory):
    mattress = tmp_path_factory.mktemp("mattress")
    triangles = tmp_path_factory.mktemp("triangles")
    assert main(["run", "mattress-2d", "--model", "corotated", "--nu", "0.45", "--resolution",
                 "2", "--steps", "6", "--out", str(mattress), "--quiet"]) == 0  # fmt: skip
    assert main(["run", "triangles-2d", "--model", "corotated", "--t-end", "0.02", "--out",
                 str(triangles), "--quiet"]) == 0  # fmt: skip
    return {"mattress": mattress, "triangles": triangles}


def test_parser_has_both_reports_with_their_options():
    top = parser()
    arguments = top.parse_args(["report", "contours", "--mattress", "a", "--triangles", "b"])
    assert str(arguments.out) == "results/reports/contours"
    assert [str(path) for path in arguments.mattress] == ["a"]
    assert [str(path) for path in arguments.triangles] == ["b"]
    arguments = top.parse_args(["report", "error-vs-time", "--quick"])
    assert arguments.quick and str(arguments.out) == "results/reports/error-vs-time"
    assert arguments.report_module == "error_vs_time"


def test_report_draws_the_scene_trajectories(scene_runs, tmp_path, capsys):
    out = tmp_path / "figures"
    code = main(["report", "contours", "--quick", "--out", str(out),
                 "--mattress", str(scene_runs["mattress"]),
                 "--triangles", str(scene_runs["triangles"])])  # fmt: skip
    assert code == 0
    printed = capsys.readouterr().out
    for kind, scene, elements in (("stretch", "mattress", 8), ("relaxation", "triangles", 3)):
        steps = np.load(scene_runs[scene] / "trajectories.npy").shape[1]
        assert f"{kind}: {elements} elements × {steps} steps" in printed
    for name in ("contours.png", "contours_stretch.png", "contours_relaxation.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("scene", ["mattress", "triangles"])
def test_drawn_lines_are_the_files_data_on_the_runs_material(scene_runs, scene):
    directory = scene_runs[scene]
    trajectories = np.load(directory / "trajectories.npy")
    summary = json.loads((directory / "summary.json").read_text())
    assert trajectories.shape[0] == (8 if scene == "mattress" else 3)
    figure, described = figures.scene_figure([directory], 0.04, "title")
    (axes,) = figure.axes
    # The trajectories are the lines at z-order 4 (contours 3, markers 6).
    drawn = [line.get_xydata() for line in axes.get_lines() if line.get_zorder() == 4]
    # One line per element, in element order, with the file's σ₁ and signed σ₂.
    assert len(drawn) == len(trajectories)
    for line, path in zip(drawn, trajectories):
        np.testing.assert_array_equal(line, path)
    (entry,) = described
    assert entry["elements"] == len(trajectories)
    assert entry["steps"] == trajectories.shape[1]
    assert "Corotated" in entry["material"]
    assert summary["model"] in axes.get_title()
    if scene == "mattress":
        # Paper Fig. 1: corotated drives stretched elements through inversion, the scene too.
        assert entry["inverted_elements"] > 0
        assert entry["min_sigma2"] < 0.0


def test_missing_or_malformed_scene_data_is_refused(scene_runs, tmp_path, capsys):
    out = tmp_path / "figures"
    assert main(["report", "contours", "--quick", "--out", str(out),
                 "--mattress", str(tmp_path / "nowhere")]) == 2  # fmt: skip
    assert "trajectories.npy does not exist" in capsys.readouterr().err
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "summary.json").write_text((scene_runs["mattress"] / "summary.json").read_text())
    np.save(broken / "trajectories.npy", np.zeros((4, 3)))
    assert main(["report", "contours", "--quick", "--out", str(out),
                 "--mattress", str(broken)]) == 2  # fmt: skip
    assert "elements × steps × 2" in capsys.readouterr().err
    # σ₁ < |σ₂|: not the IFE convention the scenes write.
    np.save(broken / "trajectories.npy", np.array([[[0.5, -1.0], [1.0, 1.0]]]))
    assert main(["report", "contours", "--quick", "--out", str(out),
                 "--mattress", str(broken)]) == 2  # fmt: skip
    assert "IFE convention" in capsys.readouterr().err
