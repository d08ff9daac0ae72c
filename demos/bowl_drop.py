"""A soft cube dropped into a bowl: it falls, hits the bottom, rocks and settles.

The ``bowl-drop`` scene (``dolfinx-invertible run bowl-drop``, see
``dolfinx_invertible/scenes/bowl_drop.py``) with one check more, through a ``RunObserver`` (the
public way to watch a run): besides the boundary vertices of every accepted step, every Newton
iterate is checked for vertices inside the bowl. Prints
the smallest gap over the run and both penetration counts, which must be 0: the script exits
non-zero otherwise. Writes ``output/bowl-drop/`` (XDMF, step log, summary).

    .venv/bin/python demos/bowl_drop.py
    mpirun -n 2 .venv/bin/python demos/bowl_drop.py
"""

from __future__ import annotations

import sys
from pathlib import Path

# mpi4py before dolfinx: the PyPI DOLFINx wheel loads its MPI library through mpi4py.
from mpi4py import MPI

from dolfinx_invertible.scenes import Parameters, RunObserver, run_scene
from dolfinx_invertible.scenes.bowl_drop import BowlDrop


class IterateCheck(RunObserver):
    """Counts boundary vertices inside the bowl at every Newton iterate of the run."""

    def __init__(self):
        self.iterates = 0
        self.penetrations = 0
        self.min_gap = float("inf")

    def iteration(self, run, iteration) -> None:
        """Check the iterate: ``u`` holds it during the call (collective on every rank)."""
        contact = run.scene.contact
        self.iterates += 1
        self.penetrations += contact.penetrations()
        self.min_gap = min(self.min_gap, contact.minimum_gap())


def drop(*, comm=MPI.COMM_WORLD, output: Path | None = None, quiet: bool = True, **values):
    """Run the scene with its defaults, changed by ``values``; return the summary.

    The summary gets the demo's own figures: ``iterates`` checked, ``iterate_penetrations``
    found there, and ``min_gap`` taken over the iterates too.
    """
    parameters = Parameters(**{**BowlDrop.defaults, **values})
    check = IterateCheck()
    summary = run_scene(
        BowlDrop, parameters, output=output, quiet=quiet, comm=comm, observers=[check]
    )
    summary.update(
        iterates=check.iterates,
        iterate_penetrations=check.penetrations,
        min_gap=min(summary["min_gap"], check.min_gap),
    )
    return summary


def main() -> int:
    """Run the scene and print its figures; non-zero exit on any penetration."""
    comm = MPI.COMM_WORLD
    summary = drop(comm=comm, output=Path("output") / BowlDrop.name, quiet=False)
    if comm.rank == 0:
        centre = summary["final_centre"]
        print(
            f"{summary['steps']} steps ({summary['stepping']['cuts']} cuts), "
            f"{summary['newton_iterations']['total']} Newton iterations on {comm.size} rank(s), "
            f"wall {summary['wall_time_s']:.1f} s; "
            f"barrier d̂ = {summary['barrier_distance']:.3e} m\n"
            f"smallest gap over the run {summary['min_gap']:.3e} m; penetrations after "
            f"accepted steps {summary['penetrations']}, at Newton iterates "
            f"{summary['iterate_penetrations']} (of {summary['iterates']})\n"
            f"end: kinetic energy {summary['final_kinetic_energy']:.2e} J (peak "
            f"{summary['peak_kinetic_energy']:.2e} J), centre z = {centre[2]:.4f} m "
            f"(a rigid cube would rest at {summary['rest_centre_height']:.4f} m)",
            flush=True,
        )
    clean = summary["penetrations"] == 0 and summary["iterate_penetrations"] == 0
    return 0 if summary["completed"] and clean else 1


if __name__ == "__main__":
    sys.exit(main())
