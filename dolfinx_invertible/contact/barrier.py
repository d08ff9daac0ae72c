"""The IPC log barrier of Li et al. (2020) and the rules that choose its two parameters.

    b(d) = −κ (d − d̂)² ln(d / d̂)   for 0 < d < d̂,   0 for d ≥ d̂,   +∞ for d ≤ 0.

b, b′ and b″ vanish at d = d̂ (b is C² there) and b → ∞ as d → 0. With t = d − d̂:

    b′(d) = −κ (2t ln(d/d̂) + t²/d),    b″(d) = −κ (2 ln(d/d̂) + 4t/d − t²/d²).

b″ depends on d/d̂ only, b″(d̂/2) = (5 + 2 ln 2) κ, which is what the stiffness rule uses.

Rules (both are overridable where the barrier is built):

- d̂ = ``fraction`` × h, h the boundary vertex spacing of the mesh (see
  :func:`barrier_distance`); a tenth by default, so that the gap the barrier leaves is small
  against an element yet spans several Newton steps of a few orders of magnitude each.
- κ such that the barrier's stiffness at d = d̂/2 on a boundary vertex, w b″(d̂/2) with w ≈
  h^(D−1) the vertex's share of the boundary, equals the material's stiffness per vertex,
  E h^(D−2) (D the dimension): κ = E / ((5 + 2 ln 2) h), see :func:`barrier_stiffness`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from dolfinx_invertible.constitutive.validation import check_positive

__all__ = [
    "DEFAULT_DISTANCE_FRACTION",
    "HALF_DISTANCE_CURVATURE",
    "Barrier",
    "barrier_distance",
    "barrier_stiffness",
    "youngs_modulus_for_stiffness",
]

#: d̂ as a share of the boundary vertex spacing h.
DEFAULT_DISTANCE_FRACTION = 0.1
#: b″(d̂/2) / κ = 5 + 2 ln 2.
HALF_DISTANCE_CURVATURE = 5.0 + 2.0 * math.log(2.0)


def barrier_distance(spacing: float, fraction: float = DEFAULT_DISTANCE_FRACTION) -> float:
    """Return d̂ = ``fraction`` × ``spacing`` (the boundary vertex spacing h)."""
    return check_positive("fraction", fraction) * check_positive("spacing", spacing)


def youngs_modulus_for_stiffness(material=None, youngs_modulus: float | None = None) -> float:
    """Return the E that the stiffness rules use: ``youngs_modulus``, else the material's.

    Raises ``ValueError`` if neither is given or ``material`` is not a
    :class:`~dolfinx_invertible.Material`.
    """
    from dolfinx_invertible.constitutive.material import Material

    if youngs_modulus is None:
        if material is None:
            raise ValueError(
                "the barrier stiffness needs a scale: give the material, youngs_modulus or "
                "stiffness"
            )
        if not isinstance(material, Material):
            raise ValueError(f"material must be a Material, got {material!r}")
        youngs_modulus = material.model.youngs_modulus
    return check_positive("youngs_modulus", youngs_modulus)


def barrier_stiffness(youngs_modulus: float, spacing: float) -> float:
    """Return κ = E / ((5 + 2 ln 2) h): barrier stiffness at d̂/2 per vertex ≈ E h^(D−2)."""
    return check_positive("youngs_modulus", youngs_modulus) / (
        HALF_DISTANCE_CURVATURE * check_positive("spacing", spacing)
    )


class Barrier:
    """The scalar barrier b(d) and its first two derivatives, elementwise on arrays of gaps.

    Parameters
    ----------
    distance
        d̂ > 0: where the barrier starts to act.
    stiffness
        κ > 0.
    """

    def __init__(self, distance: float, stiffness: float) -> None:
        self.distance = check_positive("distance", distance)
        self.stiffness = check_positive("stiffness", stiffness)

    def _parts(self, d):
        d = np.asarray(d, dtype=np.float64)
        active = (d > 0.0) & (d < self.distance)
        safe = np.where(active, d, self.distance)
        t = safe - self.distance
        return d, active, safe, t, np.log(safe / self.distance)

    def value(self, d: ArrayLike) -> np.ndarray:
        """b(d): +∞ for d ≤ 0 (and NaN gaps), 0 for d ≥ d̂."""
        d, active, _, t, log = self._parts(d)
        inside = -self.stiffness * t * t * log
        return np.where(active, inside, np.where(d >= self.distance, 0.0, math.inf))

    def derivative(self, d: ArrayLike) -> np.ndarray:
        """b′(d): −∞ for d ≤ 0, 0 for d ≥ d̂."""
        d, active, safe, t, log = self._parts(d)
        inside = -self.stiffness * (2.0 * t * log + t * t / safe)
        return np.where(active, inside, np.where(d >= self.distance, 0.0, -math.inf))

    def second_derivative(self, d: ArrayLike) -> np.ndarray:
        """b″(d): +∞ for d ≤ 0, 0 for d ≥ d̂."""
        d, active, safe, t, log = self._parts(d)
        ratio = t / safe
        inside = -self.stiffness * (2.0 * log + 4.0 * ratio - ratio * ratio)
        return np.where(active, inside, np.where(d >= self.distance, 0.0, math.inf))

    def __repr__(self) -> str:
        return f"Barrier(distance={self.distance!r}, stiffness={self.stiffness!r})"
