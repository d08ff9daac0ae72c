"""Per-form counters of quadrature points evaluated and of those that needed an SVD.

Each set of forms owns one row of :data:`PATH_COUNTERS`; its address travels in the kernels'
constants header, and every kernel adds to its own pair of fields. The pool is module-level and
never freed, so a kernel can never write into released memory whatever the lifetime of the
Python objects around a form; rows are handed out round-robin.
"""

from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.fem.kernels.constants import COUNTERS_SLOT

__all__ = [
    "COUNTER_FIELDS",
    "ENERGY_COUNTS",
    "KERNEL_KINDS",
    "PATH_COUNTERS",
    "RESIDUAL_COUNTS",
    "TANGENT_COUNTS",
    "count_points",
    "counter_row",
    "counts_by_kind",
    "integer_from_bits",
]

#: The kernels, in the order of their counter fields.
KERNEL_KINDS = ("energy", "residual", "tangent")
# Each kernel's pair (points evaluated, points through the SVD) starts at:
ENERGY_COUNTS = 0
RESIDUAL_COUNTS = 2
TANGENT_COUNTS = 4
COUNTER_FIELDS = 6

PATH_COUNTERS = np.zeros((4096, COUNTER_FIELDS))
_next_counter_row = [0]


def counter_row() -> np.ndarray:
    """Return a zeroed row of :data:`PATH_COUNTERS` for one set of forms (round-robin reuse)."""
    row = PATH_COUNTERS[_next_counter_row[0] % PATH_COUNTERS.shape[0]]
    _next_counter_row[0] += 1
    row[:] = 0.0
    return row


def counts_by_kind(row: np.ndarray) -> dict[str, tuple[int, int]]:
    """Read a counter row as ``{kind: (points, points through the SVD)}``."""
    counts = row.astype(np.int64)
    offsets = (ENERGY_COUNTS, RESIDUAL_COUNTS, TANGENT_COUNTS)
    return {
        kind: (int(counts[offset]), int(counts[offset + 1]))
        for kind, offset in zip(KERNEL_KINDS, offsets, strict=True)
    }


@intrinsic
def _pointer_from_bits(typingctx, bits):
    """Reinterpret the float64 ``bits`` as a pointer to float64 (0.0 gives null)."""

    def codegen(context, builder, signature, args):
        integer = builder.bitcast(args[0], ir.IntType(64))
        return builder.inttoptr(integer, context.get_value_type(signature.return_type))

    return types.CPointer(types.float64)(types.float64), codegen


@intrinsic
def integer_from_bits(typingctx, bits):
    """Reinterpret the float64 ``bits`` as an int64 (an address the constants carry)."""

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.int64(types.float64), codegen


@intrinsic
def _is_null(typingctx, pointer):
    def codegen(context, builder, signature, args):
        return cgutils.is_null(builder, args[0])

    return types.boolean(pointer), codegen


@compiled_only(forceinline=True)
def count_points(c, first_field, points, svd_points):
    """Add a cell's point counts to the row the constants ``c`` point to (if any)."""
    pointer = _pointer_from_bits(c[COUNTERS_SLOT])
    if not _is_null(pointer):
        counters = numba.carray(pointer, COUNTER_FIELDS)
        counters[first_field] += points
        counters[first_field + 1] += svd_points
