"""Analysis reports: figures and numbers that reproduce the paper's analyses.

Each report module has ``run(output_directory, *, quick=False) -> dict``, which writes its
figures into ``output_directory`` and returns a JSON-ready summary (the file names and the
numbers it checked). The modules import matplotlib (Agg backend) inside their functions, so
listing them is cheap.

- ``contours``: primary contours in the 2D singular-value plane (paper §3.2, Figs. 1–2).
"""

#: name -> one-line description; the module of the same name implements it.
REPORTS = {
    "contours": "primary contours of four materials in the 2D singular-value plane, with "
    "energy gradients and element trajectories (paper §3.2, Figs. 1-2)",
}

__all__ = ["REPORTS"]
