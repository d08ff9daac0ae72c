"""The DOLFINx layer: cell kernels, forms, per-cell diagnostics and input checks.

- :mod:`.kernels`: numba cell kernels with DOLFINx's custom-kernel signature;
- :mod:`.forms`: :class:`HyperelasticForms`, the energy, residual and tangent forms of a material;
- :mod:`.diagnostics`: per-cell inversion, extension and energy diagnostics;
- :mod:`.checks`: checks of a mesh and of boundary conditions before a solve;
- :mod:`.spaces`: function spaces on every supported DOLFINx;
- :mod:`.mesh`: a mesh from its vertices and cells on every supported DOLFINx, and the same
  partition of a mesh on every run;
- :mod:`.sampling`: singular values per cell and values at points, gathered over ranks.
"""

# The PyPI DOLFINx wheel finds its MPI library only once mpi4py has loaded it: mpi4py first.
from mpi4py import MPI  # noqa: F401

from dolfinx_invertible.fem.checks import check_boundary_conditions, check_mesh
from dolfinx_invertible.fem.diagnostics import DIAGNOSTIC_NAMES, cell_diagnostics, summary
from dolfinx_invertible.fem.forms import HyperelasticForms, default_quadrature_degree
from dolfinx_invertible.fem.mesh import mesh_from_cells, reproducible_partitioning
from dolfinx_invertible.fem.sampling import CellSingularValues, PointValues
from dolfinx_invertible.fem.spaces import scalar_function_space, vector_function_space

__all__ = [
    "DIAGNOSTIC_NAMES",
    "CellSingularValues",
    "HyperelasticForms",
    "PointValues",
    "cell_diagnostics",
    "check_boundary_conditions",
    "check_mesh",
    "default_quadrature_degree",
    "mesh_from_cells",
    "reproducible_partitioning",
    "scalar_function_space",
    "summary",
    "vector_function_space",
]
