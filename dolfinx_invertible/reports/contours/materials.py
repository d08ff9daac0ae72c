"""The four materials of the primary-contour report (the paper's Figs. 1–2)."""

from __future__ import annotations

from dolfinx_invertible.constitutive import (
    C1,
    C2,
    Corotated,
    FixedCorotated,
    Material,
    NeoHookean,
    lame,
)

__all__ = ["POISSON_RATIO", "YOUNGS_MODULUS", "report_materials"]

#: Young's modulus and Poisson ratio of the report's materials (λ/μ = 9, plane strain). The
#: contours depend only on λ/μ and the extensions' ε and k/μ.
YOUNGS_MODULUS = 1.0e5
POISSON_RATIO = 0.45


def report_materials(
    *, youngs_modulus: float = YOUNGS_MODULUS, poisson_ratio: float = POISSON_RATIO
) -> dict[str, Material]:
    """Build the four materials of the paper's Figs. 1–2, by display name.

    Parameters
    ----------
    youngs_modulus
        E of every material.
    poisson_ratio
        ν of every material.

    Returns
    -------
    dict
        Neo-Hookean + C1 (ε = 0.4, k = 20E), Neo-Hookean + C2 (ε = 0.9), corotated and fixed
        corotated.
    """
    mu, lam = lame(youngs_modulus, poisson_ratio)
    return {
        "Neo-Hookean + C1": Material(NeoHookean(mu=mu, lam=lam), C1(eps=0.4)),
        "Neo-Hookean + C2": Material(NeoHookean(mu=mu, lam=lam), C2(eps=0.9)),
        "corotated": Material(Corotated(mu=mu, lam=lam)),
        "fixed corotated": Material(FixedCorotated(mu=mu, lam=lam)),
    }
