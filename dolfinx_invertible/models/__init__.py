"""Isotropic energy models Ψ̂(σ), one module each (energy tables, divided differences, class)."""

from dolfinx_invertible.models.arap import ARAP
from dolfinx_invertible.models.base import Model
from dolfinx_invertible.models.corotated import Corotated
from dolfinx_invertible.models.fixed_corotated import FixedCorotated
from dolfinx_invertible.models.neo_hookean import NeoHookean
from dolfinx_invertible.models.stable_neo_hookean import StableNeoHookean
from dolfinx_invertible.models.stvk import StVK

__all__ = ["ARAP", "Corotated", "FixedCorotated", "Model", "NeoHookean", "StableNeoHookean", "StVK"]
