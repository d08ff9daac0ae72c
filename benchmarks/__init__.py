"""Benchmarks of the package, in its source checkout only: this folder is not installed.

Run as ``python -m dolfinx_invertible bench NAME`` (each has ``--help``): the package's command
line finds this folder next to the package directory. ``python -m benchmarks NAME`` from the
repository root, or ``python path/to/benchmarks NAME`` from anywhere, is the same command.

Each benchmark module has ``add_arguments(parser)`` and ``command(arguments)``, prints a table
and writes JSON (``--json PATH``, otherwise JSON on stdout and the table on stderr). Ratios are
against a baseline measured in the same run; every report records the load average before and
after. Modules import DOLFINx only inside their functions, so listing them is cheap and the
material benchmark runs without DOLFINx.

- ``material``: the constitutive kernels, numba against the NumPy reference of the tests
  (``tests/constitutive/numpy_reference.py``);
- ``assembly``, ``points``, ``solve``, ``scaling``, ``compile``, ``memory``: the DOLFINx side;
- ``scenes``: whole scenes at growing resolutions, both solver paths;
- ``contact``: the contact scenes, where a run's time goes, per rank count;
- :mod:`.common`: cases, timing and reporting shared by the DOLFINx benchmarks;
- :mod:`.threads`: one thread per process;
- :mod:`.cold_start` and :mod:`.tangent_points`: scripts of their own, outside the command line
  (``python -m benchmarks.cold_start``, ``python benchmarks/tangent_points.py``).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from pathlib import Path

__all__ = ["BENCHMARKS", "FOLDER", "add_arguments", "command", "command_line"]

#: name -> one-line description; the module of the same name implements it.
BENCHMARKS = {
    "material": "Neo-Hookean + C2 material kernels: numba vs NumPy reference",
    "assembly": "residual, tangent and Newton step: our kernels vs FFCx's UFL Neo-Hookean and a "
    "zero kernel",
    "points": "per-point cost of each kernel stage (SVD, extension, stress, tangent): the profile",
    "solve": "time to solution on Cook's membrane: UFL Neo-Hookean vs our kernels, same solver",
    "scaling": "MPI speed-up of assembly and a Newton step, mpirun -n 1 vs -n 2",
    "compile": "cold and warm kernel compilation, and concurrent ranks on an empty numba cache",
    "memory": "peak resident memory of building and one Newton step of a large P1 problem",
    "scenes": "scenes as their meshes grow: outcome, Newton and Krylov counts, time and memory "
    "per step, on the direct and the iterative path",
    "contact": "contact scenes: cells, surface vertices, steps, cuts, Newton and Krylov counts, "
    "and the shares of the time in candidates, CCD, barrier, elastic and linear solve",
}

#: This folder.
FOLDER = Path(__file__).resolve().parent


def command_line(argv: Sequence[str]) -> list[str]:
    """Command line of ``python -m dolfinx_invertible bench *argv`` in a new interpreter.

    It runs this folder (``python FOLDER *argv``, see ``__main__.py``) rather than the
    package's command line, which finds the benchmarks only next to the package: an installed
    package (the CI's wheel lane) has none beside it.
    """
    return [sys.executable, str(FOLDER), *argv]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add one subcommand per benchmark to ``parser``, the command line's ``bench``."""
    benchmarks = parser.add_subparsers(dest="benchmark", required=True, metavar="NAME")
    for name, description in BENCHMARKS.items():
        subparser = benchmarks.add_parser(name, help=description, description=description)
        importlib.import_module(f"{__name__}.{name}").add_arguments(subparser)
        subparser.set_defaults(handler=command)


def command(arguments: argparse.Namespace) -> int:
    """Run the benchmark ``arguments.benchmark`` on one thread per process; its exit code.

    ``arguments.bench_argv`` holds the arguments after ``bench``, for the restart with one
    thread (:func:`~benchmarks.threads.restart_with_one_thread`).
    """
    from benchmarks.threads import restart_with_one_thread

    if getattr(arguments, "points", 1) < 1 or getattr(arguments, "repeats", 1) < 1:
        print("--points and --repeats must be at least 1", file=sys.stderr)
        return 2
    restart_with_one_thread(arguments.bench_argv)
    module = importlib.import_module(f"{__name__}.{arguments.benchmark}")
    return module.command(arguments)
