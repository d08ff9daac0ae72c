"""Invertible extensions of an energy past an inversion threshold (Stomakhin et al. 2012).

One module each (C1, C2 and the stress-only IFE baseline) and :mod:`.registry`, which lists them
(:data:`EXTENSIONS`).
"""

from dolfinx_invertible.constitutive.extensions.base import Extension
from dolfinx_invertible.constitutive.extensions.c1 import C1
from dolfinx_invertible.constitutive.extensions.c2 import C2
from dolfinx_invertible.constitutive.extensions.ife import IFE
from dolfinx_invertible.constitutive.extensions.registry import EXTENSIONS

__all__ = ["C1", "C2", "EXTENSIONS", "IFE", "Extension"]
