"""Material parameters: their layout in the compiled code, and conversions."""

from __future__ import annotations

import math

from dolfinx_invertible.constitutive.validation import check_positive

__all__ = ["PARAMETER_COUNT", "lame"]

#: Entries of a material's parameter vector, in the order the compiled code reads: [μ, λ, ε, k].
PARAMETER_COUNT = 4


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lamé parameters (μ, λ) from Young's modulus ``E`` and Poisson ratio ``nu``.

    These are the 3D constants, which are also the plane-strain ones used in 2D.

    Raises
    ------
    ValueError
        If ``E`` ≤ 0 or ``nu`` is outside (−1, 0.5).
    """
    E = check_positive("E", E)
    nu = float(nu)
    if not (math.isfinite(nu) and -1.0 < nu < 0.5):
        raise ValueError(f"nu (Poisson ratio) must lie in (-1, 0.5), got {nu!r}")
    mu = E / (2.0 * (1.0 + nu))
    lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    return mu, lam
