"""The mesh cache: generate once (rank 0), store as XDMF, read in parallel."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from dolfinx_invertible import _compat

__all__ = ["cache_directory", "cached_mesh"]


def cache_directory() -> Path:
    """Return the folder cached meshes live in (created if missing)."""
    root = os.environ.get("DOLFINX_INVERTIBLE_CACHE")
    folder = Path(root) if root else Path.home() / ".cache" / "dolfinx_invertible"
    folder = folder / "meshes"
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def cached_mesh(comm, key: str, generate: Callable[[], tuple[np.ndarray, np.ndarray]]):
    """Return the mesh stored under ``key``, generating it first if the cache lacks it.

    ``generate()`` returns (points (n, 3), tetrahedra (m, 4)); it runs on rank 0 only. The
    folder is written under a temporary name and renamed into place, so that runs starting
    together never read half a file.
    """
    folder = cache_directory() / key
    error = None
    if comm.rank == 0 and not (folder / "mesh.xdmf").exists():
        try:
            import meshio

            points, cells = generate()
            staging = Path(tempfile.mkdtemp(prefix=f".{key}-", dir=folder.parent))
            # Uncompressed: the HDF5 inside the DOLFINx wheel has no deflate filter to read with.
            meshio.write(
                staging / "mesh.xdmf", meshio.Mesh(points, [("tetra", cells)]), compression=None
            )
            try:
                os.rename(staging, folder)
            except OSError:  # another run got there first
                shutil.rmtree(staging, ignore_errors=True)
        except Exception as exception:  # re-raised on every rank below
            error = f"could not generate the mesh {key!r}: {exception!r}"
    error = comm.bcast(error, root=0)
    if error is not None:
        raise RuntimeError(error)
    return _compat.read_xdmf_mesh(comm, folder / "mesh.xdmf")
