"""C2 extension (paper §4.2) past the threshold surface J = ε.

Below the surface, Ψ̂ext(σ) is the second-order Taylor expansion of Ψ̂ at the point q where the
segment from the rest point r = (1, …, 1) to σ first meets J = ε:

    Ψ̂ext(σ) = Ψ̂(q) + ∇Ψ̂(q)·(σ − q) + ½ (σ − q)ᵀ ∇²Ψ̂(q) (σ − q).

(The paper's text prints the linear term with the opposite sign, which is not even C1.)
With a = σ − r, q = r + s a and w = 1 − s, the anchor parameter s(σ) is differentiated
implicitly through Π(1 + s aᵢ) = ε; the gradient needs third and the Hessian fourth derivatives
of Ψ̂ at q.
"""

from __future__ import annotations

import numba

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.extensions.base import Extension
from dolfinx_invertible.constitutive.models.registry import model_derivatives_into
from dolfinx_invertible.constitutive.polynomial import first_root_in_unit_interval

__all__ = ["C2", "derivatives", "c2_derivatives", "threshold_parameter"]

# |∂J/∂s| at the crossing is bounded below by this (relative): a tangential crossing is a
# measure-zero event that would otherwise divide by zero.
_MIN_CROSSING_SLOPE = 1e-12


@numba.njit(cache=True)
def threshold_parameter(a, eps):
    """Smallest s in (0, 1] with Π(1 + s aᵢ) = ε, given Π(1 + aᵢ) < ε < 1."""
    d = a.shape[0]
    e1 = 0.0
    e2 = 0.0
    e3 = 0.0
    for i in range(d):
        e1 += a[i]
        for j in range(i + 1, d):
            e2 += a[i] * a[j]
    if d == 3:
        e3 = a[0] * a[1] * a[2]
    s = first_root_in_unit_interval(1.0 - eps, e1, e2, e3)
    # J(σ) < ε guarantees a crossing; round-off at J(σ) ≈ ε may hide it at s = 1.
    return min(s, 1.0)


@numba.njit(cache=True)
def c2_derivatives(model_id, sigma, params, order, work):
    """Ψ̂ext(σ) and (up to ``order`` ≤ 2) its gradient and Hessian into the G, H slots.

    Returns the energy and the region: 0 on the model, 1 in the extension.
    """
    if sigma.shape[0] == 3:
        return _c2_derivatives_3d(model_id, sigma, params, order, work)
    return _c2_derivatives_2d(model_id, sigma, params, order, work)


