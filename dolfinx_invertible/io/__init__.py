"""Output: the XDMF time series ParaView reads and the JSON-lines step log."""

# The PyPI DOLFINx wheel finds its MPI library only once mpi4py has loaded it: mpi4py first.
from mpi4py import MPI  # noqa: F401

from dolfinx_invertible.io.xdmf import DISPLACEMENT_NAME, SERIES_NAME, ResultWriter

__all__ = ["DISPLACEMENT_NAME", "SERIES_NAME", "ResultWriter"]
