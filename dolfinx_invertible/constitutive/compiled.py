"""How the package's numba functions are compiled: for compiled callers only, or for Python too.

With every function numba compiles, and keeps in its disk cache, a CPython wrapper (unboxing
the arguments, boxing the result) and a C wrapper. A function that only other compiled code
calls needs neither: :func:`compiled_only` leaves both out, which cut the cold start to the
first residual and tangent by about a fifth (docs/performance.md). Such a function called from
Python would jump through a null entry point, so its dispatcher refuses the call with a
``TypeError`` instead. Functions that Python calls (the batch loops' entries, the helpers the
tests call one by one) keep ``numba.njit(cache=True)``.
"""

from __future__ import annotations

from collections.abc import Callable

import numba

__all__ = ["compiled_only"]


def _probe():
    return None


# The class numba.njit makes in this numba version (its module moved between versions).
_Dispatcher = type(numba.njit(_probe))


class _CompiledOnlyDispatcher(_Dispatcher):
    """A dispatcher without the Python entry point: other compiled functions call it natively."""

    def __call__(self, *args, **kwargs):
        function = self.py_func
        raise TypeError(
            f"{function.__module__}.{function.__qualname__} is compiled without a Python entry "
            "point and can only be called from compiled code"
        )


def compiled_only(function: Callable | None = None, *, forceinline: bool = False):
    """``numba.njit(cache=True)`` without the Python and C wrappers, for compiled callers only.

    Parameters
    ----------
    function
        The function to compile; without it, returns the decorator.
    forceinline
        Ask LLVM to inline the function into its callers (numba's ``forceinline``).
    """

    def decorate(function: Callable):
        options = {"nopython": True, "no_cpython_wrapper": True, "no_cfunc_wrapper": True}
        if forceinline:
            options["forceinline"] = True
        dispatcher = _CompiledOnlyDispatcher(py_func=function, locals={}, targetoptions=options)
        dispatcher.enable_caching()
        return dispatcher

    return decorate if function is None else decorate(function)
