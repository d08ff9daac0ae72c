"""How the package's numba functions are compiled: for compiled callers only, or for Python too.

With every function numba compiles, and keeps in its disk cache, a CPython wrapper (unboxing
the arguments, boxing the result) and a C wrapper. A function that only other compiled code
calls needs neither, nor machine code of its own (its callers link its LLVM IR in and generate
code for the whole chain): :func:`compiled_only` leaves all three out (CHANGELOG.md has
what each saved), and :func:`compiled_overload` does the same for the implementations of the
package's numba overloads (the dispatch on model, extension and dimension). A compiled-only
function called from Python would jump through a null entry point, so its dispatcher refuses
the call with a ``TypeError`` instead. Functions that Python calls (the batch loops' entries,
the helpers the tests call one by one) are :func:`python_callable`, the C entry points
:func:`c_callable`. All three save to numba's disk cache under a lock. The numba internals
these rest on are in :mod:`~dolfinx_invertible.constitutive.numba_internals`, each with a
plain-numba fallback (the same numbers, a slower first compile) for a numba release that
lacks them.

A cold process can also hand an independent compilation to a helper process
(:func:`compile_ahead`): numba compiles under one lock per process, so two compilations in one
process run one after the other, while a helper fills the shared disk cache on another core.
The process then loads the helper's result from the cache (:func:`wait_for_helper`), or
compiles it itself if the helper failed.
"""

from __future__ import annotations

import atexit
import logging
import os
import subprocess
import sys
from collections.abc import Callable

from dolfinx_invertible.constitutive import numba_internals

__all__ = [
    "HELPER_VARIABLE",
    "available_cores",
    "c_callable",
    "c_callable_after_helper",
    "cached_c_callable",
    "compile_ahead",
    "helper_exited",
    "compiled_only",
    "compiled_overload",
    "compiling_ahead",
    "finish_helper",
    "helpers_allowed",
    "python_callable",
    "start_helper",
    "wait_for_helper",
]

#: Environment variable that, set to ``0``, keeps every compilation in the calling process.
HELPER_VARIABLE = "DOLFINX_INVERTIBLE_COMPILE_HELPER"
#: Seconds a helper may take before the calling process stops it and compiles itself.
HELPER_TIMEOUT = 900.0
_PACKAGE_PARENT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
_LOG = logging.getLogger(__name__)
_RUNNING: set[subprocess.Popen] = set()
# The helpers of compile_ahead by their callers' keys (None: the helper did not start).
_AHEAD: dict[tuple, subprocess.Popen | None] = {}


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
        return numba_internals.compiled_only_dispatcher(function, forceinline=forceinline)

    return decorate if function is None else decorate(function)


def compiled_overload(function: Callable, **options):
    """``numba.extending.overload`` whose implementations compile as :func:`compiled_only` does.

    numba compiles an overload's implementation as an ordinary jit function: a library of its
    own, optimised and turned into machine code with every callee linked in, for code that only
    its compiled callers run after linking it again. This one keeps the LLVM IR only, and does
    not optimise the linked module either: the package's overloads dispatch while typing, so an
    implementation only forwards its arguments to the compiled function chosen, and its callers
    optimise it together with their own code. The ``options`` are ``overload``'s own
    (``prefer_literal``, ...).
    """
    from numba.extending import overload

    return overload(function, jit_options=numba_internals.overload_jit_options(), **options)


def python_callable(function: Callable):
    """``numba.njit(cache=True)(function)``, its disk cache saved under the lock."""
    return numba_internals.jit_cached(function)


def c_callable(function: Callable, signature) -> object:
    """``numba.cfunc(signature, cache=True)(function)``, its disk cache saved under the lock."""
    return numba_internals.c_callable(function, signature)


def cached_c_callable(function: Callable, signature) -> object | None:
    """:func:`c_callable` if numba's disk cache holds it, else ``None`` without compiling."""
    return numba_internals.cached_c_callable(function, signature)


