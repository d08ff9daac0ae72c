"""The SVD path of a point, compiled once per material as a C function called through its address.

A point that the invariant fast path cannot settle takes the SVD: U σ V, the extended energy
Ψ̂ext(σ) with its derivatives, then P and the (projected) tangent from them. That chain is most
of a material's code. Called as an ordinary compiled function it would be linked into every
caller (the point functions, each cell kernel, each batch loop, each C entry) and optimised and
compiled to machine code again in each, since numba compiles every function's module with all
of its callees. As a C function (one per model, extension and dimension, in numba's disk cache)
it is compiled once; callers pass its address at run time: the cell kernels read it from their
constants header, the batch loops take it as an argument. An address baked into compiled code
would differ from process to process and defeat the disk cache.

A cold process can compile the SVD path in a helper process (:func:`compile_svd_path_ahead`)
while it compiles the cell kernels, which do not need it until they run. Until then the kernels
call it through a stand-in (:func:`bind_svd_path`): the lazy binding of a dynamic linker, whose
first call waits for the helper and points the caller at the real function.

The region of the point comes back in the workspace's ``REGION`` slot, U, σ, V and the σ-space
derivatives in their own slots, as on the direct path.
"""

from __future__ import annotations

import ctypes
import logging
import math
from collections.abc import Callable

import numba
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from dolfinx_invertible.constitutive import compiled
from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.parameters import PARAMETER_COUNT
from dolfinx_invertible.constitutive.principal import UNDEFINED_REGION, principal_derivatives
from dolfinx_invertible.constitutive.svd import polar_svd_point
from dolfinx_invertible.constitutive.tangent import stress_derivative, workspace_first_piola

__all__ = [
    "bind_svd_path",
    "call_svd_path",
    "compile_svd_path_ahead",
    "svd_path_address",
]

_POINTER = types.CPointer(types.float64)
# F, positive_only, params, project, order, work, P, C -> Ψ
_SIGNATURE = types.float64(
    _POINTER, types.int64, _POINTER, types.int64, types.int64, _POINTER, _POINTER, _POINTER
)
_DOUBLES = ctypes.POINTER(ctypes.c_double)
_C_TYPE = ctypes.CFUNCTYPE(
    ctypes.c_double,
    _DOUBLES,
    ctypes.c_int64,
    _DOUBLES,
    ctypes.c_int64,
    ctypes.c_int64,
    _DOUBLES,
    _DOUBLES,
    _DOUBLES,
)
_COMPILED: dict[tuple[int, int, int], object] = {}
# Per material whose helper runs: the stand-in C function and the callers waiting to be bound.
_STAND_INS: dict[tuple[int, int, int], tuple[object, list[Callable[[int], None]]]] = {}
_LOG = logging.getLogger(__name__)


# The ids and the dimension are captured integers, literals inside (numba keys its disk cache on
# their values, as for the cell kernels' entries).
def _entry(model_id: int, extension_id: int, d: int):
    def svd_path(F_, positive_only, params_, project, order, work_, P_, C_):
        F = numba.carray(F_, (d, d))
        params = numba.carray(params_, PARAMETER_COUNT)
        work = numba.carray(work_, ws.WORKSPACE_SIZE)
        sigma = ws.vector(work, ws.SIGMA, d)
        polar_svd_point(F, d, ws.matrix(work, ws.U, d), sigma, ws.matrix(work, ws.V, d))
        psi, region = principal_derivatives(
            model_id, extension_id, positive_only != 0, sigma, d, params, order, work
        )
        if order >= 1:
            workspace_first_piola(work, numba.carray(P_, (d, d)), d)
        if order >= 2:
            C = numba.carray(C_, (d * d, d * d))
            if region == UNDEFINED_REGION:
                C[:, :] = 0.0
            else:
                stress_derivative(model_id, region, sigma, d, params, work, project != 0, C)
        work[ws.REGION] = region
        return psi

    return svd_path


def svd_path_address(model_id: int, extension_id: int, d: int) -> int:
    """Return the address of the SVD path of a material for d×d F (compiled or loaded once)."""
    key = (int(model_id), int(extension_id), int(d))
    if key not in _COMPILED:
        _COMPILED[key] = compiled.c_callable_after_helper(
            _helper_key(*key), _entry(*key), _SIGNATURE
        )
    return _COMPILED[key].address


def compile_svd_path_ahead(model_id: int, extension_id: int, d: int) -> None:
    """Start compiling the SVD path in a helper process if it is neither loaded nor cached.

    :func:`svd_path_address` waits for the helper, then loads its result from numba's disk
    cache. Nothing starts when :func:`~dolfinx_invertible.constitutive.compiled.helpers_allowed`
    says no; a path already in the disk cache is loaded here.
    """
    key = (int(model_id), int(extension_id), int(d))
    if key not in _COMPILED:
        statement = f"from {__name__} import svd_path_address; svd_path_address{key}"
        loaded = compiled.compile_ahead(_helper_key(*key), _entry(*key), _SIGNATURE, statement)
        if loaded is not None:
            _COMPILED[key] = loaded


