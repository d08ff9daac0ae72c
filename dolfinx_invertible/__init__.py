"""dolfinx_invertible: energetically consistent invertible hyperelasticity for DOLFINx.

Implements Stomakhin, Howes, Schroeder and Teran, "Energetically Consistent Invertible
Elasticity" (SCA 2012): C1 and C2 extensions of isotropic energies past an inversion threshold,
with the first Piola–Kirchhoff stress and an SPD-projected tangent from a polar SVD.
"""

from dolfinx_invertible.extensions import C1, C2, IFE, Extension
from dolfinx_invertible.material import Material, NoEnergyError
from dolfinx_invertible.models import (
    ARAP,
    Corotated,
    FixedCorotated,
    Model,
    NeoHookean,
    StableNeoHookean,
    StVK,
)
from dolfinx_invertible.parameters import lame
from dolfinx_invertible.svd import polar_svd

__version__ = "0.1.0"

__all__ = [
    "ARAP",
    "C1",
    "C2",
    "IFE",
    "Corotated",
    "Extension",
    "FixedCorotated",
    "Material",
    "Model",
    "NeoHookean",
    "NoEnergyError",
    "StVK",
    "StableNeoHookean",
    "lame",
    "polar_svd",
]
