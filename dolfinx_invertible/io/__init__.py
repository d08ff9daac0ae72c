"""Output: the XDMF time series ParaView reads and the JSON-lines step log."""

from dolfinx_invertible.io.xdmf import DISPLACEMENT_NAME, SERIES_NAME, ResultWriter

__all__ = ["DISPLACEMENT_NAME", "SERIES_NAME", "ResultWriter"]
