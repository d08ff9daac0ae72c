"""Scratch arrays for the per-point kernels, living on the caller's stack.

The point functions never allocate: everything they write lives in a :class:`Workspace`. Its
arrays are views into one stack buffer (``stack_buffer`` in the outermost compiled function,
then :func:`workspace_from`), so they carry no reference count: passing the workspace down the
call chain costs no atomic increments, which on heap arrays cost more than the maths itself.
"""

from __future__ import annotations

from collections import namedtuple

import numba
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["WORKSPACE_SIZE", "Workspace", "stack_buffer", "workspace_from"]

Workspace = namedtuple(
    "Workspace",
    [
        # polar SVD
        "sigma", "U", "V",
        # derivatives of the (extended) energy in σ: gradient, Hessian
        "g", "H",
        # derivatives of the model itself (at σ, or at the extension's anchor point q)
        "model_g", "model_H", "model_T", "model_Q", "f", "h",
        # extension intermediates
        "q", "a", "z", "n", "t2", "q3", "T1", "Q2", "Dn",
        # SPD projection and F-space assembly
        "A", "eigenvalues", "eigenvectors", "modes", "weighted",
    ],
)  # fmt: skip

#: float64 entries a 3D workspace needs (2D needs fewer).
WORKSPACE_SIZE = 3 * (1 + 3 + 3 + 1 + 3 + 1 + 3 + 9 + 27 + 5 + 5 + 6 + 9 + 3 + 1 + 3 + 9 + 9)


@intrinsic
def stack_buffer(typingctx, size):
    """A pointer to ``size`` (a compile-time constant) float64 on the calling function's stack.

    Valid until the function that calls this returns; use it in the outermost kernel or loop.
    """
    if not isinstance(size, types.IntegerLiteral):
        return None

    def codegen(context, builder, signature, args):
        element = context.get_data_type(types.float64)
        return cgutils.alloca_once(builder, element, size=size.literal_value)

    return types.CPointer(types.float64)(size), codegen


@numba.njit(cache=True)
def workspace_from(pointer, d):
    """Carve a :class:`Workspace` for dimension ``d`` out of ``WORKSPACE_SIZE`` float64."""
    buffer = numba.carray(pointer, WORKSPACE_SIZE)
    buffer[:] = 0.0
    v = d
    m = d * d
    sizes = (v, m, m, v, m, v, m, m * d, m * m, 5 * d, 5 * d,
             v, v, v, v, v, v, m, m, m, m, v, m, m * d, m * d)  # fmt: skip
    offsets = [0] * len(sizes)
    total = 0
    for i in range(len(sizes)):
        offsets[i] = total
        total += sizes[i]

    def vector(i):
        return buffer[offsets[i] : offsets[i] + sizes[i]]

    return Workspace(
        vector(0), vector(1).reshape((d, d)), vector(2).reshape((d, d)),
        vector(3), vector(4).reshape((d, d)),
        vector(5), vector(6).reshape((d, d)), vector(7).reshape((d, d, d)),
        vector(8).reshape((d, d, d, d)), vector(9).reshape((d, 5)), vector(10).reshape((d, 5)),
        vector(11), vector(12), vector(13), vector(14), vector(15), vector(16),
        vector(17).reshape((d, d)), vector(18).reshape((d, d)), vector(19).reshape((d, d)),
        vector(20).reshape((d, d)), vector(21), vector(22).reshape((d, d)),
        vector(23).reshape((d, d * d)), vector(24).reshape((d, d * d)),
    )  # fmt: skip
