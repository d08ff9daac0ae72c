"""ParaView as a separate process: read a result series back as users see it, render pictures.

:func:`inspect_xdmf` opens a :class:`~dolfinx_invertible.io.xdmf.ResultWriter` series with
ParaView's XDMF3 reader and reports its time steps, arrays and their ranges; :func:`render`
draws one picture of a run (with analytic obstacles, if given); :func:`animate` an animated
GIF; :func:`render_runs` draws one picture per run for the gallery. From the shell
(:mod:`dolfinx_invertible.scenes.pictures` is the command)::

    dolfinx-invertible paraview inspect output/collapse/point_C2.xdmf
    dolfinx-invertible paraview render output/collapse --output docs/gallery

- :mod:`.series`: reading and rendering (:func:`inspect_xdmf`, :func:`render`,
  :func:`animate`, :func:`render_runs`, :func:`run_files`, the picture's constants);
- :mod:`.obstacles`: obstacles sampled on a grid for ParaView, the steps of a run's log;
- :mod:`.process`: ``pvbatch`` as a child process, with its own ``Xvfb`` for pictures
  (:func:`find_pvbatch`, :class:`ParaViewError`).
"""

from dolfinx_invertible.io.paraview.process import (
    ParaViewError,
    ParaViewNotFoundError,
    find_pvbatch,
)
from dolfinx_invertible.io.paraview.series import (
    ANIMATION_FRAMES,
    ANIMATION_SIZE,
    BODY_OPACITY,
    IMAGE_SIZE,
    INVERTED_COLOUR,
    MIN_J_COLOUR_MAP,
    MIN_J_RANGE,
    OBSTACLE_COLOUR,
    OBSTACLE_OPACITY,
    TIME_KEYWORDS,
    VIEW_DIRECTION,
    animate,
    inspect_vtx,
    inspect_xdmf,
    render,
    render_runs,
    run_files,
)

__all__ = [
    "ANIMATION_FRAMES",
    "ANIMATION_SIZE",
    "BODY_OPACITY",
    "IMAGE_SIZE",
    "INVERTED_COLOUR",
    "MIN_J_COLOUR_MAP",
    "MIN_J_RANGE",
    "OBSTACLE_COLOUR",
    "OBSTACLE_OPACITY",
    "ParaViewError",
    "ParaViewNotFoundError",
    "TIME_KEYWORDS",
    "VIEW_DIRECTION",
    "animate",
    "find_pvbatch",
    "inspect_vtx",
    "inspect_xdmf",
    "render",
    "render_runs",
    "run_files",
]
