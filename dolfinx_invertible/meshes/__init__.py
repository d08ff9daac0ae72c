"""Meshes made by gmsh scripts on first use, cached on disk and read in parallel.

No mesh data is downloaded or stored in the repository: each module here builds its geometry
with gmsh (on rank 0), writes it once to a cache folder (``DOLFINX_INVERTIBLE_CACHE`` or
``~/.cache/dolfinx_invertible``), and every later run on any number of ranks reads that file.
"""

# The PyPI DOLFINx wheel finds its MPI library only once mpi4py has loaded it: mpi4py first.
from mpi4py import MPI  # noqa: F401

from dolfinx_invertible.meshes.cache import cache_directory, cached_mesh

__all__ = ["cache_directory", "cached_mesh"]
