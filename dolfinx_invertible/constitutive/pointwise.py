"""Per-point energy density, stress and tangent from F, and their batch loops.

These compiled functions are the single implementation behind :class:`~dolfinx_invertible.Material`
and the DOLFINx cell kernels. The model and extension ids and the dimension ``d`` of F are
compile-time literals (:mod:`~dolfinx_invertible.constitutive.literal`): each material compiles
its own chain, for the dimension in use only. A point the invariant fast path does not settle
takes the material's SVD path, a C function called through the address the caller passes
(:mod:`~dolfinx_invertible.constitutive.svd_path`). A point's status is its region code (see
:func:`~dolfinx_invertible.constitutive.principal.principal_derivatives`).
"""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.compiled import compiled_only, python_callable
from dolfinx_invertible.constitutive.invariants import (
    invariant_energy,
    invariant_stress,
    invariant_tangent,
    invariants,
)
from dolfinx_invertible.constitutive.literal import run_time_integers
from dolfinx_invertible.constitutive.principal import (
    OVERFLOW_REGION,
    principal_derivatives,
)
from dolfinx_invertible.constitutive.svd_path import call_svd_path

__all__ = [
    "point_energy",
    "point_stress",
    "point_tangent",
    "energy_batch",
    "stress_batch",
    "tangent_batch",
    "sigma_batch",
    "batch",
]

# Bounds of :func:`_extreme`.
_SAFE_SQUARED_NORM = 1e50
_SAFE_DETERMINANT = 1e-50
_SAFE_PARAMETER = 1e100

# Derivative orders as runtime integers: a literal argument would make numba compile the whole
# call chain once per order value, tripling the cold compile time for no measurable speed.
_ENERGY, _STRESS, _TANGENT = run_time_integers(0, 1, 2)


@compiled_only
def _extreme(I1, J, params):
    """F or the parameters so large (or J so small) that some intermediate may overflow.

    Inside these bounds no model's energy, stress or tangent can reach 1e308 (the largest powers
    are σ⁴ and 1/J², times a parameter); outside them the results are checked and a point whose
    results are not finite is reported as overflowing. NaN-safe.
    """
    largest = max(abs(params[0]), abs(params[1]), abs(params[3]))
    return not (
        I1 < _SAFE_SQUARED_NORM and abs(J) > _SAFE_DETERMINANT and largest < _SAFE_PARAMETER
    )


@compiled_only
def _overflowed(I1, J):
    """|F|² or det F beyond the largest double: nothing about the point can be computed."""
    return not (I1 < np.inf and abs(J) < np.inf)


@compiled_only
def _finite(M):
    """All entries of the matrix finite."""
    total = 0.0
    for i in range(M.shape[0]):
        row = 0.0
        for j in range(M.shape[1]):
            row += M[i, j] * 0.0
        total += row
    return total == 0.0


@compiled_only
def point_energy(F, d, model_id, extension_id, positive_only, params, svd_path, work):
    """Return (Ψ(F), region, through_svd).

    ``F`` is ``d×d``; ``svd_path`` the address of the material's SVD path
    (:func:`~dolfinx_invertible.constitutive.svd_path.svd_path_address`); ``work`` a workspace
    buffer (see :mod:`~dolfinx_invertible.constitutive.workspace`); ``through_svd`` says whether
    the SVD path was taken. An energy that overflows is +inf.
    """
    I1, I2, J = invariants(F, model_id, extension_id)
    if _overflowed(I1, J):
        return np.inf, OVERFLOW_REGION, False
    done, psi, region = invariant_energy(
        F, I1, I2, J, model_id, extension_id, positive_only, params
    )
    through_svd = False
    if not done:
        psi = call_svd_path(svd_path, F, positive_only, params, False, _ENERGY, work, work, work)
        region = int(work[ws.REGION])
        through_svd = True
    if not abs(psi) < np.inf:  # NaN (inf − inf) or ±inf: beyond the largest double
        psi = np.inf
    return psi, region, through_svd


@compiled_only
def point_stress(F, d, model_id, extension_id, positive_only, params, svd_path, work, P):
    """P(F) into ``P``; returns (Ψ(F), region, through_svd).

    Where the stress overflows, P is zero, Ψ is +inf and the region :data:`OVERFLOW_REGION`.
    """
    I1, I2, J = invariants(F, model_id, extension_id)
    if _overflowed(I1, J):
        P[:, :] = 0.0
        return np.inf, OVERFLOW_REGION, False
    done, psi, region = invariant_stress(
        F, I1, I2, J, model_id, extension_id, positive_only, params, P
    )
    through_svd = False
    if not done:
        psi = call_svd_path(svd_path, F, positive_only, params, False, _STRESS, work, P, work)
        region = int(work[ws.REGION])
        through_svd = True
    if not abs(psi) < np.inf:
        psi = np.inf
    if _extreme(I1, J, params) and not _finite(P):
        P[:, :] = 0.0
        return np.inf, OVERFLOW_REGION, through_svd
    return psi, region, through_svd


