"""Isotropic energy models Ψ̂(σ), one module each, and their registry.

Each module holds its energy's separable-form tables, divided differences and class;
:mod:`.registry` lists every model (:data:`MODELS`) and dispatches on a model's id.
"""

from dolfinx_invertible.constitutive.models.arap import ARAP
from dolfinx_invertible.constitutive.models.base import Model
from dolfinx_invertible.constitutive.models.corotated import Corotated
from dolfinx_invertible.constitutive.models.fixed_corotated import FixedCorotated
from dolfinx_invertible.constitutive.models.neo_hookean import NeoHookean
from dolfinx_invertible.constitutive.models.registry import MODELS
from dolfinx_invertible.constitutive.models.stable_neo_hookean import StableNeoHookean
from dolfinx_invertible.constitutive.models.stvk import StVK

__all__ = [
    "ARAP",
    "MODELS",
    "Corotated",
    "FixedCorotated",
    "Model",
    "NeoHookean",
    "StableNeoHookean",
    "StVK",
]
