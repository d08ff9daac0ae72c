"""Print the barrier's curvature by collision type at every fifth Newton iteration of a contact run.

For each type of ipctk collision (face–vertex, edge–edge, edge–vertex, vertex–vertex) in the
barrier's set: how many pairs, how many have negative curvature, the sum of the negative and of
the positive eigenvalues of their Hessians, and the worst ratio λ_min / λ_max of one pair (0
where none is negative). What docs/contact.md ("The barrier's negative curvature, pair by
pair") was measured with; serial only (every rank holds the whole surface, so more ranks
would repeat the same work and print it once each):

    .venv/bin/python tools/barrier_curvature.py cubes-in-bowl --resolution 2 --from 0.38 \\
        --t-stop 0.7
"""

from __future__ import annotations

import argparse
import collections

from mpi4py import MPI

import numpy as np

from dolfinx_invertible.contact import BodyContactTerm
from dolfinx_invertible.scenes import Parameters, RunObserver, get_scene, run_scene


class Curvature(RunObserver):
    """Prints the curvature of the barrier's pairs by type (see the module description)."""

    def __init__(self, start: float, every: int) -> None:
        self.begin = start
        self.every = every
        self.count = 0

    def iteration(self, run, iteration) -> None:
        term = next((term for term in run.terms if isinstance(term, BodyContactTerm)), None)
        if iteration.iteration == 0 or term is None or run.stepper.time < self.begin:
            return
        self.count += 1
        if self.count % self.every:
            return
        positions = term.positions()
        collisions = term._collisions_for(positions)  # the barrier's own set at this iterate
        mesh = term.collision_mesh
        # per type: pairs, pairs with negative curvature, Σ|λ<0|, Σλ>0, worst λ_min/λ_max
        table = collections.defaultdict(lambda: [0, 0, 0.0, 0.0, 0.0])
        for index in range(len(collisions)):
            collision = collisions[index]
            stencil = collision.dof(positions, mesh.edges, mesh.faces)
            hessian = term.potential.hessian(collision, stencil)
            eigenvalues = np.linalg.eigvalsh(0.5 * (hessian + hessian.T))
            row = table[type(collision).__name__.removesuffix("NormalCollision")]
            row[0] += 1
            row[1] += eigenvalues[0] < -1e-8 * abs(eigenvalues[-1])
            row[2] += -min(eigenvalues[0], 0.0)
            row[3] += max(eigenvalues[-1], 0.0)
            row[4] = min(row[4], eigenvalues[0] / max(eigenvalues[-1], np.finfo(float).tiny))
        print(
            f"t = {run.stepper.time:.4f} s, iteration {iteration.iteration}, residual "
            f"{iteration.residual_norm:.2e}, {iteration.direction}, kappa {term.stiffness:.3g}, "
            f"{len(collisions)} pairs: "
            + " | ".join(
                f"{name} {row[0]} ({row[1]} negative) sum|neg| {row[2]:.3g} sum pos {row[3]:.3g} "
                f"worst {row[4]:.2f}"
                for name, row in sorted(table.items())
            ),
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--resolution", type=int)
    parser.add_argument("--count", type=int)
    parser.add_argument("--from", type=float, default=0.0, dest="start")
    parser.add_argument("--t-stop", type=float, dest="t_stop")
    parser.add_argument("--every", type=int, default=5)
    arguments = parser.parse_args()
    if MPI.COMM_WORLD.size > 1:
        parser.error("run it serially")
    scene = get_scene(arguments.scene)
    values = dict(scene.defaults)
    for name in ("resolution", "count", "t_stop"):
        if getattr(arguments, name) is not None:
            values[name] = getattr(arguments, name)
    observer = Curvature(arguments.start, arguments.every)
    run_scene(scene, Parameters(**values), output=None, comm=MPI.COMM_WORLD, observers=[observer])


if __name__ == "__main__":
    main()