@compiled_only
def point_tangent(
    F, d, model_id, extension_id, positive_only, params, project, svd_path, work, P, C
):
    """Write P(F) into ``P`` and dP/dF into ``C``; return (Ψ, region, through_svd).

    The tangent is SPD-projected if ``project``. Where the stress or the tangent overflows, both
    are zero, Ψ is +inf and the region :data:`OVERFLOW_REGION`.
    """
    I1, I2, J = invariants(F, model_id, extension_id)
    if _overflowed(I1, J):
        P[:, :] = 0.0
        C[:, :] = 0.0
        return np.inf, OVERFLOW_REGION, False
    done, psi, region = invariant_tangent(
        F, d, I1, I2, J, model_id, extension_id, positive_only, params, project, P, C
    )
    through_svd = False
    if not done:
        psi = call_svd_path(svd_path, F, positive_only, params, project, _TANGENT, work, P, C)
        region = int(work[ws.REGION])
        through_svd = True
    if not abs(psi) < np.inf:
        psi = np.inf
    if _extreme(I1, J, params) and not (_finite(P) and _finite(C)):
        P[:, :] = 0.0
        C[:, :] = 0.0
        return np.inf, OVERFLOW_REGION, through_svd
    return psi, region, through_svd


@compiled_only
def energy_batch(F, d, model_id, extension_id, positive_only, params, svd_path, energy, region):
    """Energy and region of every F (``d×d``) in the batch into ``energy`` and ``region``."""
    work = ws.new_workspace(ws.stack_buffer())
    for n in range(F.shape[0]):
        energy[n], region[n], _ = point_energy(
            F[n], d, model_id, extension_id, positive_only, params, svd_path, work
        )


@compiled_only
def stress_batch(F, d, model_id, extension_id, positive_only, params, svd_path, P, region):
    """Stress and region of every F (``d×d``) in the batch into ``P`` and ``region``."""
    work = ws.new_workspace(ws.stack_buffer())
    for n in range(F.shape[0]):
        _, region[n], _ = point_stress(
            F[n], d, model_id, extension_id, positive_only, params, svd_path, work, P[n]
        )


@compiled_only
def tangent_batch(
    F, d, model_id, extension_id, positive_only, params, project, svd_path, C, region
):
    """Tangent (projected if ``project``) and region of every F (``d×d``) into ``C``, ``region``."""
    work = ws.new_workspace(ws.stack_buffer())
    P = np.empty((d, d))
    for n in range(F.shape[0]):
        _, region[n], _ = point_tangent(
            F[n], d, model_id, extension_id, positive_only, params, project, svd_path, work, P,
            C[n],
        )  # fmt: skip


@compiled_only
def sigma_batch(
    sigma, d, model_id, extension_id, positive_only, params, order, energy, g, H, region
):
    """Energy, gradient and Hessian in σ-space (up to ``order``) for canonical signed σ."""
    work = ws.new_workspace(ws.stack_buffer())
    for n in range(sigma.shape[0]):
        psi, region[n] = principal_derivatives(
            model_id, extension_id, positive_only, sigma[n], d, params, order, work
        )
        energy[n] = psi if abs(psi) < np.inf else np.inf
        if order >= 1:
            g[n] = ws.vector(work, ws.G, d)
        if order >= 2:
            H[n] = ws.matrix(work, ws.H, d)
        if order >= 1 and not (_finite(g[n : n + 1]) and (order < 2 or _finite(H[n]))):
            energy[n] = np.inf
            region[n] = OVERFLOW_REGION


_BATCH_LOOPS = {
    "energy": energy_batch,
    "stress": stress_batch,
    "tangent": tangent_batch,
    "sigma": sigma_batch,
}
_BATCH_ENTRIES: dict[tuple[str, int, int, int], object] = {}


# Each entry captures the ids and the dimension as integers: inside it they are literals (numba
# types a closure's integer cells as constants), and numba keys its disk cache on those values.
# A plain Python int passed to a compiled loop would instead be retyped on every call.
def _batch_entry(kind: str, model_id: int, extension_id: int, d: int):
    if kind == "energy":

        def entry(F, positive_only, params, svd_path, energy, region):
            energy_batch(
                F, d, model_id, extension_id, positive_only, params, svd_path, energy, region
            )

    elif kind == "stress":

        def entry(F, positive_only, params, svd_path, P, region):
            stress_batch(F, d, model_id, extension_id, positive_only, params, svd_path, P, region)

    elif kind == "tangent":

        def entry(F, positive_only, params, project, svd_path, C, region):
            tangent_batch(
                F, d, model_id, extension_id, positive_only, params, project, svd_path, C, region
            )

    else:

        def entry(sigma, positive_only, params, order, energy, g, H, region):
            sigma_batch(
                sigma, d, model_id, extension_id, positive_only, params, order, energy, g, H,
                region,
            )  # fmt: skip

    return python_callable(entry)


def batch(kind: str, model_id: int, extension_id: int, d: int):
    """Return the compiled batch loop ``kind`` ("energy", "stress", "tangent", "sigma") for d×d F.

    Its arguments are those of the loop of that name without the two ids and the dimension
    ``d`` (2 or 3), which are compiled in (:mod:`~dolfinx_invertible.constitutive.literal`):
    each material compiles its own chain for the dimension in use, once per process (or loads
    it from numba's disk cache).
    """
    if kind not in _BATCH_LOOPS:
        raise ValueError(f"kind must be one of {tuple(_BATCH_LOOPS)}, got {kind!r}")
    key = (kind, int(model_id), int(extension_id), int(d))
    if key not in _BATCH_ENTRIES:
        _BATCH_ENTRIES[key] = _batch_entry(*key)
    return _BATCH_ENTRIES[key]
