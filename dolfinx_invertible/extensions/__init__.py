"""Invertible extensions of an energy past an inversion threshold (Stomakhin et al. 2012)."""

from dolfinx_invertible.extensions.base import Extension
from dolfinx_invertible.extensions.c1 import C1
from dolfinx_invertible.extensions.c2 import C2
from dolfinx_invertible.extensions.ife import IFE

__all__ = ["C1", "C2", "IFE", "Extension"]
