"""Per-point energy density, stress and tangent from F, and their batch loops.

These compiled functions are the single implementation behind :class:`~dolfinx_invertible.Material`
and the DOLFINx cell kernels. A point's status is its region code (see
:func:`~dolfinx_invertible.principal.principal_derivatives`).
"""

from __future__ import annotations

import numba
import numpy as np

from dolfinx_invertible.principal import UNDEFINED_REGION, principal_derivatives
from dolfinx_invertible.svd import polar_svd_point
from dolfinx_invertible.tangent import first_piola, stress_derivative
from dolfinx_invertible.workspace import WORKSPACE_SIZE, stack_buffer, workspace_from

__all__ = [
    "point_energy",
    "point_stress",
    "point_tangent",
    "energy_batch",
    "stress_batch",
    "tangent_batch",
    "sigma_batch",
]

# Derivative orders as runtime integers: a literal argument would make numba compile the whole
# call chain once per order value, tripling the cold compile time for no measurable speed.
_ENERGY = np.array([0])[0]
_STRESS = np.array([1])[0]
_TANGENT = np.array([2])[0]


@numba.njit(cache=True)
def point_energy(F, model_id, extension_id, positive_only, params, ws):
    """(Ψ(F), region)."""
    polar_svd_point(F, ws.U, ws.sigma, ws.V)
    return principal_derivatives(model_id, extension_id, positive_only, ws.sigma, params, _ENERGY, ws)


@numba.njit(cache=True)
def point_stress(F, model_id, extension_id, positive_only, params, ws, P):
    """P(F) into ``P``; returns (Ψ(F), region)."""
    polar_svd_point(F, ws.U, ws.sigma, ws.V)
    psi, region = principal_derivatives(
        model_id, extension_id, positive_only, ws.sigma, params, _STRESS, ws
    )
    first_piola(ws.U, ws.g, ws.V, P)
    return psi, region


@numba.njit(cache=True)
def point_tangent(F, model_id, extension_id, positive_only, params, project, ws, P, C):
    """P(F) into ``P`` and dP/dF (projected if ``project``) into ``C``; returns (Ψ, region)."""
    polar_svd_point(F, ws.U, ws.sigma, ws.V)
    psi, region = principal_derivatives(
        model_id, extension_id, positive_only, ws.sigma, params, _TANGENT, ws
    )
    first_piola(ws.U, ws.g, ws.V, P)
    if region == UNDEFINED_REGION:
        C[:, :] = 0.0
    else:
        stress_derivative(model_id, region, ws.sigma, params, ws, project, C)
    return psi, region


@numba.njit(cache=True)
def energy_batch(F, model_id, extension_id, positive_only, params, energy, region):
    ws = workspace_from(stack_buffer(WORKSPACE_SIZE), F.shape[1])
    for n in range(F.shape[0]):
        energy[n], region[n] = point_energy(F[n], model_id, extension_id, positive_only, params, ws)


@numba.njit(cache=True)
def stress_batch(F, model_id, extension_id, positive_only, params, P, region):
    ws = workspace_from(stack_buffer(WORKSPACE_SIZE), F.shape[1])
    for n in range(F.shape[0]):
        _, region[n] = point_stress(
            F[n], model_id, extension_id, positive_only, params, ws, P[n]
        )


@numba.njit(cache=True)
def tangent_batch(F, model_id, extension_id, positive_only, params, project, C, region):
    d = F.shape[1]
    ws = workspace_from(stack_buffer(WORKSPACE_SIZE), d)
    P = np.empty((d, d))
    for n in range(F.shape[0]):
        _, region[n] = point_tangent(
            F[n], model_id, extension_id, positive_only, params, project, ws, P, C[n]
        )


@numba.njit(cache=True)
def sigma_batch(sigma, model_id, extension_id, positive_only, params, order, energy, g, H, region):
    """Energy, gradient and Hessian in σ-space (up to ``order``) for canonical signed σ."""
    ws = workspace_from(stack_buffer(WORKSPACE_SIZE), sigma.shape[1])
    for n in range(sigma.shape[0]):
        energy[n], region[n] = principal_derivatives(
            model_id, extension_id, positive_only, sigma[n], params, order, ws
        )
        if order >= 1:
            g[n] = ws.g
        if order >= 2:
            H[n] = ws.H
