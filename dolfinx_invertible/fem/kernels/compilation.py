"""The C entry points DOLFINx calls, compiled on first use into numba's disk cache.

One entry per (kind, dimension). Two arities exist because ufcx's ``tabulate_tensor`` gained a
``custom_data`` pointer in DOLFINx 0.10; :mod:`~dolfinx_invertible._compat` says which one this
DOLFINx wants. An entry is compiled only when a form first needs it, so a scene that never asks
for the energy, say, never compiles its kernel.
"""

from __future__ import annotations

import time

import numba

from dolfinx_invertible.fem.kernels.cells import cell_energy, cell_residual, cell_tangent
from dolfinx_invertible.fem.kernels.counters import KERNEL_KINDS

__all__ = ["compile_kernel", "kernel_address", "precompile"]

_COMPILED: dict[tuple[str, int], object] = {}


# Each entry names its cell function as a global and captures only the dimension: numba keys its
# disk cache on the captured values, which must stay plain numbers.
def _entries(kind: str, d: int) -> tuple:
    if kind == "energy":

        def entry(A_, w_, c_, coordinates_, entity_local_index, permutation):
            cell_energy(A_, w_, c_, coordinates_, d)

        def entry_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
            cell_energy(A_, w_, c_, coordinates_, d)

    elif kind == "residual":

        def entry(A_, w_, c_, coordinates_, entity_local_index, permutation):
            cell_residual(A_, w_, c_, coordinates_, d)

        def entry_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
            cell_residual(A_, w_, c_, coordinates_, d)

    else:

        def entry(A_, w_, c_, coordinates_, entity_local_index, permutation):
            cell_tangent(A_, w_, c_, coordinates_, d)

        def entry_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
            cell_tangent(A_, w_, c_, coordinates_, d)

    return entry, entry_with_data


def compile_kernel(entries: tuple) -> object:
    """Compile a numba ``cfunc`` with the kernel signature of the running DOLFINx.

    ``entries`` holds the six-argument and the seven-argument (``custom_data``) Python function;
    the one matching :data:`dolfinx_invertible._compat.KERNEL_TAKES_CUSTOM_DATA` is compiled
    (or loaded from numba's disk cache).
    """
    from dolfinx_invertible import _compat

    entry = entries[1] if _compat.KERNEL_TAKES_CUSTOM_DATA else entries[0]
    return numba.cfunc(_compat.KERNEL_SIGNATURE, nopython=True, cache=True)(entry)


def kernel_address(kind: str, dimension: int) -> int:
    """Return the address of a compiled cell kernel.

    Parameters
    ----------
    kind
        ``"energy"``, ``"residual"`` or ``"tangent"``.
    dimension
        2 or 3; any supported element of that dimension uses the same kernel.
    """
    if kind not in KERNEL_KINDS:
        raise ValueError(f"kind must be one of {KERNEL_KINDS}, got {kind!r}")
    if dimension not in (2, 3):
        raise ValueError(f"no kernel for dimension {dimension}; 2 and 3 are supported")
    key = (kind, int(dimension))
    if key not in _COMPILED:
        _COMPILED[key] = compile_kernel(_entries(*key))
    return _COMPILED[key].address


def precompile(dimensions: tuple[int, ...] = (3, 2)) -> dict[tuple[str, int], float]:
    """Compile every cell kernel for ``dimensions`` into numba's disk cache; seconds per kernel.

    ``make setup`` runs this (``python -m dolfinx_invertible compile``) so that the first
    assembly in a user's script loads the kernels instead of compiling them; with a warm cache
    it takes about a second.
    """
    seconds = {}
    for dimension in dimensions:
        for kind in KERNEL_KINDS:
            start = time.perf_counter()
            kernel_address(kind, dimension)
            seconds[(kind, dimension)] = time.perf_counter() - start
    return seconds
