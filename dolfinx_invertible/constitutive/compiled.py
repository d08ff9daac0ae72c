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
:func:`c_callable`. All three save to numba's disk cache under a lock
(``_LockedFunctionCache``).

A cold process can also hand an independent compilation to a helper process
(:func:`compile_ahead`): numba compiles under one lock per process, so two compilations in one
process run one after the other, while a helper fills the shared disk cache on another core.
The process then loads the helper's result from the cache (:func:`wait_for_helper`), or
compiles it itself if the helper failed.
"""

from __future__ import annotations

import atexit
import fcntl
import itertools
import logging
import os
import secrets
import subprocess
import sys
from collections.abc import Callable

import numba
from numba.core.caching import FunctionCache

__all__ = [
    "HELPER_VARIABLE",
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


def _distinct_function_numbers() -> None:
    """Start this process's numbering of compiled functions at a random value.

    numba names the machine code of a function by its qualified name, its argument types and a
    counter that starts at 1 in every process, and the JIT binds a cached object's calls by name.
    Two closures of one name (a function specialised per model, extension and dimension) compiled
    in two processes could then carry the same name for different code, and a process loading
    both from the disk cache would run the first one's code for both (the 2D and 3D SVD paths
    would give wrong stresses, without an error). A random start among 2⁴⁸ keeps them apart.
    """
    from numba.core import bytecode

    bytecode.FunctionIdentity._unique_ids = itertools.count(secrets.randbits(48) + 1)


_distinct_function_numbers()


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


_LINK_ONLY_CLASSES: dict[type, type] = {}


class _LinkOnlyCodegen:
    """The codegen seen through a link-only library: no environment to bind in the JIT."""

    def __init__(self, codegen):
        self._codegen = codegen

    def __getattr__(self, name: str):
        return getattr(self._codegen, name)

    def set_env(self, env_name, env) -> None:
        # The environment global would be bound in this library's machine code, which is never
        # generated; the callers' code carries its own copy.
        return None


def _link_only_library(codegen, name: str, optimise: bool = True):
    """Return a library of ``codegen``'s class that keeps LLVM IR for callers, no machine code.

    numba finalises every function's library on its own: it links the callees' IR in, optimises
    the result and generates its machine code. A compiled-only function's machine code is never
    run (its callers link its IR and optimise and generate code for the whole chain again), so
    this library stops after the optimisation. Its disk cache entry holds that IR; a process that
    loads it generates the machine code then, as numba does for IR entries. With ``optimise``
    false it also leaves out the optimisation of the linked module (numba's per-function passes
    still run): for a function that only forwards to a callee, whose callers optimise the whole
    chain again, it would optimise the callee's already optimised IR once more for nothing.
    """
    base = type(codegen.create_library("probe"))
    if base not in _LINK_ONLY_CLASSES:

        def _finalize_final_module(self):
            self._finalize_dynamic_globals()
            self._verify_declare_only_symbols()
            self._finalized = True

        def serialize_using_object_code(self):
            return self.serialize_using_bitcode()

        def _optimize_final_module(self):
            if self._optimise:
                base._optimize_final_module(self)

        _LINK_ONLY_CLASSES[base] = type(
            "LinkOnlyCodeLibrary",
            (base,),
            {
                "_finalize_final_module": _finalize_final_module,
                "_optimize_final_module": _optimize_final_module,
                "serialize_using_object_code": serialize_using_object_code,
                "codegen": property(lambda self: _LinkOnlyCodegen(self._codegen)),
            },
        )
    library = _LINK_ONLY_CLASSES[base](codegen, name)
    library._optimise = optimise
    library.enable_object_caching()
    return library


def _compiled_only_pipeline_class(optimise: bool = True):
    """Numba's nopython pipeline with the link-only library in place before native lowering."""
    from numba.core.compiler import CompilerBase, DefaultPassBuilder
    from numba.core.compiler_machinery import LoweringPass, PassManager, register_pass
    from numba.core.typed_passes import NativeLowering

    @register_pass(mutates_CFG=False, analysis_only=True)
    class LinkOnlyLibrary(LoweringPass):
        _name = "dolfinx_invertible_link_only_library"

        def __init__(self):
            LoweringPass.__init__(self)

        def run_pass(self, state):
            if state.library is None:
                codegen = state.targetctx.codegen()
                state.library = _link_only_library(codegen, state.func_id.func_qualname, optimise)
            return False

    class CompiledOnlyCompiler(CompilerBase):
        def define_pipelines(self):
            default = DefaultPassBuilder.define_nopython_pipeline(self.state)
            pipeline = PassManager("compiled_only")
            for pass_class, description in default.passes:
                if pass_class is NativeLowering:
                    pipeline.add_pass(LinkOnlyLibrary, "keep LLVM IR, no machine code")
                pipeline.add_pass(pass_class, description)
            pipeline.finalize()
            return [pipeline]

    return CompiledOnlyCompiler