def _specialised_c2_derivatives(d: int):
    """Compile :func:`c2_derivatives` for one dimension.

    Constant loop bounds unroll and the index tests fold away.
    """

    @numba.njit(cache=True)
    def specialised(model_id, sigma, params, order, work):
        eps = params[2]
        J = 1.0
        for i in range(d):
            J *= sigma[i]
        if J >= eps:
            return model_derivatives_into(model_id, sigma, params, order, work, ws.G, ws.H), 0
        a = ws.vector(work, ws.A_OFFSET, d)
        q = ws.vector(work, ws.Q_POINT, d)
        z = ws.vector(work, ws.Z, d)
        n = ws.vector(work, ws.N, d)
        t2 = ws.vector(work, ws.T2, d)
        q3 = ws.vector(work, ws.Q3, d)
        for i in range(d):
            a[i] = sigma[i] - 1.0
        s = threshold_parameter(a, eps)
        w = 1.0 - s
        for i in range(d):
            q[i] = 1.0 + s * a[i]
        g = ws.vector(work, ws.MODEL_G, d)
        H = ws.matrix(work, ws.MODEL_H, d)
        T = ws.tensor3(work, ws.MODEL_T, d)
        Q = ws.tensor4(work, ws.MODEL_Q, d)
        psi_q = model_derivatives_into(model_id, q, params, order + 2, work, ws.MODEL_G, ws.MODEL_H)
        slope = 0.0  # ψ′ along the segment: ∇Ψ̂(q)·a
        curvature = 0.0  # ψ″: aᵀ ∇²Ψ̂(q) a
        for i in range(d):
            slope += g[i] * a[i]
            for j in range(d):
                curvature += a[i] * H[i, j] * a[j]
        psi = psi_q + w * slope + 0.5 * w * w * curvature
        if order < 1:
            return psi, 1

        third = 0.0  # ψ‴ = T[a, a, a]
        crossing = 0.0  # a·z with z = 1/q, proportional to dJ/ds at the crossing
        for k in range(d):
            t2[k] = 0.0
            for i in range(d):
                for j in range(d):
                    t2[k] += T[i, j, k] * a[i] * a[j]
            third += t2[k] * a[k]
            z[k] = 1.0 / q[k]
            crossing += a[k] * z[k]
        scale = 0.0
        for k in range(d):
            scale += abs(a[k] * z[k])
        if crossing > -_MIN_CROSSING_SLOPE * scale:
            crossing = -_MIN_CROSSING_SLOPE * max(scale, 1e-300)
        for k in range(d):
            n[k] = -s * z[k] / crossing  # ∇s
        out = ws.vector(work, ws.G, d)
        for k in range(d):
            Ha = 0.0
            for j in range(d):
                Ha += H[k, j] * a[j]
            out[k] = g[k] + w * Ha + 0.5 * s * w * w * t2[k] + 0.5 * w * w * third * n[k]
        if order < 2:
            return psi, 1

        T1 = ws.matrix(work, ws.T1, d)
        Q2 = ws.matrix(work, ws.Q2, d)
        Dn = ws.matrix(work, ws.DN, d)
        fourth = 0.0
        for k in range(d):
            q3[k] = 0.0
            for m in range(d):
                T1[k, m] = 0.0
                Q2[k, m] = 0.0
                for i in range(d):
                    T1[k, m] += T[i, k, m] * a[i]
                    for j in range(d):
                        Q2[k, m] += Q[i, j, k, m] * a[i] * a[j]
                q3[k] += Q2[k, m] * a[m]
            fourth += q3[k] * a[k]
        # Hessian of s(σ) by differentiating ∇s = −s z/(a·z) once more.
        weighted_square = 0.0
        for i in range(d):
            weighted_square += a[i] * a[i] * z[i] * z[i]
        for k in range(d):
            for m in range(d):
                dz = -z[k] * z[k] * (n[m] * a[k] + (s if k == m else 0.0))
                dcrossing = z[m] - n[m] * weighted_square - s * a[m] * z[m] * z[m]
                Dn[k, m] = -(n[m] * z[k] + s * dz) / crossing + s * z[k] * dcrossing / (
                    crossing * crossing
                )
        out_H = ws.matrix(work, ws.H, d)
        for k in range(d):
            for m in range(k, d):
                value = (
                    H[k, m]
                    + s * w * (1.0 + w) * T1[k, m]
                    + 0.5 * s * s * w * w * Q2[k, m]
                    + 1.5 * w * w * (t2[k] * n[m] + n[k] * t2[m])
                    + 0.5 * s * w * w * (q3[k] * n[m] + n[k] * q3[m])
                    + 0.5 * (w * w * fourth - 2.0 * w * third) * n[k] * n[m]
                    + 0.25 * w * w * third * (Dn[k, m] + Dn[m, k])
                )
                out_H[k, m] = value
                out_H[m, k] = value
        return psi, 1

    return specialised


_c2_derivatives_2d = _specialised_c2_derivatives(2)
_c2_derivatives_3d = _specialised_c2_derivatives(3)


#: The module's entry for the compiled dispatch on the extension id.
derivatives = c2_derivatives


class C2(Extension):
    """C2 extension past J = ε (default ε = 0.9): energy, stress and tangent stay continuous.

    Parameters
    ----------
    eps
        Threshold on J = det F in (0, 1).
    """

    def __init__(self, eps: float = 0.9):
        super().__init__(eps)
