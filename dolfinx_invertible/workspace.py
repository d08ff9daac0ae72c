"""Scratch memory for the per-point kernels: one flat float64 buffer on the caller's stack.

The point functions never allocate. Everything they write lives in one ``work`` buffer of
``WORKSPACE_SIZE`` entries, created by ``stack_buffer`` in the outermost compiled function (a
batch loop or a cell kernel) and passed down as a single array; each function takes the views
it needs through the accessors below. Views of a stack buffer carry no reference count, and a
single array is cheap to pass: a tuple of two dozen heap arrays cost more per call (reference
counting and argument copies) than the energy evaluation itself.

Slots are sized for 3D; 2D uses the leading part of each.
"""

from __future__ import annotations

import numba
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["WORKSPACE_SIZE", "stack_buffer", "stack_array", "address", "new_workspace",
           "vector", "matrix", "table", "tensor3", "tensor4"]  # fmt: skip

# Slot offsets. Vectors take 3 entries, matrices 9, tables (d, 5) 15, third-order tensors 27,
# fourth-order 81, mode sets (d, d²) 27.
SIGMA, U, V = 0, 3, 12
G, H = 21, 24  # gradient and Hessian of the (extended) energy in σ
MODEL_G, MODEL_H, MODEL_T, MODEL_Q = 33, 36, 45, 72  # derivatives of the model itself
F_TABLE, H_TABLE = 153, 168  # separable-form tables of the model
Q_POINT, A_OFFSET, Z, N, T2, Q3 = 183, 186, 189, 192, 195, 198  # extension vectors
T1, Q2, DN = 201, 210, 219  # extension matrices
A_BLOCK, EIGENVALUES, EIGENVECTORS = 228, 237, 240  # SPD projection
MODES, WEIGHTED = 249, 276  # F-space assembly
STRETCH_MODE, TWIST_MODE = 303, 312  # one pair's stretch and twist modes, d² entries each
WORKSPACE_SIZE = 321


@intrinsic
def stack_buffer(typingctx):
    """A pointer to ``WORKSPACE_SIZE`` float64 on the calling function's stack.

    Valid until the function that calls this returns; use it in the outermost kernel or loop.
    """

    def codegen(context, builder, signature, args):
        element = context.get_data_type(types.float64)
        return cgutils.alloca_once(builder, element, size=WORKSPACE_SIZE)

    return types.CPointer(types.float64)(), codegen


@intrinsic
def stack_array(typingctx, size):
    """A pointer to ``size`` float64 on the calling function's stack; ``size`` a constant."""
    if not isinstance(size, types.IntegerLiteral):
        return None
    count = size.literal_value

    def codegen(context, builder, signature, args):
        element = context.get_data_type(types.float64)
        return cgutils.alloca_once(builder, element, size=count)

    return types.CPointer(types.float64)(size), codegen


@intrinsic
def address(typingctx, array, offset):
    """Pointer to ``array[offset]`` (no bounds check)."""

    def codegen(context, builder, signature, args):
        view = context.make_array(signature.args[0])(context, builder, args[0])
        return builder.gep(view.data, [args[1]])

    return types.CPointer(array.dtype)(array, offset), codegen


@numba.njit(cache=True)
def new_workspace(pointer):
    """The zeroed ``WORKSPACE_SIZE`` buffer behind ``pointer`` as an array."""
    work = numba.carray(pointer, WORKSPACE_SIZE)
    work[:] = 0.0
    return work


# Views are built with carray on a pointer into the buffer: a reshape would call into numba's C
# helper on every access, which costs more than the arithmetic that follows.
@numba.njit(cache=True)
def vector(work, offset, d):
    return numba.carray(address(work, offset), d)


@numba.njit(cache=True)
def matrix(work, offset, d):
    return numba.carray(address(work, offset), (d, d))


@numba.njit(cache=True)
def table(work, offset, d):
    return numba.carray(address(work, offset), (d, 5))


@numba.njit(cache=True)
def tensor3(work, offset, d):
    return numba.carray(address(work, offset), (d, d, d))


@numba.njit(cache=True)
def tensor4(work, offset, d):
    return numba.carray(address(work, offset), (d, d, d, d))


@numba.njit(cache=True)
def modes(work, offset, d):
    return numba.carray(address(work, offset), (d, d * d))
