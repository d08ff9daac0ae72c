"""Layout of the constants array every cell kernel reads, and its packing.

Everything a kernel needs besides the cell's dofs and coordinates travels in one DOLFINx
Constant: a header, the material parameters, then the Basix reference tables. Passing the tables
as data rather than baking them into the machine code lets one compiled (and disk-cached) kernel
serve every element, quadrature rule and material; DOLFINx packs constants once per assembly,
not per cell, and changing a parameter or the projection switch never recompiles.

Material parameters given as scalar DOLFINx Constants are not copied: the forms pass those
Constants to DOLFINx after this array (DOLFINx concatenates a form's constants in order), the
header says which parameter sits at which offset there, and the kernels read them at every
assembly, so ``mu.value = ...`` takes effect as in a UFL form.
"""

from __future__ import annotations

import numpy as np

from dolfinx_invertible import _compat
from dolfinx_invertible.constitutive.parameters import PARAMETER_COUNT
from dolfinx_invertible.constitutive.svd_path import bind_svd_path
from dolfinx_invertible.fem.kernels.tables import ReferenceTables

__all__ = [
    "COUNTERS_SLOT",
    "DERIVED_STIFFNESS",
    "DIMENSION_SLOT",
    "EXTENSION_SLOT",
    "GEOMETRY_NODES_SLOT",
    "HEADER_SIZE",
    "MAX_NODES",
    "MODEL_SLOT",
    "NODES_SLOT",
    "NO_SOURCE",
    "PARAMETERS_START",
    "PARAMETER_COUNT",
    "PARAMETER_SOURCES_SLOT",
    "POINTS_SLOT",
    "POSITIVE_ONLY_SLOT",
    "PROJECT_SLOT",
    "SVD_PATH_SLOT",
    "USER_CONSTANTS_SLOT",
    "WEIGHTS_START",
    "pack_constants",
    "set_svd_path",
]

# Header slots, in order.
DIMENSION_SLOT = 0
NODES_SLOT = 1  # nodes of the displacement's scalar element
POINTS_SLOT = 2  # quadrature points
GEOMETRY_NODES_SLOT = 3
MODEL_SLOT = 4  # registry id of the model
EXTENSION_SLOT = 5  # registry id of the extension
POSITIVE_ONLY_SLOT = 6  # 1.0: the energy is undefined at J <= 0
PROJECT_SLOT = 7  # 1.0: SPD-projected tangent
COUNTERS_SLOT = 8  # address (as float64 bits) of the path-counter row the kernels count into
SVD_PATH_SLOT = 9  # address (as float64 bits) of the material's SVD path (constitutive.svd_path)
# Where each parameter is read: NO_SOURCE (the value packed below), an offset into the user's
# Constants that DOLFINx packs after this array, or (k only) DERIVED_STIFFNESS, 20·E(μ, λ).
PARAMETER_SOURCES_SLOT = 10
USER_CONSTANTS_SLOT = PARAMETER_SOURCES_SLOT + PARAMETER_COUNT  # how many values follow
HEADER_SIZE = USER_CONSTANTS_SLOT + 1
NO_SOURCE = -1.0
DERIVED_STIFFNESS = -2.0

PARAMETERS_START = HEADER_SIZE
# Then: quadrature weights (points), basis derivatives (points × nodes × d), geometry
# derivatives (points × geometry nodes × d).
WEIGHTS_START = PARAMETERS_START + PARAMETER_COUNT

#: Largest number of nodes per cell the kernels' stack scratch is sized for (Q2 hexahedra).
MAX_NODES = 27


def _bits(address: int) -> float:
    """Return the float64 with the bits of ``address`` (the constants array is float64)."""
    return np.array([address], dtype=np.int64).view(np.float64)[0]


def pack_constants(
    tables: ReferenceTables,
    dimension: int,
    material,
    project: bool,
    counters: np.ndarray | None = None,
    sources: np.ndarray | None = None,
    user_constants: int = 0,
) -> np.ndarray:
    """Return the constants array the cell kernels read.

    Parameters
    ----------
    tables
        Quadrature weights and reference derivatives of the element and the geometry.
    dimension
        Space dimension, 2 or 3.
    material
        The :class:`~dolfinx_invertible.Material` whose ids and parameters go in.
    project
        Initial state of the projection switch.
    counters
        Row of :data:`~dolfinx_invertible.fem.kernels.counters.PATH_COUNTERS` the kernels
        count into; ``None`` for no counting.
    sources
        Per parameter, :data:`NO_SOURCE`, an offset into the user Constants packed after this
        array, or :data:`DERIVED_STIFFNESS`; ``None``: every parameter from this array.
    user_constants
        Number of values DOLFINx packs after this array (the user's Constants).

    The :data:`SVD_PATH_SLOT` stays zero: :func:`set_svd_path` fills it in before the kernels
    first run.
    """
    points, nodes, _ = tables.basis_derivatives.shape
    geometry_nodes = tables.geometry_derivatives.shape[1]
    if max(nodes, geometry_nodes) > MAX_NODES:
        largest = max(nodes, geometry_nodes)
        raise ValueError(f"the kernels support at most {MAX_NODES} nodes per cell, got {largest}")
    address = 0.0
    if counters is not None:
        address = _bits(counters.ctypes.data)
    model_id, extension_id = material.model.model_id, material.extension_id
    header = np.zeros(HEADER_SIZE)
    header[DIMENSION_SLOT] = dimension
    header[NODES_SLOT] = nodes
    header[POINTS_SLOT] = points
    header[GEOMETRY_NODES_SLOT] = geometry_nodes
    header[MODEL_SLOT] = model_id
    header[EXTENSION_SLOT] = extension_id
    header[POSITIVE_ONLY_SLOT] = float(material.positive_only)
    header[PROJECT_SLOT] = float(project)
    header[COUNTERS_SLOT] = address
    header[PARAMETER_SOURCES_SLOT : PARAMETER_SOURCES_SLOT + PARAMETER_COUNT] = (
        NO_SOURCE if sources is None else sources
    )
    header[USER_CONSTANTS_SLOT] = user_constants
    return np.concatenate(
        [
            header,
            material.parameters,
            tables.weights,
            tables.basis_derivatives.ravel(),
            tables.geometry_derivatives.ravel(),
        ]
    )


def set_svd_path(constant, material, dimension: int) -> None:
    """Write the address of the material's SVD path into the packed constants of ``constant``.

    ``constant`` is the DOLFINx Constant holding the array :func:`pack_constants` made.
    Compiles the SVD path or loads it from numba's disk cache. While a helper process compiles
    it (:func:`~dolfinx_invertible.constitutive.svd_path.compile_svd_path_ahead`), the slot
    holds a stand-in instead, which waits for the helper when a point first needs the path and
    then writes the path's own address into the constants
    (:func:`~dolfinx_invertible.constitutive.svd_path.bind_svd_path`).
    """
    # The C++ Constant, not a view of its values: DOLFINx's value array does not keep the
    # Constant alive, and the stand-in may write after the forms that packed it are gone.
    owner = _compat.cpp_object(constant)

    def bind(address: int) -> None:
        owner.value[SVD_PATH_SLOT] = _bits(address)

    bind_svd_path(material.model.model_id, material.extension_id, dimension, bind)
