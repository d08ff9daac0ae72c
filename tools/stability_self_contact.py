"""Rerun the stability study's collapse cells that ended tangled, now with self-contact.

Reads docs/stability/stability.csv, takes the collapse cells whose cause was a self-overlapping
equilibrium (the body passed through itself), runs each again with ``self_contact=True`` (IPC
Toolkit keeps the surface from passing through itself; everything else as in the study) and
writes a table with both outcomes to docs/stability/self_contact.md. A cell that has not ended
after ``--wall-limit`` seconds (default 900) is stopped and reported with the time it reached.
Run from the repository root::

    .venv/bin/python tools/stability_self_contact.py [--wall-limit SECONDS]
"""

from __future__ import annotations

import argparse
import csv
import signal
import sys
import time
from pathlib import Path

from mpi4py import MPI

REPOSITORY = Path(__file__).resolve().parents[1]
CAUSES = ("self-overlapping equilibrium",)


class _OutOfTime(BaseException):  # noqa: N818 (an interruption, not an error)
    """Raised by SIGALRM; a BaseException, so the time stepper does not retry it as a failure."""


def _out_of_time(signal_number, frame):
    raise _OutOfTime


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--wall-limit", type=int, default=900, help="seconds per cell")
    wall_limit = parser.parse_args().wall_limit
    signal.signal(signal.SIGALRM, _out_of_time)
    from dolfinx_invertible.reports.stability.study import Cell
    from dolfinx_invertible.scenes import Parameters, get_scene, run_scene

    rows = list(csv.DictReader((REPOSITORY / "docs/stability/stability.csv").open()))
    chosen = [row for row in rows if row["scene"] == "collapse" and row["cause"] in CAUSES]
    lines = [
        "| method | ν | E [Pa] | dt [s] | study: outcome (cause) | with `--self-contact`: "
        "outcome | final inverted | intersections | Newton | wall [s] |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    recovered = 0
    for number, row in enumerate(chosen, 1):
        cell = Cell("collapse", row["method"], float(row["nu"]), float(row["E"]), float(row["dt"]))
        values = cell.parameters()
        values["self_contact"] = True
        start = time.perf_counter()
        reached = {}  # the time and the Newton iterations at the last completed step
        parameters = Parameters(**values)

        def count(run, reached=reached):
            reached.update(time=run.time, newton=run.statistics.newton_iterations["total"])

        signal.alarm(wall_limit)
        try:
            summary = run_scene(
                get_scene("collapse"), parameters, comm=MPI.COMM_SELF, on_step=count
            )
            outcome = summary["outcome"]
            figures = (summary["final_inverted"], summary["intersections"],
                       summary["newton_iterations"]["total"])  # fmt: skip
        except _OutOfTime:
            outcome = (
                f"not ended after {wall_limit} s "
                f"(t = {reached.get('time', 0.0):.3g} of {parameters.t_end:.3g} s)"
            )
            figures = ("", "", reached.get("newton", 0))
        except Exception as error:  # a refused start or a solver failure is a result too
            outcome, figures = f"error: {error}", ("", "", "")
        finally:
            signal.alarm(0)
        recovered += outcome == "recovered"
        wall = time.perf_counter() - start
        lines.append(
            f"| {row['method']} | {row['nu']} | {float(row['E']):g} | {row['dt']} | "
            f"{row['outcome']} ({row['cause']}) | {outcome} | {figures[0]} | {figures[1]} | "
            f"{figures[2]} | {wall:.1f} |"
        )
        print(f"[{number}/{len(chosen)}] {lines[-1]}", flush=True)
    lines.append("")
    lines.append(f"Recovered with self-contact: {recovered} of {len(chosen)}.")
    (REPOSITORY / "docs/stability/self_contact.md").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
