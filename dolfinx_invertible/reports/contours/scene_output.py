"""Element trajectories written by a 2D scene run, and the material it ran with."""

from __future__ import annotations

import json
import pathlib

import numpy as np

from dolfinx_invertible.constitutive import Material

__all__ = ["load_scene_trajectories"]


def load_scene_trajectories(directory) -> tuple[np.ndarray, Material, dict]:
    """Read a scene run's element trajectories and the material it ran with.

    Parameters
    ----------
    directory
        Output directory of a scene that writes ``trajectories.npy`` (``mattress-2d``,
        ``triangles-2d``), with its ``summary.json``.

    Returns
    -------
    (trajectories, material, summary)
        The array (elements × steps × 2, signed singular values in the IFE convention), the
        :class:`~dolfinx_invertible.Material` of the run's parameters and the run's summary.

    Raises
    ------
    ValueError
        A file is missing or the array has the wrong shape.
    """
    from dolfinx_invertible.scenes.parameters import Parameters, make_material

    directory = pathlib.Path(directory)
    path, summary_path = directory / "trajectories.npy", directory / "summary.json"
    for needed in (path, summary_path):
        if not needed.is_file():
            raise ValueError(
                f"{needed} does not exist: give the output directory of a mattress-2d or "
                f"triangles-2d run (python -m dolfinx_invertible run mattress-2d --out {directory})"
            )
    trajectories = np.load(path)
    if trajectories.ndim != 3 or trajectories.shape[2] != 2 or trajectories.shape[1] < 1:
        raise ValueError(
            f"{path} must hold elements × steps × 2 singular values, got shape {trajectories.shape}"
        )
    summary = json.loads(summary_path.read_text())
    material = make_material(Parameters(**summary["parameters"]))
    return trajectories, material, summary
