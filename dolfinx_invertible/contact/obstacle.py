"""What every rigid obstacle provides: a signed gap, its derivatives and straight-path crossings.

The gap d(x, t) is positive where the body may be (outside a ball, inside a bowl), zero on the
obstacle's surface and negative inside the obstacle; near the surface it is the distance to it.
A shape defines its gap in its own frame (as constructed); an optional
:class:`~dolfinx_invertible.contact.motion.RigidMotion` moves it, and the gap at time t is that of
the point mapped back into the shape's frame, y = R(t)ᵀ(x − p − T(t)) + p. Hence

    ∇ₓd = R ∇_y d,    ∇ₓ²d = R ∇_y²d Rᵀ,

and, since y is affine in x, a straight path x + α p stays straight in the shape's frame (with
direction Rᵀp): each shape's crossing test is exact for moving obstacles at a fixed time too.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dolfinx_invertible.contact.motion import RigidMotion
from dolfinx_invertible.quadratic import first_positive_root_quadratic

__all__ = ["Obstacle"]


class Obstacle:
    """Base class of the analytic rigid obstacles.

    Subclasses set ``dimension`` and implement, in the shape's own frame (points ``y`` as rows):

    - ``_gap(y)`` → (n,);
    - ``_gap_derivatives(y)`` → (gap (n,), gradient (n, d), Hessian (n, d, d));
    - ``_crossing_polynomial(y, q)`` → coefficients (c₀, c₁, c₂), each (n,), of a polynomial
      c₀ + c₁α + c₂α² with c₀ > 0 where the gap at y is positive, whose first positive root is
      the first α at which the gap along y + α q reaches 0.
    """

    dimension: int = 0

    def __init__(self, motion: RigidMotion | None = None) -> None:
        if motion is not None:
            if not isinstance(motion, RigidMotion):
                raise ValueError(f"motion must be a RigidMotion or None, got {motion!r}")
            if motion.dimension != self.dimension:
                raise ValueError(
                    f"motion is {motion.dimension}D but the obstacle is {self.dimension}D"
                )
        self.motion = motion

    # -- world frame --------------------------------------------------------------------------
    def _points(self, name: str, x) -> np.ndarray:
        array = np.asarray(x, dtype=np.float64)
        if array.ndim != 2 or array.shape[1] != self.dimension:
            raise ValueError(
                f"{name} must have shape (n, {self.dimension}) for a {self.dimension}D "
                f"obstacle, got shape {array.shape}"
            )
        return array

    def _path_in_body(self, x, direction, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Return the points and the directions of paths ``x + α · direction`` in the body frame."""
        x = self._points("x", x)
        p = self._points("direction", direction)
        if p.shape != x.shape:
            raise ValueError(f"direction has shape {p.shape}, x has shape {x.shape}")
        y, R = self._to_body(x, t)
        return y, (p if R is None else p @ R)

    def _to_body(self, x: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray | None]:
        if self.motion is None:
            return x, None
        return self.motion.to_body(x, t)

    def gap(self, x: ArrayLike, t: float = 0.0) -> np.ndarray:
        """Return the signed gap at the points ``x`` (n, d) at time ``t``: shape (n,)."""
        y, _ = self._to_body(self._points("x", x), t)
        return self._gap(y)

    def gap_derivatives(
        self, x: ArrayLike, t: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the gap (n,), its gradient (n, d) and Hessian (n, d, d) in x at time ``t``.

        Where the gap's derivatives do not exist (the centre of a sphere, the axis of a
        cylinder or cone, far from the surface), they are reported as zero.
        """
        y, R = self._to_body(self._points("x", x), t)
        gap, gradient, hessian = self._gap_derivatives(y)
        if R is not None:
            gradient = gradient @ R.T
            hessian = R @ hessian @ R.T
        return gap, gradient, hessian

    def path_crossing(self, x: ArrayLike, direction: ArrayLike, t: float = 0.0) -> np.ndarray:
        """First α > 0 at which the gap along ``x + α · direction`` reaches 0, at time ``t``.

        ``x`` and ``direction`` are (n, d). Returns (n,): ``inf`` where the path never reaches
        the obstacle, 0 where the point is not outside it to begin with.
        """
        y, q = self._path_in_body(x, direction, t)
        c0, c1, c2 = self._crossing_polynomial(y, q)
        roots = first_positive_root_quadratic(c0, c1, c2)
        roots[~(self._gap(y) > 0.0)] = 0.0
        return roots

    # -- shape frame --------------------------------------------------------------------------
    def _gap(self, y: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _gap_derivatives(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        raise NotImplementedError

    def _crossing_polynomial(
        self, y: np.ndarray, q: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        raise NotImplementedError


def radial_frame(
    v: np.ndarray, projector: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Length ρ = |v| (n,), unit vectors e = v/ρ (zero where ρ = 0) and (P − eeᵀ)/ρ (n, d, d).

    With v = P(x − c) for a constant orthogonal projector P (the identity by default), these
    are the derivatives of ρ in x: ∇ρ = e, ∇²ρ = (P − eeᵀ)/ρ (zero at ρ = 0, where ρ has none).
    """
    rho = np.linalg.norm(v, axis=1)
    safe = np.where(rho > 0.0, rho, 1.0)
    e = v / safe[:, None]
    e[rho == 0.0] = 0.0
    d = v.shape[1]
    projector = np.eye(d) if projector is None else projector
    curvature = (projector[None] - e[:, :, None] * e[:, None, :]) / safe[:, None, None]
    curvature[rho == 0.0] = 0.0
    return rho, e, curvature
