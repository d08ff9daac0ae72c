"""Pictures and animations of a scene's run show its obstacles (ParaView, headless).

A short bowl-drop run (until the cube has landed) is rendered with and without its bowl: the
bowl's colour (translucent over the white background) covers a good part of the picture with
it and next to none without. The animation has one frame per step of the step log (up to the
frame count), the body moving between them. Fails, and does not skip, without ParaView:
``make test`` installs it.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from dolfinx_invertible.io import paraview
from dolfinx_invertible.scenes import Parameters, get_scene, run_scene
from dolfinx_invertible.scenes.pictures import animate_run, render_run, run_obstacles


@pytest.fixture(scope="module")
def bowl_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bowl-drop")
    scene = get_scene("bowl-drop")
    parameters = Parameters(**{**scene.defaults, "resolution": 2, "t_end": 0.45})
    run_scene(scene, parameters, output=folder)
    return folder


def _obstacle_pixels(png) -> int:
    """Pixels of the obstacles' colour blended over white, as the picture draws them."""
    pixels = np.asarray(Image.open(png).convert("RGB"), dtype=float) / 255.0
    expected = 1.0 - paraview.OBSTACLE_OPACITY * (1.0 - np.asarray(paraview.OBSTACLE_COLOUR))
    # Lighting scales the colour: compare its direction (warm grey) and brightness range.
    norm = np.linalg.norm(pixels, axis=-1, keepdims=True)
    direction = pixels / np.maximum(norm, 1e-9)
    reference = expected / np.linalg.norm(expected)
    aligned = (direction @ reference) > 0.9995
    shaded = (norm[..., 0] > 0.5 * np.linalg.norm(expected)) & (norm[..., 0] < 1.65)
    return int(np.count_nonzero(aligned & shaded))


def test_the_bowl_is_drawn_around_the_body(bowl_run, tmp_path):
    assert len(run_obstacles(bowl_run)) == 1
    with_bowl = render_run(bowl_run, tmp_path / "with.png", time="last", size=(320, 240))
    without = paraview.render(
        bowl_run / "bowl-drop.xdmf", tmp_path / "without.png", time="last", size=(320, 240)
    )
    assert with_bowl["time"] == without["time"] == pytest.approx(0.45)
    drawn, bare = (_obstacle_pixels(tmp_path / name) for name in ("with.png", "without.png"))
    # Without the bowl a few grey pixels match too (the label's and the edges' anti-aliasing).
    assert drawn > 0.05 * 320 * 240 and bare < 0.015 * 320 * 240, (drawn, bare)


def test_an_animation_has_a_frame_per_step_and_the_body_falls(bowl_run, tmp_path):
    log = (bowl_run / "bowl-drop.jsonl").read_text().splitlines()
    times = [json.loads(line)["time"] for line in log]
    result = animate_run(bowl_run, tmp_path / "drop.gif", frames=50, size=(160, 120))
    assert result["frames"] == len(times) and result["times"] == pytest.approx(times)
    gif = Image.open(tmp_path / "drop.gif")
    assert gif.n_frames == len(times) and gif.size == (160, 120)
    first = np.asarray(gif.convert("RGB"), dtype=float)
    gif.seek(gif.n_frames - 1)
    last = np.asarray(gif.convert("RGB"), dtype=float)
    assert np.abs(first - last).mean() > 1.0  # the body has moved (the camera is fixed)
    fewer = animate_run(bowl_run, tmp_path / "few.gif", frames=3, size=(160, 120))
    assert fewer["times"] == pytest.approx([times[0], times[len(times) // 2], times[-1]], abs=0.011)
    with pytest.raises(ValueError, match="frames must be a whole number >= 2"):
        animate_run(bowl_run, tmp_path / "one.gif", frames=1)


def test_the_command_line_animates_a_run_with_its_obstacles(bowl_run, tmp_path):
    completed = subprocess.run(
        [sys.executable, "-m", "dolfinx_invertible.io.paraview", "animate", str(bowl_run),
         "--output", str(tmp_path), "--frames", "3", "--size", "160", "120"],
        capture_output=True, text=True, timeout=600, env=dict(os.environ),
    )  # fmt: skip
    assert completed.returncode == 0, completed.stderr
    gif = tmp_path / bowl_run.name / "bowl-drop.gif"
    assert "3 frames" in completed.stdout and Image.open(gif).n_frames == 3
