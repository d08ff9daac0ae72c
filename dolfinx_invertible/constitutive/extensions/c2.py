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

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.constitutive.extensions.base import Extension
from dolfinx_invertible.constitutive.literal import dispatch_on_dimension
from dolfinx_invertible.constitutive.models.registry import (
    model_anchor_derivatives,
    model_derivatives_into,
)
from dolfinx_invertible.constitutive.polynomial import single_root_in_unit_interval

__all__ = ["C2", "derivatives", "c2_derivatives", "threshold_parameter"]

# |∂J/∂s| at the crossing is bounded below by this (relative): a tangential crossing is a
# measure-zero event that would otherwise divide by zero.
_MIN_CROSSING_SLOPE = 1e-12


@compiled_only
def threshold_parameter(a, eps):
    """Smallest s in (0, 1] with Π(1 + s aᵢ) = ε, given Π(1 + aᵢ) < ε < 1 (σ = 1 + a canonical).

    The cubic Π(1 + s aᵢ) − ε changes sign once on [0, 1]: up to the first zero of a factor the
    geometric mean of the (positive, affine) factors is concave in s, so it falls through
    ε^(1/d) once; past that zero exactly one factor is negative (the polar SVD leaves at most one
    σᵢ < 0), so the product stays below 0. The bracket [0, 1] therefore holds the root alone,
    without a search for the cubic's critical points.
    """
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
    return single_root_in_unit_interval(1.0 - eps, e1, e2, e3)


def _specialised_c2_derivatives(d: int):
    """Compile :func:`c2_derivatives` for one dimension.

    Constant loop bounds unroll and the index tests fold away.
    """

    @compiled_only
    def specialised(model_id, sigma, params, order, work):
        eps = params[2]
        J = 1.0
        for i in range(d):
            J *= sigma[i]
        if J >= eps:
            return model_derivatives_into(model_id, sigma, d, params, order, work, ws.G, ws.H), 0
        # Slots are read and written by offset: each array view costs two out-of-line
        # reference-count calls, more than the arithmetic they would serve.
        a = ws.A_OFFSET
        for i in range(d):
            work[a + i] = sigma[i] - 1.0
        s = threshold_parameter(ws.vector(work, a, d), eps)
        w = 1.0 - s
        for i in range(d):
            work[ws.Q_POINT + i] = 1.0 + s * work[a + i]
        # g, H at q and T[a, ·, ·], T[a, a, ·], Q[a, a, ·, ·]: what the orders below need.
        psi_q = model_anchor_derivatives(
            model_id, ws.vector(work, ws.Q_POINT, d), d, params, order + 2, work
        )
        g = ws.MODEL_G
        H = ws.MODEL_H
        slope = 0.0  # ψ′ along the segment: ∇Ψ̂(q)·a
        curvature = 0.0  # ψ″: aᵀ ∇²Ψ̂(q) a
        for i in range(d):
            slope += work[g + i] * work[a + i]
            for j in range(d):
                curvature += work[a + i] * work[H + d * i + j] * work[a + j]
        psi = psi_q + w * slope + 0.5 * w * w * curvature
        if order < 1:
            return psi, 1

        z = ws.Z
        n = ws.N
        t2 = ws.T2
        third = 0.0  # ψ‴ = T[a, a, a]
        crossing = 0.0  # a·z with z = 1/q, proportional to dJ/ds at the crossing
        scale = 0.0
        for k in range(d):
            third += work[t2 + k] * work[a + k]
            work[z + k] = 1.0 / work[ws.Q_POINT + k]
            crossing += work[a + k] * work[z + k]
            scale += abs(work[a + k] * work[z + k])
        if crossing > -_MIN_CROSSING_SLOPE * scale:
            crossing = -_MIN_CROSSING_SLOPE * max(scale, 1e-300)
        for k in range(d):
            work[n + k] = -s * work[z + k] / crossing  # ∇s
        out = ws.G
        for k in range(d):
            Ha = 0.0
            for j in range(d):
                Ha += work[H + d * k + j] * work[a + j]
            work[out + k] = (
                work[g + k]
                + w * Ha
                + 0.5 * s * w * w * work[t2 + k]
                + 0.5 * w * w * third * work[n + k]
            )
        if order < 2:
            return psi, 1

        T1 = ws.T1
        Q2 = ws.Q2
        q3 = ws.Q3
        fourth = 0.0
        for k in range(d):
            total = 0.0
            for m in range(d):
                total += work[Q2 + d * k + m] * work[a + m]
            work[q3 + k] = total
            fourth += total * work[a + k]
        # Hessian of s(σ) by differentiating ∇s = −s z/(a·z) once more.
        weighted_square = 0.0
        for i in range(d):
            weighted_square += work[a + i] * work[a + i] * work[z + i] * work[z + i]
        Dn = ws.DN
        for k in range(d):
            z_k = work[z + k]
            for m in range(d):
                n_m = work[n + m]
                dz = -z_k * z_k * (n_m * work[a + k] + (s if k == m else 0.0))
                dcrossing = (
                    work[z + m]
                    - n_m * weighted_square
                    - s * work[a + m] * work[z + m] * work[z + m]
                )
                work[Dn + d * k + m] = -(n_m * z_k + s * dz) / crossing + s * z_k * dcrossing / (
                    crossing * crossing
                )
        out_H = ws.H
        for k in range(d):
            for m in range(k, d):
                value = (
                    work[H + d * k + m]
                    + s * w * (1.0 + w) * work[T1 + d * k + m]
                    + 0.5 * s * s * w * w * work[Q2 + d * k + m]
                    + 1.5 * w * w * (work[t2 + k] * work[n + m] + work[n + k] * work[t2 + m])
                    + 0.5 * s * w * w * (work[q3 + k] * work[n + m] + work[n + k] * work[q3 + m])
                    + 0.5 * (w * w * fourth - 2.0 * w * third) * work[n + k] * work[n + m]
                    + 0.25 * w * w * third * (work[Dn + d * k + m] + work[Dn + d * m + k])
                )
                work[out_H + d * k + m] = value
                work[out_H + d * m + k] = value
        return psi, 1

    return specialised


def c2_derivatives(model_id, sigma, d, params, order, work):
    """Ψ̂ext(σ) and (up to ``order`` ≤ 2) its gradient and Hessian into the G, H slots.

    Returns the energy and the region: 0 on the model, 1 in the extension. ``d`` is the length
    of ``sigma``, a compile-time literal in compiled code.
    """
    return _C2_DERIVATIVES[d](model_id, sigma, params, order, work)


_C2_DERIVATIVES = {d: _specialised_c2_derivatives(d) for d in (2, 3)}
dispatch_on_dimension(c2_derivatives, _C2_DERIVATIVES)


#: The module's entry for the compiled dispatch on the extension id.
derivatives = c2_derivatives


class C2(Extension):
    """C2 extension past J = ε (default ε = 0.9): energy, stress and tangent stay continuous.

    Parameters
    ----------
    eps
        Threshold on J = det F in (0, 1).
    """

    extension_id = 2

    def __init__(self, eps: float = 0.9):
        super().__init__(eps)
