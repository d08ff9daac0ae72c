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

from dolfinx_invertible.constitutive.compiled import compiled_only

__all__ = ["WORKSPACE_SIZE", "stack_buffer", "stack_array", "address", "new_workspace",
           "vector", "matrix", "table", "tensor3", "tensor4"]  # fmt: skip

# Slot sizes (3D; 2D uses the leading part of each).
VECTOR = 3
MATRIX = 9
TABLE = 15  # (d, 5): a function and its first four derivatives at each singular value
TENSOR3 = 27
TENSOR4 = 81
MODE_SET = 27  # (d, d²)
MODE = 9  # one d² mode


class _Layout:
    """Hands out consecutive slots of a flat buffer; ``size`` is the total so far."""

    def __init__(self) -> None:
        self.size = 0

    def slot(self, size: int) -> int:
        offset = self.size
        self.size += size
        return offset


_layout = _Layout()
# The polar SVD.
SIGMA = _layout.slot(VECTOR)
U = _layout.slot(MATRIX)
V = _layout.slot(MATRIX)
# Gradient and Hessian of the (extended) energy in σ.
G = _layout.slot(VECTOR)
H = _layout.slot(MATRIX)
# Derivatives of the model itself (at σ, or at an extension's anchor point).
MODEL_G = _layout.slot(VECTOR)
MODEL_H = _layout.slot(MATRIX)
MODEL_T = _layout.slot(TENSOR3)
MODEL_Q = _layout.slot(TENSOR4)
# Separable-form tables of the model.
F_TABLE = _layout.slot(TABLE)
H_TABLE = _layout.slot(TABLE)
# Extension vectors and matrices.
Q_POINT = _layout.slot(VECTOR)
A_OFFSET = _layout.slot(VECTOR)
Z = _layout.slot(VECTOR)
N = _layout.slot(VECTOR)
T2 = _layout.slot(VECTOR)
Q3 = _layout.slot(VECTOR)
T1 = _layout.slot(MATRIX)
Q2 = _layout.slot(MATRIX)
DN = _layout.slot(MATRIX)
# SPD projection.
A_BLOCK = _layout.slot(MATRIX)
EIGENVALUES = _layout.slot(VECTOR)
EIGENVECTORS = _layout.slot(MATRIX)
# F-space assembly: the diagonal modes, weighted modes, and one pair's stretch and twist modes.
MODES = _layout.slot(MODE_SET)
WEIGHTED = _layout.slot(MODE_SET)
STRETCH_MODE = _layout.slot(MODE)
TWIST_MODE = _layout.slot(MODE)
# The region code of the SVD path (:mod:`~dolfinx_invertible.constitutive.svd_path`).
REGION = _layout.slot(1)
WORKSPACE_SIZE = _layout.size


@intrinsic
def stack_buffer(typingctx):
    """Return a pointer to ``WORKSPACE_SIZE`` float64 on the calling function's stack.

    Valid until the function that calls this returns; use it in the outermost kernel or loop.
    """

    def codegen(context, builder, signature, args):
        element = context.get_data_type(types.float64)
        return cgutils.alloca_once(builder, element, size=WORKSPACE_SIZE)

    return types.CPointer(types.float64)(), codegen


@intrinsic
def stack_array(typingctx, size):
    """Return a pointer to ``size`` float64 on the calling function's stack; ``size`` a constant."""
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


@compiled_only
def new_workspace(pointer):
    """Return the ``WORKSPACE_SIZE`` buffer behind ``pointer`` as an array, not zeroed.

    Every slot is written before it is read (the derivative tensors up to the order asked for,
    the SVD, the tables), so no zeroing is needed: a cell kernel that takes the invariant fast
    path never touches the buffer and need not pay for clearing its 2.5 kB on every cell (the
    tests run once with it filled with NaN instead).
    """
    return numba.carray(pointer, WORKSPACE_SIZE)


# Views are built with carray on a pointer into the buffer: a reshape would call into numba's C
# helper on every access, which costs more than the arithmetic that follows.
@compiled_only
def vector(work, offset, d):
    """View the slot at ``offset`` as a vector of length d."""
    return numba.carray(address(work, offset), d)


@compiled_only
def matrix(work, offset, d):
    """View the slot at ``offset`` as a d×d matrix."""
    return numba.carray(address(work, offset), (d, d))


@compiled_only
def table(work, offset, d):
    """View the slot at ``offset`` as a (d, 5) table."""
    return numba.carray(address(work, offset), (d, 5))


@compiled_only
def tensor3(work, offset, d):
    """View the slot at ``offset`` as a d×d×d tensor."""
    return numba.carray(address(work, offset), (d, d, d))


@compiled_only
def tensor4(work, offset, d):
    """View the slot at ``offset`` as a d×d×d×d tensor."""
    return numba.carray(address(work, offset), (d, d, d, d))


@compiled_only
def modes(work, offset, d):
    """View the slot at ``offset`` as d modes of d² entries."""
    return numba.carray(address(work, offset), (d, d * d))
