"""ParaView as a separate process: read a result series back as users see it, render pictures.

:func:`inspect_xdmf` opens a :class:`~dolfinx_invertible.io.xdmf.ResultWriter` series with
ParaView's XDMF3 reader and reports its time steps, arrays and their ranges; :func:`render`
draws one picture of a run; :func:`render_runs` draws one per run for the gallery. From the
shell::

    python -m dolfinx_invertible.io.paraview inspect output/collapse/point_C2.xdmf
    python -m dolfinx_invertible.io.paraview render output/collapse --output docs/gallery

- :mod:`.series`: reading and rendering (:func:`inspect_xdmf`, :func:`render`,
  :func:`render_runs`, :func:`run_files`, the picture's constants);
- :mod:`.process`: ``pvbatch`` as a child process, with its own ``Xvfb`` for pictures
  (:func:`find_pvbatch`, :class:`ParaViewError`);
- :mod:`.cli`: the command line (:func:`main`).
"""

from dolfinx_invertible.io.paraview.cli import main
from dolfinx_invertible.io.paraview.process import (
    ParaViewError,
    ParaViewNotFoundError,
    find_pvbatch,
)
from dolfinx_invertible.io.paraview.series import (
    BODY_OPACITY,
    IMAGE_SIZE,
    INVERTED_COLOUR,
    MIN_J_COLOUR_MAP,
    MIN_J_RANGE,
    TIME_KEYWORDS,
    inspect_xdmf,
    render,
    render_runs,
    run_files,
)

__all__ = [
    "BODY_OPACITY",
    "IMAGE_SIZE",
    "INVERTED_COLOUR",
    "MIN_J_COLOUR_MAP",
    "MIN_J_RANGE",
    "ParaViewError",
    "ParaViewNotFoundError",
    "TIME_KEYWORDS",
    "find_pvbatch",
    "inspect_xdmf",
    "main",
    "render",
    "render_runs",
    "run_files",
]
