"""Command-line entry point: ``python -m dolfinx_invertible <command> ...``.

Commands:

- ``bench <subcommand> ...``: benchmarks, see :mod:`dolfinx_invertible.bench`
  (e.g. ``python -m dolfinx_invertible bench material --points 200000``).
- ``compile``: compile the DOLFINx cell kernels (2D and 3D) into numba's disk cache, so that
  the first assembly of a script does not pay for it (``make setup`` runs it).
"""

from __future__ import annotations

import sys
from typing import Callable, Dict, Sequence


def _bench(argv: Sequence[str]) -> int:
    # Imported lazily so that other commands do not pay for (or depend on) the benchmark module.
    from dolfinx_invertible import bench

    return bench.main(argv)


def _compile(argv: Sequence[str]) -> int:
    import time

    from dolfinx_invertible import kernels

    if argv:
        print("usage: python -m dolfinx_invertible compile", file=sys.stderr)
        return 2
    start = time.perf_counter()
    seconds = kernels.precompile()
    details = ", ".join(
        f"{kind} {dimension}D {value:.1f} s" for (kind, dimension), value in seconds.items()
    )
    print(
        f"kernels compiled or loaded from the cache in {time.perf_counter() - start:.1f} s "
        f"({details})"
    )
    return 0


# name -> handler taking the remaining arguments and returning an exit code.
COMMANDS: Dict[str, Callable[[Sequence[str]], int]] = {"bench": _bench, "compile": _compile}


def main(argv: Sequence[str] | None = None) -> int:
    """Dispatch to a command; returns the process exit code.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments after the program name; defaults to ``sys.argv[1:]``.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in COMMANDS:
        print(f"usage: python -m dolfinx_invertible {{{','.join(COMMANDS)}}} ...", file=sys.stderr)
        return 2
    return COMMANDS[argv[0]](argv[1:])


if __name__ == "__main__":
    sys.exit(main())