_PIPELINE_CLASS = _compiled_only_pipeline_class()
# For functions that only forward to a callee (compiled_overload's implementations).
_FORWARDING_PIPELINE_CLASS = _compiled_only_pipeline_class(optimise=False)


class _LockedFunctionCache(FunctionCache):
    """numba's disk cache of a function, its entries saved one process at a time.

    A save reads the function's index, picks a data file and rewrites both. Two processes saving
    different specialisations of one function at once (two test workers, or a process and its
    compile helper) could both pick the same data file, and the index could end up naming the
    other one's code. An exclusive lock on a file in the cache directory orders the saves;
    loads need none, since a data file then only ever holds the entry its index names.
    """

    def _save_overload(self, sig, data):
        try:
            os.makedirs(self._cache_path, exist_ok=True)
            lock = open(os.path.join(self._cache_path, "dolfinx_invertible.lock"), "a")  # noqa: SIM115
        except OSError:  # a read-only cache: numba decides what saving means there
            return super()._save_overload(sig, data)
        with lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            try:
                return super()._save_overload(sig, data)
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)


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
        dispatcher = _CompiledOnlyDispatcher(
            py_func=function, locals={}, targetoptions=options, pipeline_class=_PIPELINE_CLASS
        )
        dispatcher._cache = _LockedFunctionCache(function)
        return dispatcher

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

    jit_options = {
        "no_cpython_wrapper": True,
        "no_cfunc_wrapper": True,
        "pipeline_class": _FORWARDING_PIPELINE_CLASS,
    }
    return overload(function, jit_options=jit_options, **options)


def python_callable(function: Callable):
    """``numba.njit(cache=True)(function)``, its disk cache saved under the lock."""
    dispatcher = numba.njit(function)
    dispatcher._cache = _LockedFunctionCache(function)
    return dispatcher


def _c_callback(function: Callable, signature):
    from numba.core import sigutils
    from numba.core.ccallback import CFunc

    # As numba.cfunc(signature, cache=True) builds it, with the locked cache.
    callback = CFunc(function, sigutils.normalize_signature(signature), {}, {"nopython": True})
    callback._cache = _LockedFunctionCache(function)
    return callback


def c_callable(function: Callable, signature) -> object:
    """``numba.cfunc(signature, cache=True)(function)``, its disk cache saved under the lock."""
    callback = _c_callback(function, signature)
    callback.compile()
    return callback


def cached_c_callable(function: Callable, signature) -> object | None:
    """:func:`c_callable` if numba's disk cache holds it, else ``None`` without compiling."""
    callback = _c_callback(function, signature)
    target = callback._targetdescr.target_context
    if callback._cache.load_overload(callback._sig, target) is None:
        return None
    callback.compile()
    return callback


def helpers_allowed() -> bool:
    """Whether a compilation may go to a helper process.

    Not when :data:`HELPER_VARIABLE` is ``0`` or this process may run on one core only.
    """
    if os.environ.get(HELPER_VARIABLE, "1").strip() == "0":
        return False
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return cores > 1


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