def _helper_key(model_id: int, extension_id: int, d: int) -> tuple:
    """Return the key of the helper compiling this SVD path (``compiled.compile_ahead``)."""
    return ("svd path", model_id, extension_id, d)


def bind_svd_path(model_id: int, extension_id: int, d: int, bind: Callable[[int], None]) -> None:
    """Give ``bind`` the address to call the material's SVD path through, without waiting.

    Once the path is loaded, or when no helper is compiling it (it is then compiled or loaded
    here), ``bind`` gets its address at once. While a helper compiles it, ``bind`` gets the
    address of a stand-in with the same C signature, and the real address later: the stand-in's
    first call waits for the helper, loads the path, passes its address to every ``bind``
    waiting for it, and forwards the call (as do later calls made before the caller rebinds,
    such as the rest of an assembly whose constants DOLFINx packed already). A ``bind`` must
    keep alive what it writes to; once the helper has exited, the next call here binds every
    waiting caller too, so none is held longer than the helper runs.
    """
    key = (int(model_id), int(extension_id), int(d))
    helper = _helper_key(*key)
    # A helper that has exited costs no wait: bind to the path itself, and whoever waits too.
    if not compiled.compiling_ahead(helper) or compiled.helper_exited(helper):
        address = svd_path_address(*key)
        _bind_waiting(key, address)
        bind(address)
        return
    if key not in _STAND_INS:
        _STAND_INS[key] = (_stand_in(key), [])
    stand_in, waiting = _STAND_INS[key]
    waiting.append(bind)
    bind(ctypes.cast(stand_in, ctypes.c_void_p).value)


def _stand_in(key: tuple[int, int, int]):
    def forward(F, positive_only, params, project, order, work, P, C):
        try:
            address = svd_path_address(*key)
        except Exception:
            # An exception cannot leave a C callback: NaN in Ψ, P and C fails the solve instead.
            _LOG.exception("the SVD path %s could not be compiled", key)
            size = key[2] * key[2]
            for index in range(size if order >= 1 else 0):
                P[index] = math.nan
            for index in range(size * size if order >= 2 else 0):
                C[index] = math.nan
            return math.nan
        _bind_waiting(key, address)
        return _C_TYPE(address)(F, positive_only, params, project, order, work, P, C)

    return _C_TYPE(forward)


def _bind_waiting(key: tuple[int, int, int], address: int) -> None:
    """Pass the path's ``address`` to every caller bound to the stand-in of ``key``; forget them."""
    waiting = _STAND_INS[key][1] if key in _STAND_INS else []
    while waiting:
        waiting.pop()(address)


def _as_int64(builder, value, value_type):
    if isinstance(value_type, types.Boolean):
        return builder.zext(value, ir.IntType(64))
    width = value.type.width
    if width < 64:
        return builder.sext(value, ir.IntType(64))
    return builder.trunc(value, ir.IntType(64)) if width > 64 else value


@intrinsic
def call_svd_path(typingctx, address, F, positive_only, params, project, order, work, P, C):
    """Run the SVD path at ``address`` (:func:`svd_path_address`) on F; return Ψ.

    F, params, work, P and C are C-contiguous arrays (P and C are written only up to
    ``order``: a caller without them may pass ``work``); the flags and the order are booleans
    or integers.
    """
    arrays = (1, 3, 6, 7, 8)
    integers = (0, 2, 4, 5)
    given = (address, F, positive_only, params, project, order, work, P, C)
    # The C function reads each array from its first element on: a strided view would be read
    # wrongly, so it does not compile.
    if not all(isinstance(given[i], types.Array) and given[i].layout == "C" for i in arrays):
        return None

    def codegen(context, builder, signature, args):
        pointer = ir.PointerType(ir.DoubleType())
        integer = ir.IntType(64)
        function_type = ir.FunctionType(
            ir.DoubleType(),
            [pointer, integer, pointer, integer, integer, pointer, pointer, pointer],
        )
        values = {}
        for index in arrays:
            array = context.make_array(signature.args[index])(context, builder, args[index])
            values[index] = array.data
        for index in integers:
            values[index] = _as_int64(builder, args[index], signature.args[index])
        function = builder.inttoptr(values[0], function_type.as_pointer())
        return builder.call(function, [values[index] for index in range(1, 9)])

    return (
        types.float64(address, F, positive_only, params, project, order, work, P, C),
        codegen,
    )
