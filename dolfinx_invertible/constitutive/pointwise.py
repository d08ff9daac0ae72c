"""Per-point energy density, stress and tangent from F, and their batch loops.

These compiled functions are the single implementation behind :class:`~dolfinx_invertible.Material`
and the DOLFINx cell kernels. The batch loops take the model and extension ids as compile-time
literals (:mod:`~dolfinx_invertible.constitutive.literal`): each material compiles its own chain. A point's status is its region code (see
:func:`~dolfinx_invertible.constitutive.principal.principal_derivatives`).
"""

from __future__ import annotations

import numba
import numpy as np

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.invariants import (
    invariant_energy,
    invariant_stress,
    invariant_tangent,
)
from dolfinx_invertible.constitutive.principal import UNDEFINED_REGION, principal_derivatives
from dolfinx_invertible.constitutive.svd import polar_svd_point
from dolfinx_invertible.constitutive.tangent import first_piola, stress_derivative

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
def _through_svd(F, model_id, extension_id, positive_only, params, order, work):
    """Take the SVD path; return (Ψ, region).

    U, σ, V go into the workspace, then Ψ̂ext(σ) with derivatives up to ``order`` into the G, H
    slots.
    """
    d = F.shape[0]
    sigma = ws.vector(work, ws.SIGMA, d)
    polar_svd_point(F, ws.matrix(work, ws.U, d), sigma, ws.matrix(work, ws.V, d))
    return principal_derivatives(model_id, extension_id, positive_only, sigma, params, order, work)


@numba.njit(cache=True)
def point_energy(F, model_id, extension_id, positive_only, params, work):
    """Return (Ψ(F), region, through_svd).

    ``work`` is a workspace buffer (see :mod:`~dolfinx_invertible.constitutive.workspace`);
    ``through_svd`` says whether the SVD path was taken.
    """
    done, psi, region = invariant_energy(F, model_id, extension_id, positive_only, params)
    if done:
        return psi, region, False
    psi, region = _through_svd(F, model_id, extension_id, positive_only, params, _ENERGY, work)
    return psi, region, True


@numba.njit(cache=True)
def point_stress(F, model_id, extension_id, positive_only, params, work, P):
    """P(F) into ``P``; returns (Ψ(F), region, through_svd)."""
    done, psi, region = invariant_stress(F, model_id, extension_id, positive_only, params, P)
    if done:
        return psi, region, False
    psi, region = _through_svd(F, model_id, extension_id, positive_only, params, _STRESS, work)
    d = F.shape[0]
    first_piola(ws.matrix(work, ws.U, d), ws.vector(work, ws.G, d), ws.matrix(work, ws.V, d), P)
    return psi, region, True


@numba.njit(cache=True)
def point_tangent(F, model_id, extension_id, positive_only, params, project, work, P, C):
    """Write P(F) into ``P`` and dP/dF into ``C``; return (Ψ, region, through_svd).

    The tangent is SPD-projected if ``project``.
    """
    done, psi, region = invariant_tangent(
        F, model_id, extension_id, positive_only, params, project, P, C
    )
    if done:
        return psi, region, False
    psi, region = _through_svd(F, model_id, extension_id, positive_only, params, _TANGENT, work)
    d = F.shape[0]
    sigma = ws.vector(work, ws.SIGMA, d)
    first_piola(ws.matrix(work, ws.U, d), ws.vector(work, ws.G, d), ws.matrix(work, ws.V, d), P)
    if region == UNDEFINED_REGION:
        C[:, :] = 0.0
    else:
        stress_derivative(model_id, region, sigma, params, work, project, C)
    return psi, region, True


@numba.njit(cache=True)
def energy_batch(F, model_id, extension_id, positive_only, params, energy, region):
    """Energy and region of every F in the batch into ``energy`` and ``region``."""
    numba.literally(model_id)
    numba.literally(extension_id)
    work = ws.new_workspace(ws.stack_buffer())
    for n in range(F.shape[0]):
        energy[n], region[n], _ = point_energy(
            F[n], model_id, extension_id, positive_only, params, work
        )


@numba.njit(cache=True)
def stress_batch(F, model_id, extension_id, positive_only, params, P, region):
    """Stress and region of every F in the batch into ``P`` and ``region``."""
    numba.literally(model_id)
    numba.literally(extension_id)
    work = ws.new_workspace(ws.stack_buffer())
    for n in range(F.shape[0]):
        _, region[n], _ = point_stress(
            F[n], model_id, extension_id, positive_only, params, work, P[n]
        )


@numba.njit(cache=True)
def tangent_batch(F, model_id, extension_id, positive_only, params, project, C, region):
    """Tangent (projected if ``project``) and region of every F into ``C`` and ``region``."""
    numba.literally(model_id)
    numba.literally(extension_id)
    d = F.shape[1]
    work = ws.new_workspace(ws.stack_buffer())
    P = np.empty((d, d))
    for n in range(F.shape[0]):
        _, region[n], _ = point_tangent(
            F[n], model_id, extension_id, positive_only, params, project, work, P, C[n]
        )


@numba.njit(cache=True)
def sigma_batch(sigma, model_id, extension_id, positive_only, params, order, energy, g, H, region):
    """Energy, gradient and Hessian in σ-space (up to ``order``) for canonical signed σ."""
    numba.literally(model_id)
    numba.literally(extension_id)
    d = sigma.shape[1]
    work = ws.new_workspace(ws.stack_buffer())
    for n in range(sigma.shape[0]):
        energy[n], region[n] = principal_derivatives(
            model_id, extension_id, positive_only, sigma[n], params, order, work
        )
        if order >= 1:
            g[n] = ws.vector(work, ws.G, d)
        if order >= 2:
            H[n] = ws.matrix(work, ws.H, d)
