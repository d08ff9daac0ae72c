"""The largest time step at which a dynamic scene's first step is convex, from its t = 0 state.

Backward Euler's step energy has the Hessian M/dt² + K (M the mass, K the elastic tangent), so
it is convex for every dt below dt* = (−λ_min)^(−1/2), λ_min the smallest eigenvalue of
K v = λ M v (lumped M). Assembles both from the scene's own problem at t = 0 and prints λ_min,
λ_max and dt*; one rank (SciPy's Lanczos on the gathered matrices)::

    .venv/bin/python tools/convexity_time_scale.py scatter --resolution 16

docs/performance.md ("The scatter's first steps") compares dt* with the step that passes.
"""

from __future__ import annotations

import argparse
import json

from mpi4py import MPI

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from dolfinx_invertible import _compat
from dolfinx_invertible.scenes import Parameters, RunObserver, get_scene, run_scene


class _MeasuredError(Exception):
    """Ends the run once the t = 0 state has been measured."""


def _scipy(matrix) -> scipy.sparse.csr_matrix:
    indptr, indices, data = matrix.getValuesCSR()
    size = matrix.getSize()[0]
    return scipy.sparse.csr_matrix((data, indices, indptr), shape=(size, size))


class ConvexityTimeScale(RunObserver):
    """Measures the t = 0 state when the run starts, then stops it."""

    def start(self, run) -> None:
        stepper = run.stepper
        problem = stepper.problem.energy_problem
        x = problem.create_vector()
        _compat.petsc_vector(run.u).copy(x)
        matrix = problem.create_matrix()
        with stepper.inertia_weight(0.0):
            problem.J(None, x, matrix, matrix)
        elastic = _scipy(matrix).copy()
        matrix.zeroEntries()
        with stepper.inertia_weight(1.0):
            problem.J(None, x, matrix, matrix)
        lumped = np.asarray((_scipy(matrix) - elastic).sum(axis=1)).ravel()
        scale = scipy.sparse.diags(1.0 / np.sqrt(lumped))
        scaled = scale @ elastic @ scale
        lowest = scipy.sparse.linalg.eigsh(
            scaled, k=3, which="SA", return_eigenvectors=False, maxiter=20000, tol=1e-4
        )
        highest = scipy.sparse.linalg.eigsh(
            scaled, k=1, which="LA", return_eigenvectors=False, maxiter=20000, tol=1e-3
        )
        smallest = float(min(lowest))
        print(
            json.dumps(
                {
                    "unknowns": elastic.shape[0],
                    "lambda_min": smallest,
                    "lambda_max": float(highest[0]),
                    "dt_convex": 1.0 / np.sqrt(-smallest) if smallest < 0.0 else None,
                    "dt": run.parameters.dt,
                }
            ),
            flush=True,
        )
        raise _MeasuredError


def main() -> None:
    """Measure one scene at one resolution."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--resolution", type=int, required=True)
    arguments = parser.parse_args()
    if MPI.COMM_WORLD.size != 1:
        raise SystemExit("run on one rank: the matrices are gathered by SciPy")
    scene = get_scene(arguments.scene)
    if not scene.dynamic:
        raise SystemExit(f"{arguments.scene} has no time steps")
    values = dict(scene.defaults) | {"resolution": arguments.resolution}
    try:
        observers = [ConvexityTimeScale()]
        run_scene(scene, Parameters(**values), comm=MPI.COMM_WORLD, observers=observers)
    except _MeasuredError:
        pass


if __name__ == "__main__":
    main()
