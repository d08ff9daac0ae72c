"""One thread per process for every benchmark, set before numerical libraries load.

Thread pools (numba's, OpenMP's, OpenBLAS's) size themselves once, when their library is loaded,
from these variables; setting them later has no effect. A benchmark started in a process that
already loaded numpy or numba without them therefore restarts the interpreter with them set.

The question the benchmarks answer is how much a compiled per-point kernel gains per core;
NumPy's batched SVD and eigen-decompositions run one small LAPACK call per matrix on a single
thread anyway, so more threads would measure the core count rather than the code, and on a
shared small machine they mostly add noise.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

from benchmarks import command_line

__all__ = ["THREAD_VARIABLES", "restart_with_one_thread", "threads_pinned"]

THREAD_VARIABLES = {
    "NUMBA_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}


def threads_pinned() -> bool:
    """Whether this process started with one thread per library (the variables set)."""
    return all(os.environ.get(name) == value for name, value in THREAD_VARIABLES.items())


def restart_with_one_thread(argv: Sequence[str]) -> None:
    """Replace this process by ``python -m dolfinx_invertible bench *argv`` with one thread.

    The new process runs :func:`benchmarks.command_line`. Returns only if the variables were
    already set when the process started.
    """
    if threads_pinned():
        return
    os.environ.update(THREAD_VARIABLES)
    sys.stdout.flush()
    sys.stderr.flush()
    command = command_line(argv)
    # Python's copy of the environment, not the process's: a process that has initialised MPI
    # (as a singleton, on importing DOLFINx) carries Open MPI's variables for it, and an mpirun
    # started from an image that inherited them fails in orte_init ("getting local rank").
    os.execve(command[0], command, dict(os.environ))
