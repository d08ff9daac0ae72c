"""Watch a scene's Newton iterations: direction, step, Krylov count and reason, per attempt.

A RunObserver on the public API (docs/guide.md, "Watching the solver"); what the measurements
of docs/performance.md ("Scale") were taken with. Run it like a scene:

    mpirun -n 2 .venv/bin/python tools/probe_run.py collapse --resolution 24 --t-stop 0.05 \\
        --linear-solver iterative --verbose
    ... --petsc-option ksp_rtol=1e-8 --problem-option blend_after=0
"""

from __future__ import annotations

import argparse
import collections
import json
import time

from mpi4py import MPI

from dolfinx_invertible.scenes import Parameters, RunObserver, get_scene, run_scene


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--resolution", type=int)
    parser.add_argument("--t-end", type=float, dest="t_end")
    parser.add_argument("--t-stop", type=float, dest="t_stop", help="stop here; the scene's "
                        "loading keeps its schedule over t_end")  # fmt: skip
    parser.add_argument("--dt", type=float)
    parser.add_argument("--nu", type=float)
    parser.add_argument("--count", type=int, help="bodies, for the scenes that have a count")
    parser.add_argument("--linear-solver", dest="linear_solver", default="auto")
    parser.add_argument("--pc", default="gamg")
    parser.add_argument("--globalization", default="auto")
    parser.add_argument("--petsc-option", action="append", default=[], dest="petsc_option")
    parser.add_argument("--problem-option", action="append", default=[], dest="problem_option")
    parser.add_argument("--verbose", action="store_true", help="one line per Newton iteration")
    parser.add_argument("--resume", metavar="DIR", help="continue the stopped run in DIR "
                        "(it is written to)")  # fmt: skip
    arguments = parser.parse_args()
    scene = get_scene(arguments.scene)
    values = dict(scene.defaults)
    for name in (
        "resolution",
        "t_end",
        "t_stop",
        "dt",
        "nu",
        "count",
        "linear_solver",
        "pc",
        "globalization",
    ):
        if getattr(arguments, name) is not None:
            values[name] = getattr(arguments, name)
    petsc = dict(option.partition("=")[::2] for option in arguments.petsc_option)
    problem = {
        name: json.loads(value)
        for name, _, value in (option.partition("=") for option in arguments.problem_option)
    }
    comm = MPI.COMM_WORLD
    probe = Probe(comm, arguments.verbose)
    summary = run_scene(
        scene,
        Parameters(**values),
        output=arguments.resume,
        resume=arguments.resume is not None,
        petsc_options={name: value or None for name, value in petsc.items()},
        comm=comm,
        observers=[probe],
        problem_options=problem,
    )
    if comm.rank == 0:
        print("directions", dict(probe.kinds), "linear reasons", dict(probe.reasons))
        print("capped Newton steps by the limit that bound them", dict(probe.binding))
        keys = ("outcome", "steps", "newton_iterations", "linear_iterations", "wall_time_s")
        print(json.dumps({key: summary[key] for key in keys} | {"stepping": summary["stepping"]}))


class Probe(RunObserver):
    """Prints every attempt (and with ``verbose`` every Newton iteration) on rank 0."""

    def __init__(self, comm, verbose: bool):
        self.comm = comm
        self.verbose = verbose
        self.kinds: collections.Counter = collections.Counter()
        self.reasons: collections.Counter = collections.Counter()
        self.binding: collections.Counter = collections.Counter()
        self._caps: dict[str, float] = {}  # the caps below 1 of the step being taken
        self.started = time.perf_counter()

    def start(self, run) -> None:
        unknowns = run.u.function_space.dofmap.index_map.size_global * run.mesh.geometry.dim
        self._print(f"{unknowns} unknowns, {run.minimizer.linear_solver} linear solver")

    def step_cap(self, run, cap) -> None:
        if cap.cap < 1.0:
            name = type(cap.limit).__name__
            self._caps[name] = min(self._caps.get(name, 1.0), cap.cap)

    def iteration(self, run, iteration) -> None:
        if iteration.iteration == 0:
            return
        if self._caps:
            self.binding[min(self._caps, key=self._caps.get)] += 1
            self._caps = {}
        self.kinds[iteration.direction] += 1
        self.reasons[iteration.linear_reason] += 1
        if self.verbose:
            self._print(
                f"  {iteration.iteration:3d} |r| {iteration.residual_norm:.3e} energy "
                f"{iteration.energy} {iteration.direction:9s} step {iteration.step_length:.3g} "
                f"cap {iteration.step_cap:.3g} Krylov {iteration.linear_iterations:4d} "
                f"{iteration.linear_reason} AMG on {run.minimizer.directions.preconditioned_by}"
                f"{self._trust_region(run)}"
            )

    @staticmethod
    def _trust_region(run) -> str:
        region = run.minimizer.directions.trust_region
        if region is None:
            return ""
        return f" radius {region.radius:.3g} rho {region.ratio:.3g}"

    def attempt(self, run, attempt) -> None:
        result = attempt.result
        verdict = "accepted" if attempt.accepted else "FAILED  "
        self._print(
            f"t {attempt.start:.5g} -> {attempt.end:.5g} {verdict} "
            f"Newton {result.newton_iterations:3d} "
            f"Krylov {result.linear_iterations:5d} projected {result.projected_iterations:3d} "
            f"{result.reason_name} {result.linear_reason_name} "
            f"{time.perf_counter() - self.started:.1f} s"
        )

    def _print(self, text: str) -> None:
        if self.comm.rank == 0:
            print(text, flush=True)


if __name__ == "__main__":
    main()
