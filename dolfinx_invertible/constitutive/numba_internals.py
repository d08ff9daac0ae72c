"""Every use of numba's private names in the package, each guarded by a plain-numba fallback.

The package patches numba in four places (docs/design.md, docs/performance.md):

- ``function_numbers``: each process starts numba's numbering of compiled functions at a random
  value, so that two specialisations of one closure compiled in two processes never share a
  machine-code name in the disk cache (``FunctionIdentity._unique_ids``);
- ``locked_cache``: saves to numba's disk cache take a file lock, so that two processes saving
  specialisations of one function at once cannot leave its index naming the other's data
  (``FunctionCache._save_overload``, the ``_cache`` of a dispatcher); and an entry is fresh only
  while the package's compiled sources are as they were when it was saved (the index's
  ``_source_stamp``, :func:`compiled_sources_digest`): numba checks the stamp of the function's
  own file alone, so an edit to a function it calls from another file would otherwise leave
  the old machine code in use;
- ``compiled_only``: functions only compiled code calls get neither Python nor C wrappers and
  keep LLVM IR instead of machine code (a dispatcher subclass, numba's compiler pipeline and a
  code library class whose ``_finalize_final_module`` and ``_optimize_final_module`` stop
  early), for a faster cold compile (docs/performance.md has the figures);
- ``c_callable``: a C callable is built before it is compiled, so that its disk cache can be
  probed without compiling (``CFunc`` and its ``_sig``, ``_targetdescr`` and ``_cache``); the
  compile helpers need that probe.

At import each patch checks that the private names it needs exist. A patch whose names a numba
release lacks falls back to what ``numba.njit(cache=True)`` and ``numba.cfunc(cache=True)`` do:
the same numbers, a slower first compile (``compiled_only``), no compile helpers
(``c_callable``), and numba's own disk-cache behaviour when several processes compile at once
(``function_numbers``, ``locked_cache``). One ``RuntimeWarning`` names the patches that fell
back. :data:`PATCHES_VARIABLE` set to ``0`` turns every patch off, without a warning.
"""

from __future__ import annotations

import fcntl
import functools
import hashlib
import inspect
import itertools
import logging
import os
import secrets
import warnings
from collections.abc import Callable
from pathlib import Path

import numba

__all__ = [
    "ACTIVE",
    "PATCHES",
    "PATCHES_VARIABLE",
    "c_callable",
    "cached_c_callable",
    "compiled_only_dispatcher",
    "compiled_sources_digest",
    "jit_cached",
    "missing_names",
    "overload_jit_options",
]

#: Environment variable that, set to ``0``, runs numba without any of the package's patches.
PATCHES_VARIABLE = "DOLFINX_INVERTIBLE_NUMBA_PATCHES"
#: The patches, each with what its fallback costs.
PATCHES = {
    "function_numbers": "specialisations of one closure cached by two processes may collide",
    "locked_cache": "concurrent saves to numba's disk cache are not ordered",
    "compiled_only": "inner functions compile with wrappers and machine code (slower)",
    "c_callable": "no compile helper processes",
}
_LOG = logging.getLogger(__name__)


def _probe():
    return None


# The class numba.njit makes in this numba version (its module moved between versions).
_Dispatcher = type(numba.njit(_probe))


def _absent(owner, qualified_name: str, *names: str) -> list[str]:
    """Return ``qualified_name.name`` for each of ``names`` that ``owner`` lacks."""
    return [f"{qualified_name}.{name}" for name in names if not hasattr(owner, name)]


def _missing_function_numbers() -> list[str]:
    from numba.core.bytecode import FunctionIdentity

    numbers = getattr(FunctionIdentity, "_unique_ids", None)
    if isinstance(numbers, itertools.count):
        return []
    return ["numba.core.bytecode.FunctionIdentity._unique_ids"]


