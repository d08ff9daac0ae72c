"""C1 extension (paper §4.1) past the threshold σᵢ = ε on each singular value.

With S = {i : σᵢ < ε} and q = σ with the entries in S replaced by ε,

    Ψ̂ext(σ) = Σ_{T ⊆ S} ∂_T Ψ̂(q) Π_{i∈T} (σᵢ − ε) + k/2 Σ_{i∈S} (σᵢ − ε)²,

where ∂_T is the mixed partial over the indices in T. In 3D with all three values below ε the
T = {1, 2, 3} term carries the third mixed partial; without it the extension is not C1. The
stress is continuous everywhere; the tangent jumps across region boundaries by design.
"""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.compiled import compiled_only
from dolfinx_invertible.constitutive.extensions.base import Extension
from dolfinx_invertible.constitutive.models.base import Model
from dolfinx_invertible.constitutive.models.registry import model_derivatives_into
from dolfinx_invertible.constitutive.validation import Parameter

__all__ = ["C1", "derivatives", "c1_derivatives"]


@compiled_only
def _mixed_partial(subset, extra0, extra1, psi, g, H, T, Q, d):
    """Partial derivative of Ψ̂ over the indices in bitmask ``subset`` plus ``extra0/1`` (≥ 0)."""
    i0 = -1
    i1 = -1
    i2 = -1
    i3 = -1
    count = 0
    for index in range(d + 2):
        if index < d:
            if not subset & (1 << index):
                continue
            current = index
        else:
            current = extra0 if index == d else extra1
            if current < 0:
                continue
        if count == 0:
            i0 = current
        elif count == 1:
            i1 = current
        elif count == 2:
            i2 = current
        else:
            i3 = current
        count += 1
    if count == 0:
        return psi
    if count == 1:
        return g[i0]
    if count == 2:
        return H[i0, i1]
    if count == 3:
        return T[i0, i1, i2]
    return Q[i0, i1, i2, i3]


@compiled_only
def _product(subset, skip, offsets, d):
    """Π (σᵢ − ε) over the indices in ``subset`` outside bitmask ``skip``."""
    value = 1.0
    for i in range(d):
        if subset & (1 << i) and not skip & (1 << i):
            value *= offsets[i]
    return value


@compiled_only
def c1_derivatives(model_id, sigma, d, params, order, work):
    """Ψ̂ext(σ) and (up to ``order`` ≤ 2) its gradient and Hessian into the G, H slots.

    Returns the energy and the region: the number of singular values below ε. ``d`` is the
    length of ``sigma``, a compile-time literal.
    """
    eps = params[2]
    k = params[3]
    below = 0
    count = 0
    q = ws.vector(work, ws.Q_POINT, d)
    offsets = ws.vector(work, ws.A_OFFSET, d)
    for i in range(d):
        if sigma[i] < eps:
            below |= 1 << i
            count += 1
            q[i] = eps
            offsets[i] = sigma[i] - eps
        else:
            q[i] = sigma[i]
            offsets[i] = 0.0
    if count == 0:
        return model_derivatives_into(model_id, sigma, d, params, order, work, ws.G, ws.H), 0
    g = ws.vector(work, ws.MODEL_G, d)
    H = ws.matrix(work, ws.MODEL_H, d)
    T = ws.tensor3(work, ws.MODEL_T, d)
    Q = ws.tensor4(work, ws.MODEL_Q, d)
    psi_q = model_derivatives_into(
        model_id, q, d, params, min(count + order, 4), work, ws.MODEL_G, ws.MODEL_H
    )
    out_g = ws.vector(work, ws.G, d)
    out_H = ws.matrix(work, ws.H, d)

    psi = 0.0
    for subset in range(below + 1):
        if subset & ~below:
            continue
        psi += _mixed_partial(subset, -1, -1, psi_q, g, H, T, Q, d) * _product(
            subset, 0, offsets, d
        )
    for i in range(d):
        psi += 0.5 * k * offsets[i] * offsets[i]
    if order < 1:
        return psi, count

    for l in range(d):
        bit_l = 1 << l
        l_below = below & bit_l
        total = k * offsets[l]
        for subset in range(below + 1):
            if subset & ~below:
                continue
            if l_below:
                # σ_l enters only through the product: differentiate that.
                if not subset & bit_l:
                    continue
                total += _mixed_partial(subset, -1, -1, psi_q, g, H, T, Q, d) * _product(
                    subset, bit_l, offsets, d
                )
            else:
                # σ_l = q_l enters only through the partial derivative at q.
                total += _mixed_partial(subset, l, -1, psi_q, g, H, T, Q, d) * _product(
                    subset, 0, offsets, d
                )
        out_g[l] = total
    if order < 2:
        return psi, count

    for l in range(d):
        for m in range(l, d):
            bit_l = 1 << l
            bit_m = 1 << m
            skip = (below & bit_l) | (below & bit_m)
            extra_l = -1 if below & bit_l else l
            extra_m = -1 if below & bit_m else m
            total = k if (l == m and below & bit_l) else 0.0
            # The product is linear in each σᵢ, so a repeated in-S index contributes nothing.
            if not (l == m and below & bit_l):
                for subset in range(below + 1):
                    if subset & ~below or (subset & skip) != skip:
                        continue
                    total += _mixed_partial(
                        subset, extra_l, extra_m, psi_q, g, H, T, Q, d
                    ) * _product(subset, skip, offsets, d)
            out_H[l, m] = total
            out_H[m, l] = total
    return psi, count


#: The module's entry for the compiled dispatch on the extension id.
derivatives = c1_derivatives


def _check_stiffness(name: str, k: float) -> float:
    if not (k >= 0.0 and k < float("inf")):
        raise ValueError(f"{name} must be a finite number >= 0 (or None for 20 E), got {k!r}")
    return k


class C1(Extension):
    """C1 extension past σᵢ = ε (default ε = 0.4) with quadratic penalty stiffness ``k``.

    Parameters
    ----------
    eps
        Threshold on each singular value, in (0, 1).
    k
        Stiffness of the quadratic term; ``None`` means 20·E with E the Young's modulus of the
        model it extends (the paper's choice).
    """

    extension_id = 1

    def __init__(self, eps=0.4, k=None):
        super().__init__(eps)
        self._k = None if k is None else Parameter("k", k, _check_stiffness)

    @property
    def k(self) -> float | None:
        """Current stiffness, or None for 20·E of the model."""
        return None if self._k is None else self._k.value

    def stiffness(self, model: Model) -> float:
        """Return the penalty stiffness used with ``model``: ``k``, or 20·E when ``k`` is None."""
        return 20.0 * model.youngs_modulus if self._k is None else self._k.value

    def parameters(self, model: Model) -> np.ndarray:
        """Return the parameters in the order the kernels read them: [ε, k]."""
        return np.array([self.eps, self.stiffness(model)])

    def parameter_sources(self) -> dict:
        """{position in :meth:`parameters`: the Constant it is read from}."""
        sources = super().parameter_sources()
        if self._k is not None and self._k.constant is not None:
            sources[1] = self._k.constant
        return sources

    def derived_stiffness(self, model: Model) -> bool:
        """K = 20·E follows μ and λ when either is read from a Constant."""
        return self._k is None and bool(model.parameter_sources())

    def __repr__(self) -> str:
        return f"C1(eps={self._eps!r}, k={self._k!r})"
