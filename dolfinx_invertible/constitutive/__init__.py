"""The constitutive core: isotropic energies, their invertible extensions, stress and tangent.

Nothing in here imports DOLFINx, PETSc, UFL or Basix.

- :mod:`.svd`: the polar SVD;
- :mod:`.models`: one module per energy Ψ̂(σ) and the registry of models;
- :mod:`.extensions`: C1, C2 and IFE, and the registry of extensions;
- :mod:`.principal`: energy, gradient and Hessian in σ-space for a model and an extension;
- :mod:`.tangent`: P and dP/dF in F-space, and the SPD projection;
- :mod:`.invariants`: the SVD-free fast path where no extension can act;
- :mod:`.pointwise`: per-point functions and their batch loops (batch API and kernels);
- :mod:`.workspace`: allocation-free scratch memory;
- :mod:`.material`: :class:`Material`, the batch API;
- :mod:`.parameters`: Lamé parameters from E and ν;
- :mod:`.validation`: input checks with clear errors;
- :mod:`.polynomial`: the first root of a cubic on (0, 1].
"""

from dolfinx_invertible.constitutive.extensions import C1, C2, IFE, Extension
from dolfinx_invertible.constitutive.material import Material, NoEnergyError
from dolfinx_invertible.constitutive.models import (
    ARAP,
    Corotated,
    FixedCorotated,
    Model,
    NeoHookean,
    StableNeoHookean,
    StVK,
)
from dolfinx_invertible.constitutive.parameters import lame
from dolfinx_invertible.constitutive.svd import polar_svd

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
