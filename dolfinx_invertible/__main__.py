"""Command-line entry point: ``python -m dolfinx_invertible <command> ...``.

Commands:

- ``bench <subcommand> ...``: benchmarks, see :mod:`dolfinx_invertible.bench`
  (e.g. ``python -m dolfinx_invertible bench material --points 200000``).
"""

from __future__ import annotations

import sys
from typing import Callable, Dict, Sequence


def _bench(argv: Sequence[str]) -> int:
    # Imported lazily so that other commands do not pay for (or depend on) the benchmark module.
    from dolfinx_invertible import bench

    return bench.main(argv)


# name -> handler taking the remaining arguments and returning an exit code.
COMMANDS: Dict[str, Callable[[Sequence[str]], int]] = {"bench": _bench}


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