def _missing_locked_cache() -> list[str]:
    from numba.core.caching import FunctionCache, IndexDataCacheFile

    missing = _absent(FunctionCache, "numba.core.caching.FunctionCache", "_save_overload")
    missing += _absent(FunctionCache, "numba.core.caching.FunctionCache", "cache_path")
    # The stamp is an attribute of each index (``_source_stamp``), which these two compare.
    missing += _absent(IndexDataCacheFile, "numba.core.caching.IndexDataCacheFile",
                       "_load_index", "_save_index")  # fmt: skip
    return missing + _absent(numba.njit(_probe), "numba Dispatcher", "_cache")


# What the link-only code library overrides or calls of numba's code library class.
_LIBRARY_NAMES = ("_finalize_final_module", "_optimize_final_module", "_finalize_dynamic_globals",
                  "_verify_declare_only_symbols", "serialize_using_bitcode",
                  "serialize_using_object_code", "enable_object_caching")  # fmt: skip


def _missing_compiled_only() -> list[str]:
    from numba.core import compiler, compiler_machinery, typed_passes
    from numba.core.codegen import JITCodeLibrary

    missing = _absent(compiler, "numba.core.compiler", "CompilerBase", "DefaultPassBuilder")
    missing += _absent(compiler.Flags, "numba.core.compiler.Flags", "no_cpython_wrapper",
                       "no_cfunc_wrapper")  # fmt: skip
    missing += _absent(compiler_machinery, "numba.core.compiler_machinery", "LoweringPass",
                       "PassManager", "register_pass")  # fmt: skip
    missing += _absent(typed_passes, "numba.core.typed_passes", "NativeLowering")
    missing += _absent(JITCodeLibrary, "numba.core.codegen.JITCodeLibrary", *_LIBRARY_NAMES)
    if not isinstance(inspect.getattr_static(JITCodeLibrary, "codegen", None), property):
        missing.append("numba.core.codegen.JITCodeLibrary.codegen")
    parameters = inspect.signature(_Dispatcher).parameters
    missing += [
        f"numba Dispatcher({name}=...)"
        for name in ("py_func", "locals", "targetoptions", "pipeline_class")
        if name not in parameters
    ]
    return missing


def _missing_c_callable() -> list[str]:
    from numba.core import ccallback, sigutils

    missing = _absent(sigutils, "numba.core.sigutils", "normalize_signature")
    missing += _absent(ccallback, "numba.core.ccallback", "CFunc")
    if missing:
        return missing
    callback = ccallback.CFunc(_probe, sigutils.normalize_signature("void()"), {}, {})
    missing = _absent(callback, "numba.core.ccallback.CFunc", "_sig", "_targetdescr", "_cache")
    if not missing:
        missing += _absent(type(callback._targetdescr), "numba CFunc._targetdescr",
                           "target_context")  # fmt: skip
        missing += _absent(callback._cache, "numba CFunc._cache", "load_overload")
    return missing


_CHECKS = {
    "function_numbers": _missing_function_numbers,
    "locked_cache": _missing_locked_cache,
    "compiled_only": _missing_compiled_only,
    "c_callable": _missing_c_callable,
}


def missing_names() -> dict[str, list[str]]:
    """Return, for each patch of :data:`PATCHES`, the private numba names this numba lacks."""
    missing = {}
    for patch, check in _CHECKS.items():
        try:
            missing[patch] = check()
        except (ImportError, AttributeError, TypeError, ValueError) as error:
            missing[patch] = [f"{type(error).__name__}: {error}"]
    return missing


def _decide(missing: dict[str, list[str]], enabled: bool) -> dict[str, bool]:
    """Return which patches apply; warn once about those that fall back for missing names."""
    if not enabled:
        _LOG.debug("%s=0: numba runs without the package's patches", PATCHES_VARIABLE)
        return dict.fromkeys(PATCHES, False)
    lacking = {patch: names for patch, names in missing.items() if names}
    if lacking:
        falls_back = "; ".join(
            f"{patch} ({PATCHES[patch]}; needs {', '.join(names)})"
            for patch, names in lacking.items()
        )
        warnings.warn(
            f"numba {numba.__version__} lacks private names dolfinx_invertible patches; these "
            f"fall back to plain numba, with the same results: {falls_back}",
            RuntimeWarning,
            stacklevel=2,
        )
    return {patch: not missing.get(patch) for patch in PATCHES}