def helpers_allowed() -> bool:
    """Whether a compilation may go to a helper process.

    Not when :data:`HELPER_VARIABLE` is ``0``, this process may run on one core only, or
    numba's disk cache cannot be probed without compiling (no ``c_callable`` patch in
    :mod:`~dolfinx_invertible.constitutive.numba_internals`).
    """
    if os.environ.get(HELPER_VARIABLE, "1").strip() == "0":
        return False
    if not numba_internals.ACTIVE["c_callable"]:
        return False
    return available_cores() > 1


def available_cores() -> int:
    """Return the number of cores this process may run on (its affinity, else the CPU count)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def start_helper(statement: str) -> subprocess.Popen | None:
    """Run the Python ``statement`` in a helper process on this package; ``None`` if it fails.

    The helper shares this process's environment, so it compiles into the same numba cache.
    """
    environment = dict(os.environ)
    path = environment.get("PYTHONPATH")
    environment["PYTHONPATH"] = _PACKAGE_PARENT + (os.pathsep + path if path else "")
    try:
        process = subprocess.Popen(
            [sys.executable, "-c", statement],
            env=environment,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
    except OSError:
        _LOG.debug("cannot start a compile helper", exc_info=True)
        return None
    _RUNNING.add(process)
    return process


def finish_helper(process: subprocess.Popen | None) -> None:
    """Wait for a helper of :func:`start_helper`; stop it after :data:`HELPER_TIMEOUT` s.

    Whatever the helper did, the caller then loads or compiles as without it: a helper that
    failed only costs the time it ran.
    """
    if process is None:
        return
    _RUNNING.discard(process)
    try:
        _, errors = process.communicate(timeout=HELPER_TIMEOUT)
    except subprocess.TimeoutExpired:
        _stop(process)
        _LOG.warning("a compile helper ran over %.0f s and was stopped", HELPER_TIMEOUT)
        return
    if process.returncode != 0:
        _LOG.warning(
            "a compile helper failed (exit %s); compiling here instead: %s",
            process.returncode,
            errors.decode(errors="replace").strip()[-2000:],
        )


def compile_ahead(key: tuple, function: Callable, signature, statement: str) -> object | None:
    """Load a C callable from numba's disk cache, or start compiling it in a helper process.

    Returns the :func:`c_callable` of ``function`` if the disk cache holds it. Otherwise runs
    the Python ``statement``, which compiles it into the cache, in a helper known by ``key``,
    and returns ``None``. Nothing is loaded or started (``None``) when a helper of that key is
    known or :func:`helpers_allowed` says no.
    """
    if key in _AHEAD or not helpers_allowed():
        return None
    loaded = cached_c_callable(function, signature)
    if loaded is None:
        _AHEAD[key] = start_helper(statement)
    return loaded


def compiling_ahead(key: tuple) -> bool:
    """Whether a helper of :func:`compile_ahead` was started for ``key`` and not waited for."""
    return key in _AHEAD


def helper_exited(key: tuple) -> bool:
    """Whether the helper of ``key`` has exited (or never started), so waiting for it is free."""
    process = _AHEAD.get(key)
    return process is None or process.poll() is not None


def wait_for_helper(key: tuple) -> None:
    """Wait for the helper of ``key``, if any (:func:`finish_helper`); then it is forgotten."""
    finish_helper(_AHEAD.pop(key, None))


def c_callable_after_helper(key: tuple, function: Callable, signature) -> object:
    """:func:`c_callable` once the helper of ``key`` is done: it loads what the helper compiled.

    Without a helper of ``key`` (none started, or already waited for) this is :func:`c_callable`;
    after a failed one, it compiles here.
    """
    wait_for_helper(key)
    return c_callable(function, signature)


def _stop(process: subprocess.Popen) -> None:
    process.kill()
    process.communicate()


@atexit.register
def _stop_running_helpers() -> None:
    # A process that exits before it needs a helper's result does not wait for it; numba
    # replaces its cache files whole, so a stopped helper leaves no partial entry.
    for process in list(_RUNNING):
        _stop(process)
    _RUNNING.clear()
