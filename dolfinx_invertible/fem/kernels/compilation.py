"""The C entry points DOLFINx calls, compiled on first use into numba's disk cache.

One entry per (kind, dimension, model, extension): the model and extension ids are compile-time
literals like the dimension, so an entry holds the chain of its material only
(:mod:`~dolfinx_invertible.constitutive.literal`) and a cold start compiles that chain, not every
model and extension. Two arities exist because ufcx's ``tabulate_tensor`` gained a
``custom_data`` pointer in DOLFINx 0.10; :mod:`~dolfinx_invertible._compat` says which one this
DOLFINx wants. An entry is compiled only when a form first needs it, so a scene that never asks
for the energy, say, never compiles its kernel; a serial process can start compiling one in a
helper process ahead of that (:func:`compile_kernel_ahead`).
"""

from __future__ import annotations

import json
import os
import tempfile
import time

from dolfinx_invertible.constitutive import compiled
from dolfinx_invertible.constitutive.svd_path import svd_path_address
from dolfinx_invertible.fem.kernels.cells import cell_energy, cell_residual, cell_tangent
from dolfinx_invertible.fem.kernels.counters import KERNEL_KINDS

__all__ = [
    "DEFAULT_MATERIALS",
    "compile_chains",
    "compile_kernel",
    "compile_kernel_ahead",
    "compiled_kernels",
    "default_materials",
    "kernel_address",
    "precompile",
]

_COMPILED: dict[tuple[str, int, int, int], object] = {}
#: What :func:`compile_chains` compiles of a material's chain, in order.
_PIECES = ("svd path", *KERNEL_KINDS)

#: The materials ``python -m dolfinx_invertible compile`` (``make setup``) compiles kernels for,
#: in 2D and 3D: those the demos and the documentation's scenes use, as (model class name,
#: extension class name or None).
DEFAULT_MATERIALS: tuple[tuple[str, str | None], ...] = (
    ("NeoHookean", "C2"),
    ("NeoHookean", "C1"),
    ("NeoHookean", "IFE"),
    ("NeoHookean", None),
    ("Corotated", None),
    ("FixedCorotated", None),
    ("StableNeoHookean", None),
)


# Each entry names its cell function as a global and captures only integers (dimension, model
# and extension id): numba keys its disk cache on the captured values, which must stay plain
# numbers.
def _entries(kind: str, d: int, model_id: int, extension_id: int) -> tuple:
    if kind == "energy":

        def entry(A_, w_, c_, coordinates_, entity_local_index, permutation):
            cell_energy(A_, w_, c_, coordinates_, d, model_id, extension_id)

        def entry_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
            cell_energy(A_, w_, c_, coordinates_, d, model_id, extension_id)

    elif kind == "residual":

        def entry(A_, w_, c_, coordinates_, entity_local_index, permutation):
            cell_residual(A_, w_, c_, coordinates_, d, model_id, extension_id)

        def entry_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
            cell_residual(A_, w_, c_, coordinates_, d, model_id, extension_id)

    else:

        def entry(A_, w_, c_, coordinates_, entity_local_index, permutation):
            cell_tangent(A_, w_, c_, coordinates_, d, model_id, extension_id)

        def entry_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
            cell_tangent(A_, w_, c_, coordinates_, d, model_id, extension_id)

    return entry, entry_with_data


def compile_kernel(entries: tuple) -> object:
    """Compile a numba ``cfunc`` with the kernel signature of the running DOLFINx.

    ``entries`` holds the six-argument and the seven-argument (``custom_data``) Python function;
    the one matching :data:`dolfinx_invertible._compat.KERNEL_TAKES_CUSTOM_DATA` is compiled
    (or loaded from numba's disk cache).
    """
    return compiled.c_callable(*_entry_and_signature(entries))


def _entry_and_signature(entries: tuple) -> tuple:
    from dolfinx_invertible import _compat

    entry = entries[1] if _compat.KERNEL_TAKES_CUSTOM_DATA else entries[0]
    return entry, _compat.KERNEL_SIGNATURE


def _key(kind: str, dimension: int, model_id: int, extension_id: int) -> tuple:
    from dolfinx_invertible.constitutive.extensions import EXTENSIONS
    from dolfinx_invertible.constitutive.models import MODELS

    if kind not in KERNEL_KINDS:
        raise ValueError(f"kind must be one of {KERNEL_KINDS}, got {kind!r}")
    if dimension not in (2, 3):
        raise ValueError(f"no kernel for dimension {dimension}; 2 and 3 are supported")
    if model_id not in range(len(MODELS)) or extension_id not in range(len(EXTENSIONS)):
        raise ValueError(f"unknown model id {model_id!r} or extension id {extension_id!r}")
    return (kind, int(dimension), int(model_id), int(extension_id))


def kernel_address(kind: str, dimension: int, model_id: int, extension_id: int) -> int:
    """Return the address of a compiled cell kernel.

    Parameters
    ----------
    kind
        ``"energy"``, ``"residual"`` or ``"tangent"``.
    dimension
        2 or 3; any supported element of that dimension uses the same kernel.
    model_id, extension_id
        Registry ids of the material's model and extension (``Material.model.model_id``,
        ``Material.extension_id``).
    """
    key = _key(kind, dimension, model_id, extension_id)
    if key not in _COMPILED:
        entry, signature = _entry_and_signature(_entries(*key))
        _COMPILED[key] = compiled.c_callable_after_helper(_helper_key(key), entry, signature)
    return _COMPILED[key].address


