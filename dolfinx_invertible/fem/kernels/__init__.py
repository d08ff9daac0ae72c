"""Numba cell kernels with DOLFINx's custom-kernel signature.

- :mod:`.constants`: the layout of the constants array every kernel reads, and its packing;
- :mod:`.tables`: quadrature weights and Basix reference derivatives;
- :mod:`.geometry`: the geometry map and F = I + ∇u at a point;
- :mod:`.cells`: the energy, residual and tangent cell functions;
- :mod:`.counters`: per-form counts of points that took the SVD path;
- :mod:`.compilation`: the C entry points, compiled on first use.
"""

from dolfinx_invertible.fem.kernels.compilation import (
    DEFAULT_MATERIALS,
    compile_kernel,
    compile_kernel_ahead,
    compiled_kernels,
    default_materials,
    kernel_address,
    precompile,
)
from dolfinx_invertible.fem.kernels.constants import (
    DERIVED_STIFFNESS,
    HEADER_SIZE,
    MAX_NODES,
    NO_SOURCE,
    PARAMETER_COUNT,
    PARAMETER_SOURCES_SLOT,
    PARAMETERS_START,
    PROJECT_SLOT,
    pack_constants,
    set_svd_path,
)
from dolfinx_invertible.fem.kernels.counters import KERNEL_KINDS, counter_row, counts_by_kind
from dolfinx_invertible.fem.kernels.tables import ReferenceTables

__all__ = [
    "DEFAULT_MATERIALS",
    "DERIVED_STIFFNESS",
    "HEADER_SIZE",
    "KERNEL_KINDS",
    "MAX_NODES",
    "NO_SOURCE",
    "PARAMETER_COUNT",
    "PARAMETER_SOURCES_SLOT",
    "PARAMETERS_START",
    "PROJECT_SLOT",
    "ReferenceTables",
    "compile_kernel",
    "compile_kernel_ahead",
    "compiled_kernels",
    "counter_row",
    "counts_by_kind",
    "default_materials",
    "kernel_address",
    "pack_constants",
    "precompile",
    "set_svd_path",
]
