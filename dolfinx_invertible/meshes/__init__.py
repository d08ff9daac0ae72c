"""The scenes' meshes: a user's mesh files, and meshes gmsh scripts make on first use.

:func:`read_mesh` reads a gmsh ``.msh`` or XDMF file, checks it and distributes it. The
generated meshes are not stored in the package: each module here builds its geometry with gmsh
(on rank 0), writes it once to a cache folder (``DOLFINX_INVERTIBLE_CACHE`` or
``~/.cache/dolfinx_invertible``), and every later run on any number of ranks reads that file.
"""

# The PyPI DOLFINx wheel finds its MPI library only once mpi4py has loaded it: mpi4py first.
from mpi4py import MPI  # noqa: F401

from dolfinx_invertible.meshes.cache import cache_directory, cached_mesh
from dolfinx_invertible.meshes.files import MeshFileError, is_mesh_file, read_mesh

__all__ = ["MeshFileError", "cache_directory", "cached_mesh", "is_mesh_file", "read_mesh"]