_ENABLED = os.environ.get(PATCHES_VARIABLE, "1").strip() != "0"
#: Which patches apply in this process (all of them on the numba versions the package supports).
ACTIVE = _decide(missing_names() if _ENABLED else {}, _ENABLED)


# ---------------------------------------------------------------------------------------------
# function_numbers
# ---------------------------------------------------------------------------------------------
def _distinct_function_numbers() -> None:
    """Start this process's numbering of compiled functions at a random value.

    numba names the machine code of a function by its qualified name, its argument types and a
    counter that starts at 1 in every process, and the JIT binds a cached object's calls by name.
    Two closures of one name (a function specialised per model, extension and dimension) compiled
    in two processes could then carry the same name for different code, and a process loading
    both from the disk cache would run the first one's code for both (the 2D and 3D SVD paths
    would give wrong stresses, without an error). A random start among 2⁴⁸ keeps them apart.
    """
    from numba.core.bytecode import FunctionIdentity

    FunctionIdentity._unique_ids = itertools.count(secrets.randbits(48) + 1)


if ACTIVE["function_numbers"]:
    _distinct_function_numbers()


# ---------------------------------------------------------------------------------------------
# locked_cache
# ---------------------------------------------------------------------------------------------
# Text that marks a module whose functions numba compiles (a decorator or numba itself).
_COMPILED_MARKERS = (b"compiled_only", b"compiled_overload", b"jit_cached", b"c_callable",
                     b"import numba", b"from numba")  # fmt: skip


@functools.cache
def compiled_sources_digest(root: Path | None = None) -> str:
    """Return a digest of the text of every module under ``root`` that numba compiles from.

    ``root`` defaults to the package. A compiled function inlines, or links in, what it calls
    from other modules, so its cached machine code is fresh only while all of them are
    unchanged; the digest is part of every cache entry's stamp (``locked_cache``).
    """
    root = Path(__file__).resolve().parents[1] if root is None else Path(root)
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        text = path.read_bytes()
        if any(marker in text for marker in _COMPILED_MARKERS):
            digest.update(path.relative_to(root).as_posix().encode() + b"\0" + text + b"\0")
    return digest.hexdigest()


def _locked_function_cache_class() -> type:
    from numba.core.caching import FunctionCache

    class LockedFunctionCache(FunctionCache):
        """numba's disk cache of a function, its entries saved one process at a time.

        A save reads the function's index, picks a data file and rewrites both. Two processes
        saving different specialisations of one function at once (two test workers, or a process
        and its compile helper) could both pick the same data file, and the index could end up
        naming the other one's code. An exclusive lock on a file in the cache directory orders
        the saves; loads need none, since a data file then only ever holds the entry its index
        names. The index's stamp, numba's of the function's own file, also carries
        :func:`compiled_sources_digest`, so that an edit to a function it calls in another
        module makes the entry stale too.
        """

        def __init__(self, py_func):
            super().__init__(py_func)
            index = getattr(self, "_cache_file", None)
            if hasattr(index, "_source_stamp"):
                index._source_stamp = (index._source_stamp, compiled_sources_digest())

        def _save_overload(self, sig, data):
            try:
                os.makedirs(self.cache_path, exist_ok=True)
                lock = open(os.path.join(self.cache_path, "dolfinx_invertible.lock"), "a")  # noqa: SIM115
            except OSError:  # a read-only cache: numba decides what saving means there
                return super()._save_overload(sig, data)
            with lock:
                fcntl.flock(lock, fcntl.LOCK_EX)
                try:
                    return super()._save_overload(sig, data)
                finally:
                    fcntl.flock(lock, fcntl.LOCK_UN)

    return LockedFunctionCache


