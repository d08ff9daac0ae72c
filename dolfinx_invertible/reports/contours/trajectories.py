"""Computed stand-ins for the paper's element trajectories in the singular-value plane.

Single elements, no mesh: stretched quasi-statically with a lateral spring (the mattress) or
relaxed by implicit gradient flow from given deformations (the triangles). A scene run's own
trajectories (``mattress-2d``, ``triangles-2d``) replace them in the report's figures.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dolfinx_invertible.constitutive import Material
from dolfinx_invertible.constitutive.contours import REST

__all__ = [
    "LATERAL_STIFFNESS",
    "RELAXATION_STARTS",
    "relaxation_trajectories",
    "stretch_trajectories",
]

#: Deformations the three relaxing elements start from (canonical σ).
RELAXATION_STARTS = np.array([[2.6, -0.9], [0.45, 0.3], [3.4, 1.7]])

#: Lateral spring κ/μ of the three stretched elements.
LATERAL_STIFFNESS = (0.0, 1.0, 4.0)


def _canonical(sigma: np.ndarray) -> np.ndarray:
    """Return the IFE representative: |σ| sorted down, an odd sign on the last entry."""
    magnitude = np.sort(np.abs(sigma))[::-1]
    if np.prod(sigma) < 0.0:
        magnitude[-1] = -magnitude[-1]
    return magnitude


def _shear_modulus(material: Material) -> float:
    """Return μ from the rest Hessian 2μI + λ11ᵀ, which every model shares."""
    hessian = material.hessian_sigma(REST)
    return 0.5 * (hessian[0, 0] - hessian[0, 1])


def _projected(hessian: np.ndarray) -> np.ndarray:
    values, vectors = np.linalg.eigh(hessian)
    return (vectors * np.maximum(values, 0.0)) @ vectors.T


def stretch_trajectories(
    material: Material,
    *,
    stretches: np.ndarray | None = None,
    lateral_stiffness: Sequence[float] = LATERAL_STIFFNESS,
) -> np.ndarray:
    """Stretch single elements quasi-statically: σ₁ imposed, σ₂ at equilibrium.

    A stand-in for the elements of a mattress pulled by two sides. For each imposed σ₁, σ₂
    minimises Ψ̂(σ₁, σ₂) + κ/2 (σ₂ − 1)², the spring κ standing for the lateral restraint of
    the surrounding mesh (κ = 0: free sides, uniaxial stress). One-dimensional Newton with an
    energy backtracking line search, continued from the previous stretch.

    Parameters
    ----------
    material
        The material (2D).
    stretches
        Imposed σ₁ per step; default 51 values from 1 to 3.5.
    lateral_stiffness
        κ/μ per element, μ the shear modulus.

    Returns
    -------
    numpy.ndarray
        Shape (elements, steps, 2): canonical signed singular values.
    """
    stretches = np.linspace(1.0, 3.5, 51) if stretches is None else np.asarray(stretches, float)
    if stretches.ndim != 1 or len(stretches) < 2 or not np.isfinite(stretches).all():
        raise ValueError("stretches must be a 1D array of at least two finite values")
    mu = _shear_modulus(material)
    trajectories = np.empty((len(lateral_stiffness), len(stretches), 2))
    for element, factor in enumerate(lateral_stiffness):
        kappa = float(factor) * mu
        if not (np.isfinite(kappa) and kappa >= 0.0):
            raise ValueError(f"lateral_stiffness must be finite and >= 0, got {factor!r}")
        lateral = 1.0
        for step, stretch in enumerate(stretches):
            lateral = _lateral_equilibrium(material, stretch, lateral, kappa, mu)
            trajectories[element, step] = _canonical(np.array([stretch, lateral]))
    return trajectories


def _lateral_equilibrium(material, stretch, lateral, kappa, mu):
    def potential(value):
        return material.energy_sigma(np.array([stretch, value])) + 0.5 * kappa * (value - 1) ** 2

    energy = potential(lateral)
    for _ in range(100):
        point = np.array([stretch, lateral])
        slope = material.stress_sigma(point)[1] + kappa * (lateral - 1.0)
        if abs(slope) <= 1e-11 * mu:
            break
        curvature = max(material.hessian_sigma(point)[1, 1] + kappa, 1e-3 * mu)
        step = -slope / curvature
        length = 1.0
        while length > 1e-12:
            candidate = lateral + length * step
            candidate_energy = potential(candidate)
            if candidate_energy <= energy + 1e-4 * length * slope * step:
                break
            length *= 0.5
        if candidate_energy > energy:
            # No decrease left above the energy's rounding error: converged.
            break
        lateral, energy = candidate, candidate_energy
    return lateral


def relaxation_trajectories(
    material: Material,
    starts: np.ndarray,
    *,
    steps: int = 60,
    first_step: float = 0.01,
    growth: float = 1.08,
) -> np.ndarray:
    """Relax single free elements from given deformations by implicit gradient flow.

    A stand-in for the paper's triangles relaxing from different deformations. With the
    deformation gradient of a free element as the unknown (up to translation and rotation),
    gradient flow keeps U and V and moves σ along −g; each backward-Euler step minimises
    ½‖σ − σₙ‖²/Δt + Ψ̂(σ)/(2μ) by Newton with the SPD-projected Hessian and an energy
    backtracking line search. Δt is in units of the soft (shear) relaxation time, starting at
    ``first_step`` and growing by ``growth``, so both the stiff and the soft mode are resolved.

    Parameters
    ----------
    material
        The material (2D); it needs an energy (not IFE).
    starts
        Initial signed singular values, shape (elements, 2).
    steps
        Number of time steps.
    first_step
        First Δt.
    growth
        Factor between consecutive Δt.

    Returns
    -------
    numpy.ndarray
        Shape (elements, steps + 1, 2): canonical signed singular values, the start first.
    """
    starts = np.asarray(starts, dtype=float)
    if starts.ndim != 2 or starts.shape[1] != 2 or not np.isfinite(starts).all():
        raise ValueError(
            f"starts must be a finite array of shape (elements, 2), got {starts.shape}"
        )
    if int(steps) < 1 or not (first_step > 0.0 and growth >= 1.0):
        raise ValueError("steps must be >= 1, first_step > 0 and growth >= 1")
    scale = 2.0 * _shear_modulus(material)
    trajectories = np.empty((len(starts), int(steps) + 1, 2))
    for element, start in enumerate(starts):
        sigma = _canonical(start)
        trajectories[element, 0] = sigma
        step = float(first_step)
        for index in range(1, int(steps) + 1):
            sigma = _canonical(_backward_euler_step(material, sigma, step, scale))
            trajectories[element, index] = sigma
            step *= growth
    return trajectories


def _backward_euler_step(material, previous, step, scale):
    def potential(sigma):
        return 0.5 * np.sum((sigma - previous) ** 2) / step + material.energy_sigma(sigma) / scale

    def residual_of(sigma):
        inertia = (sigma - previous) / step
        force = material.stress_sigma(sigma) / scale
        return inertia + force, max(np.linalg.norm(inertia) + np.linalg.norm(force), 1.0)

    sigma = previous.copy()
    energy = potential(sigma)
    residual, size = residual_of(sigma)
    for _ in range(50):
        if np.linalg.norm(residual) <= 1e-10 * size:
            break
        system = np.eye(2) / step + _projected(material.hessian_sigma(sigma)) / scale
        direction = -np.linalg.solve(system, residual)
        slope = residual @ direction
        if -slope <= 1e-12 * abs(energy):
            # The decrease is below the energy's rounding error: the residual decides.
            candidate = sigma + direction
            candidate_residual, candidate_size = residual_of(candidate)
            if np.linalg.norm(candidate_residual) >= np.linalg.norm(residual):
                break
            sigma, energy = candidate, potential(candidate)
            residual, size = candidate_residual, candidate_size
            continue
        length = 1.0
        for _ in range(40):
            candidate = sigma + length * direction
            candidate_energy = potential(candidate)
            if candidate_energy <= energy + 1e-4 * length * slope:
                break
            length *= 0.5
        else:
            break
        sigma, energy = candidate, candidate_energy
        residual, size = residual_of(sigma)
    return sigma
