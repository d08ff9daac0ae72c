"""Analysis reports: figures and numbers that reproduce the paper's analyses.

Each report is a subpackage with ``run(output_directory, *, quick=False) -> dict``, which
writes its figures into ``output_directory`` and returns a JSON-ready summary (the file names
and the numbers it checked), and ``add_arguments(parser)`` and ``command(arguments) -> int``
for ``python -m dolfinx_invertible report NAME``. Their modules import matplotlib (Agg backend)
and DOLFINx inside their functions, so listing them is cheap.

- ``contours``: primary contours in the 2D singular-value plane (paper §3.2, Figs. 1–2);
- ``error-vs-time``: a work-precision study, error against wall time over meshes, elements,
  time steps, integrators, extensions, tangents and linear-solver tolerances
  (:mod:`.error_vs_time`);
- ``stability``: the outcome of every method over scenes, E, ν and dt, with the cause of every
  cell that did not come through.
"""

#: name -> one-line description; the subpackage of the same name (``-`` as ``_``) implements it.
REPORTS = {
    "contours": "primary contours of four materials in the 2D singular-value plane, with "
    "energy gradients and element trajectories (paper §3.2, Figs. 1-2)",
    "error-vs-time": "work-precision study: error against wall time for Cook's membrane, the "
    "twisting column and a collapse through inversion, over meshes, P1/P2, time steps, "
    "integrators, extensions, tangents, solver tolerances and DOLFINx's own UFL route",
    "stability": "outcome of every method over scenes, E, nu and dt, with the cause of every "
    "failure (CSV, heat maps, Markdown)",
}

__all__ = ["REPORTS", "add_output_arguments"]


def add_output_arguments(parser, default_output, quick_help: str) -> None:
    """Add the options every report has: ``--out DIR`` and ``--quick``."""
    import pathlib

    parser.add_argument(
        "--out",
        type=pathlib.Path,
        default=pathlib.Path(default_output),
        metavar="DIR",
        help=f"output directory (default: {default_output})",
    )
    parser.add_argument("--quick", action="store_true", help=quick_help)
