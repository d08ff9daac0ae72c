"""Pictures and animations of a scene's run with its obstacles drawn (ParaView, headless).

A run's directory says which scene ran with which parameters (``summary.json``, or the
checkpoint of a run that has not finished); the scene then makes its obstacles again, and
:func:`~dolfinx_invertible.io.paraview.render` and :func:`~dolfinx_invertible.io.paraview.
animate` draw them where they were at each time shown::

    from dolfinx_invertible.scenes.pictures import animate_run, render_run

    render_run("results/bowl-drop", "bowl-drop.png", time="last")
    animate_run("results/bowl-drop", "bowl-drop.gif")
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from mpi4py import MPI

from dolfinx_invertible.io.checkpoint import CheckpointError
from dolfinx_invertible.io.paraview import animate, render
from dolfinx_invertible.scenes.checkpoints import latest_checkpoint
from dolfinx_invertible.scenes.parameters import Parameters

__all__ = ["animate_run", "render_run", "run_obstacles"]


def _run_scene(directory: Path) -> tuple[str, dict[str, Any]] | None:
    summary = directory / "summary.json"
    if summary.is_file():
        data = json.loads(summary.read_text(encoding="utf-8"))
        return data["scene"], data["parameters"]
    try:
        state = latest_checkpoint(directory)[1]
    except CheckpointError:
        return None
    return state["scene"], state["parameters"]


def run_obstacles(directory: str | Path) -> list:
    """Return what the scene that ran in ``directory`` draws beside its body (may be empty)."""
    from dolfinx_invertible.scenes import get_scene

    found = _run_scene(Path(directory))
    if found is None:
        return []
    name, parameters = found
    return get_scene(name)(Parameters(**parameters), MPI.COMM_SELF).drawn_obstacles()


def _series(directory: Path) -> Path:
    found = _run_scene(directory)
    if found is None:
        raise FileNotFoundError(f"{directory} holds no run (no summary.json, no checkpoint)")
    return directory / f"{found[0]}.xdmf"


def render_run(directory: str | Path, png: str | Path, **options: Any) -> dict[str, Any]:
    """Render the run in ``directory`` with its obstacles; options as :func:`render`'s."""
    directory = Path(directory)
    return render(_series(directory), png, obstacles=run_obstacles(directory), **options)


def animate_run(directory: str | Path, gif: str | Path, **options: Any) -> dict[str, Any]:
    """Animate the run in ``directory`` with its obstacles; options as :func:`animate`'s."""
    directory = Path(directory)
    return animate(_series(directory), gif, obstacles=run_obstacles(directory), **options)
