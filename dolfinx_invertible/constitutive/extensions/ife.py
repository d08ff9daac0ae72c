"""IFE baseline (Irving et al. 2004, Teran et al. 2005): a stress-only extension.

Below J = ε the diagonal stress is extrapolated linearly from the same anchor point q as the C2
extension, P̂(σ) = ∇Ψ̂(q) + ∇²Ψ̂(q)(σ − q), and the tangent's diagonal block is the model Hessian
at q ("derivative clamping"), which is not the derivative of that stress. There is no energy, so
a line search has to work on the residual. Kept for comparison with the energy-based extensions.
"""

from __future__ import annotations

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.constitutive.extensions.base import Extension
from dolfinx_invertible.constitutive.extensions.c2 import threshold_parameter
from dolfinx_invertible.constitutive.models.registry import model_derivatives_into

__all__ = ["IFE", "derivatives", "ife_derivatives"]


@compiled_only
def ife_derivatives(model_id, sigma, d, params, order, work):
    """Diagonal stress into the G slot, clamped Hessian into the H slot; returns (0, region).

    The returned "energy" is always 0: IFE defines none (the public API refuses to report one).
    ``d`` is the length of ``sigma``, a compile-time literal.
    """
    eps = params[2]
    J = 1.0
    for i in range(d):
        J *= sigma[i]
    if J >= eps:
        model_derivatives_into(model_id, sigma, d, params, order, work, ws.G, ws.H)
        return 0.0, 0
    a = ws.vector(work, ws.A_OFFSET, d)
    q = ws.vector(work, ws.Q_POINT, d)
    for i in range(d):
        a[i] = sigma[i] - 1.0
    s = threshold_parameter(a, eps)
    for i in range(d):
        q[i] = 1.0 + s * a[i]
    model_derivatives_into(model_id, q, d, params, max(order, 2), work, ws.MODEL_G, ws.MODEL_H)
    g = ws.vector(work, ws.MODEL_G, d)
    H = ws.matrix(work, ws.MODEL_H, d)
    out_g = ws.vector(work, ws.G, d)
    out_H = ws.matrix(work, ws.H, d)
    for i in range(d):
        total = g[i]
        for j in range(d):
            total += H[i, j] * (sigma[j] - q[j])
            out_H[i, j] = H[i, j]
        out_g[i] = total
    return 0.0, 1


#: The module's entry for the compiled dispatch on the extension id.
derivatives = ife_derivatives


class IFE(Extension):
    """Stress-based invertible-FE extension past J = ε (default 0.9); has no energy."""

    extension_id = 3
    has_energy = False

    def __init__(self, eps: float = 0.9):
        super().__init__(eps)