def compile_kernel_ahead(kind: str, dimension: int, model_id: int, extension_id: int) -> None:
    """Start compiling a cell kernel in a helper process if it is neither loaded nor cached.

    :func:`kernel_address` waits for the helper, then loads its result from numba's disk cache.
    Nothing starts when :func:`~dolfinx_invertible.constitutive.compiled.helpers_allowed` says
    no; a kernel already in the disk cache is loaded here. Arguments as for
    :func:`kernel_address`.
    """
    key = _key(kind, dimension, model_id, extension_id)
    if key not in _COMPILED:
        statement = f"from {__name__} import kernel_address; kernel_address{key!r}"
        entry, signature = _entry_and_signature(_entries(*key))
        loaded = compiled.compile_ahead(_helper_key(key), entry, signature, statement)
        if loaded is not None:
            _COMPILED[key] = loaded


def _helper_key(key: tuple) -> tuple:
    """Return the key of the helper compiling the kernel of ``key`` (``compiled.compile_ahead``)."""
    return ("kernel", *key)


def compiled_kernels() -> int:
    """Return how many cell kernels this process has compiled or loaded (tests count them)."""
    return len(_COMPILED)


def default_materials():
    """Return the :class:`~dolfinx_invertible.Material` of each :data:`DEFAULT_MATERIALS` entry."""
    from dolfinx_invertible import constitutive

    materials = []
    for model_name, extension_name in DEFAULT_MATERIALS:
        model = getattr(constitutive, model_name)(mu=1.0, lam=1.0)
        extension = None if extension_name is None else getattr(constitutive, extension_name)()
        materials.append(constitutive.Material(model, extension))
    return materials


def precompile(
    dimensions: tuple[int, ...] = (3, 2), materials=None
) -> dict[tuple[str, int, str], float]:
    """Compile the cell kernels of ``materials`` into numba's disk cache; seconds per kernel.

    ``materials`` defaults to :func:`default_materials`. ``make setup`` runs this
    (``python -m dolfinx_invertible compile``) so that the first assembly in a user's script
    loads the kernels instead of compiling them; with a warm cache it takes a few seconds.
    Keys are (kind, dimension, material description); each value is the time the process that
    compiled the kernel spent on it.

    numba compiles one function at a time in a process, so the (material, dimension) chains are
    dealt round-robin, largest dimension first, to this process and a helper process on each
    further core (:func:`~dolfinx_invertible.constitutive.compiled.helpers_allowed`), which
    fill the same disk cache; this process then loads what the helpers compiled, or compiles it
    if a helper failed.
    """
    materials = default_materials() if materials is None else list(materials)
    names = {(m.model.model_id, m.extension_id): repr(m) for m in materials}
    chains = [(*ids, dimension) for dimension in sorted(dimensions, reverse=True) for ids in names]
    helpers = compiled.available_cores() - 1 if compiled.helpers_allowed() else 0
    shares = [chains[i :: helpers + 1] for i in range(min(helpers + 1, len(chains)))]
    with tempfile.TemporaryDirectory() as folder:
        reports = [os.path.join(folder, f"{i}.json") for i in range(1, len(shares))]
        processes = [
            compiled.start_helper(
                f"import json; from {__name__} import compile_chains; "
                f"json.dump(compile_chains({share!r}), open({report!r}, 'w'))"
            )
            for share, report in zip(shares[1:], reports, strict=True)
        ]
        timings = compile_chains(shares[0]) if shares else []
        for process, report in zip(processes, reports, strict=True):
            compiled.finish_helper(process)
            try:
                with open(report) as stream:
                    timings += [tuple(timing) for timing in json.load(stream)]
            except (OSError, ValueError):
                pass  # a helper that failed or was stopped: its chains are compiled below
    # This process loads what the helpers compiled, and compiles what a failed one left out.
    reported = {timing[:4] for timing in timings}
    loaded = compile_chains([chain for share in shares[1:] for chain in share])
    timings += [timing for timing in loaded if timing[:4] not in reported]
    seconds = {timing[:4]: timing[4] for timing in timings}
    report = {}
    for chain in chains:
        for piece in _PIECES:
            report[piece, chain[2], names[chain[:2]]] = seconds[(*chain, piece)]
    return report


def compile_chains(chains: list[tuple[int, int, int]]) -> list[tuple[int, int, int, str, float]]:
    """Compile or load the SVD path and the cell kernels of each (model id, extension id, d).

    Returns (model id, extension id, d, piece, seconds) per piece, ``"svd path"`` or one of
    :data:`KERNEL_KINDS` (the helpers of :func:`precompile` run this).
    """
    timings = []
    for model_id, extension_id, dimension in chains:
        # The kernels call the material's SVD path through its address (constants header).
        for kind in _PIECES:
            start = time.perf_counter()
            if kind == "svd path":
                svd_path_address(model_id, extension_id, dimension)
            else:
                kernel_address(kind, dimension, model_id, extension_id)
            timings.append((model_id, extension_id, dimension, kind, time.perf_counter() - start))
    return timings