_LOCKED_CACHE = _locked_function_cache_class() if ACTIVE["locked_cache"] else None


def _cache_on_disk(compiled, function: Callable) -> None:
    """Give a dispatcher or C callable the locked disk cache, or numba's own without the patch."""
    if _LOCKED_CACHE is not None:
        compiled._cache = _LOCKED_CACHE(function)
    else:
        compiled.enable_caching()


def jit_cached(function: Callable, **options):
    """``numba.njit(cache=True, **options)(function)``, its disk cache saved under the lock."""
    if _LOCKED_CACHE is None:
        return numba.njit(cache=True, **options)(function)
    dispatcher = numba.njit(**options)(function)
    _cache_on_disk(dispatcher, function)
    return dispatcher


# ---------------------------------------------------------------------------------------------
# compiled_only
# ---------------------------------------------------------------------------------------------
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
        own_codegen = base.codegen.fget

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
                "codegen": property(lambda self: _LinkOnlyCodegen(own_codegen(self))),
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


if ACTIVE["compiled_only"]:
    _PIPELINE_CLASS = _compiled_only_pipeline_class()
    # For functions that only forward to a callee (compiled_overload's implementations).
    _FORWARDING_PIPELINE_CLASS = _compiled_only_pipeline_class(optimise=False)


def compiled_only_dispatcher(function: Callable, *, forceinline: bool = False):
    """Return the disk-cached dispatcher of a function that only compiled code calls.

    With the ``compiled_only`` patch it has neither Python nor C wrapper, keeps LLVM IR only and
    refuses calls from Python with a ``TypeError``; without, it is :func:`jit_cached`'s.
    """
    options = {"forceinline": True} if forceinline else {}
    if not ACTIVE["compiled_only"]:
        return jit_cached(function, **options)
    options.update(nopython=True, no_cpython_wrapper=True, no_cfunc_wrapper=True)
    dispatcher = _CompiledOnlyDispatcher(
        py_func=function, locals={}, targetoptions=options, pipeline_class=_PIPELINE_CLASS
    )
    _cache_on_disk(dispatcher, function)
    return dispatcher


def overload_jit_options() -> dict:
    """Return the ``jit_options`` of an overload whose implementations only forward a call.

    With the ``compiled_only`` patch they compile without wrappers and keep unoptimised IR;
    without, as numba compiles any overload's implementation.
    """
    if not ACTIVE["compiled_only"]:
        return {}
    return {
        "no_cpython_wrapper": True,
        "no_cfunc_wrapper": True,
        "pipeline_class": _FORWARDING_PIPELINE_CLASS,
    }


# ---------------------------------------------------------------------------------------------
# c_callable
# ---------------------------------------------------------------------------------------------
def _c_callback(function: Callable, signature):
    from numba.core import sigutils
    from numba.core.ccallback import CFunc

    # As numba.cfunc(signature, cache=True) builds it, with the locked cache and not compiled.
    callback = CFunc(function, sigutils.normalize_signature(signature), {}, {"nopython": True})
    _cache_on_disk(callback, function)
    return callback


def c_callable(function: Callable, signature) -> object:
    """``numba.cfunc(signature, cache=True)(function)``, its disk cache saved under the lock."""
    if not ACTIVE["c_callable"]:
        return numba.cfunc(signature, cache=True)(function)
    callback = _c_callback(function, signature)
    callback.compile()
    return callback


def cached_c_callable(function: Callable, signature) -> object | None:
    """:func:`c_callable` if numba's disk cache holds it, else ``None`` without compiling.

    Without the ``c_callable`` patch the cache cannot be probed: always ``None``.
    """
    if not ACTIVE["c_callable"]:
        return None
    callback = _c_callback(function, signature)
    target = callback._targetdescr.target_context
    if callback._cache.load_overload(callback._sig, target) is None:
        return None
    callback.compile()
    return callback
