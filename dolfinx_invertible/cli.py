"""The command line: ``python -m dolfinx_invertible`` or ``dolfinx-invertible``.

Subcommands:

- ``compile``: compile the DOLFINx cell kernels of the default materials
  (:data:`~dolfinx_invertible.fem.kernels.DEFAULT_MATERIALS`, 2D and 3D) into numba's disk
  cache, so that the first assembly of a script does not pay for it (``make setup`` runs it);
- ``bench NAME``: a benchmark (``bench --help`` lists them).
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from collections.abc import Sequence

__all__ = ["main", "parser"]


def _compile(arguments: argparse.Namespace) -> int:
    from dolfinx_invertible.fem import kernels

    start = time.perf_counter()
    seconds = kernels.precompile()
    per_material: dict[str, float] = {}
    for (_, dimension, material), value in seconds.items():
        key = f"{material} {dimension}D"
        per_material[key] = per_material.get(key, 0.0) + value
    details = "\n".join(f"  {key}: {value:.1f} s" for key, value in per_material.items())
    print(
        f"{len(seconds)} kernels compiled or loaded from the cache in "
        f"{time.perf_counter() - start:.1f} s:\n{details}"
    )
    return 0


def _bench(arguments: argparse.Namespace) -> int:
    from dolfinx_invertible.bench.threads import restart_with_one_thread

    if getattr(arguments, "points", 1) < 1 or getattr(arguments, "repeats", 1) < 1:
        print("--points and --repeats must be at least 1", file=sys.stderr)
        return 2
    restart_with_one_thread(arguments.bench_argv)
    module = importlib.import_module(f"dolfinx_invertible.bench.{arguments.benchmark}")
    return module.command(arguments)


def parser() -> argparse.ArgumentParser:
    """Return the argument parser of the whole command line."""
    from dolfinx_invertible.bench import BENCHMARKS

    top = argparse.ArgumentParser(
        prog="dolfinx-invertible",
        description="Invertible hyperelasticity for DOLFINx (Stomakhin et al. 2012).",
    )
    commands = top.add_subparsers(dest="command", required=True, metavar="COMMAND")

    compile_parser = commands.add_parser(
        "compile",
        help="compile the cell kernels into numba's disk cache",
        description=(
            "Compile the DOLFINx cell kernels of the default materials (2D and 3D) into "
            "numba's disk cache."
        ),
    )
    compile_parser.set_defaults(handler=_compile)

    bench_parser = commands.add_parser(
        "bench", help="run a benchmark", description="Benchmarks; each prints a table and JSON."
    )
    benchmarks = bench_parser.add_subparsers(dest="benchmark", required=True, metavar="NAME")
    for name, description in BENCHMARKS.items():
        subparser = benchmarks.add_parser(name, help=description, description=description)
        importlib.import_module(f"dolfinx_invertible.bench.{name}").add_arguments(subparser)
        subparser.set_defaults(handler=_bench)
    return top


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the process exit code.

    Parameters
    ----------
    argv
        Arguments after the program name; defaults to ``sys.argv[1:]``.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    arguments = parser().parse_args(argv)
    if arguments.command == "bench":
        arguments.bench_argv = argv[argv.index("bench") + 1 :]
    return arguments.handler(arguments)
