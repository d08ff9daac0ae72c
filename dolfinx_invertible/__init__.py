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

# The DOLFINx layer is imported on first use, so the batch API works without loading DOLFINx.
_LAZY = {
    "HyperelasticForms": "dolfinx_invertible.forms",
    "HyperelasticProblem": "dolfinx_invertible.problem",
    "ImplicitDynamics": "dolfinx_invertible.dynamics",
    "NewtonSolver": "dolfinx_invertible.solver",
    "SolverError": "dolfinx_invertible.solver",
    "solve_load_steps": "dolfinx_invertible.solver",
    "ResultWriter": "dolfinx_invertible.output",
    "cell_diagnostics": "dolfinx_invertible.diagnostics",
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'dolfinx_invertible' has no attribute {name!r}")


__all__ = [
    *_LAZY,
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
