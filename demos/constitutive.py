"""Constitutive demo: energies through inversion and single elements relaxing from inversion.

Run it with ``.venv/bin/python demos/constitutive.py``. Writes ``output/constitutive/`` under the
working directory (a JSON summary and two PNG figures) and prints a short report:

1. Uniaxial compression σ = (t, 1, 1) from t = 1.5 down to t = -1 (through inversion) for
   Neo-Hookean with the C1 and C2 extensions, corotated and fixed corotated: energy and the
   principal stress along the path. The plain Neo-Hookean energy is infinite at t ≤ 0; the
   extensions keep it finite and smooth.
2. A 2D element (the deformation gradient itself as unknown, as for a free triangle up to
   translation) relaxes from inverted and stretched starting points by projected Newton with an
   energy backtracking line search, as in the paper's Fig. 2. Each run reports its trajectory in
   singular-value space and whether it passed through inversion.
"""

from __future__ import annotations

import json
import pathlib
import sys

import numpy as np

from dolfinx_invertible import (
    C1,
    C2,
    Corotated,
    FixedCorotated,
    Material,
    NeoHookean,
    lame,
    polar_svd,
)

OUTPUT = pathlib.Path("output") / "constitutive"


def compression_path(materials: dict[str, Material]) -> dict:
    stretch = np.linspace(1.5, -1.0, 251)
    F = np.zeros((len(stretch), 3, 3))
    F[:, 0, 0] = stretch
    F[:, 1, 1] = 1.0
    F[:, 2, 2] = 1.0
    curves = {}
    for name, material in materials.items():
        # The plain Neo-Hookean model has no stress at J <= 0 (the API refuses): leave gaps.
        defined = np.isfinite(material.energy(F))
        stress = np.full(len(F), np.nan)
        stress[defined] = material.stress(F[defined])[:, 0, 0]
        curves[name] = {
            "energy": [value if np.isfinite(value) else None for value in material.energy(F)],
            "stress_11": [value if np.isfinite(value) else None for value in stress],
        }
    return {"stretch": stretch.tolist(), "curves": curves}


def relax(material: Material, F0: np.ndarray, steps: int = 200) -> dict:
    """Minimise Ψ(F) over F by projected Newton with energy backtracking."""
    F = F0.copy()
    d = F.shape[0]
    trajectory = [polar_svd(F)[1].tolist()]
    energy = material.energy(F)
    for _ in range(steps):
        gradient = material.stress(F).ravel()
        if np.linalg.norm(gradient) < 1e-10:
            break
        tangent = material.tangent(F, project=True)
        # The projected tangent can be singular (clamped modes): regularise lightly.
        shift = 1e-8 * max(1.0, np.abs(tangent).max())
        direction = -np.linalg.solve(tangent + shift * np.eye(d * d), gradient).reshape(d, d)
        step = 1.0
        while step > 1e-12:
            candidate = F + step * direction
            candidate_energy = material.energy(candidate)
            if candidate_energy <= energy + 1e-4 * step * gradient @ direction.ravel():
                break
            step *= 0.5
        F = candidate
        energy = candidate_energy
        trajectory.append(polar_svd(F)[1].tolist())
    sigma = np.array(trajectory)
    return {
        "trajectory": trajectory,
        "iterations": len(trajectory) - 1,
        "final_sigma": sigma[-1].tolist(),
        "final_energy": float(energy),
        "passed_through_inversion": bool((sigma[:, -1] < 0).any()),
    }


def plot(summary: dict, directory: pathlib.Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    path = summary["compression"]
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for name, curve in path["curves"].items():
        energy = np.array([np.nan if v is None else v for v in curve["energy"]])
        axes[0].plot(path["stretch"], np.where(np.isfinite(energy), energy, np.nan), label=name)
        stress = np.array([np.nan if v is None else v for v in curve["stress_11"]])
        axes[1].plot(path["stretch"], stress, label=name)
    axes[0].set(xlabel="σ₁ (σ₂ = σ₃ = 1)", ylabel="energy density", yscale="symlog")
    axes[1].set(xlabel="σ₁ (σ₂ = σ₃ = 1)", ylabel="P₁₁")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(directory / "compression.png", dpi=120)
    written.append(str(directory / "compression.png"))

    fig, ax = plt.subplots(figsize=(5, 5))
    for name, run in summary["relaxation"].items():
        sigma = np.array(run["trajectory"])
        ax.plot(sigma[:, 0], sigma[:, 1], ".-", label=name, markersize=3)
    ax.axhline(0.0, color="grey", lw=0.5)
    ax.set(xlabel="σ₁", ylabel="σ₂ (signed)", title="2D element relaxing to rest (1, 1)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(directory / "relaxation.png", dpi=120)
    written.append(str(directory / "relaxation.png"))
    plt.close("all")
    return written


def main() -> int:
    mu, lam = lame(1.0e5, 0.45)
    materials = {
        "Neo-Hookean (plain)": Material(NeoHookean(mu=mu, lam=lam)),
        "Neo-Hookean + C1": Material(NeoHookean(mu=mu, lam=lam), C1(eps=0.4)),
        "Neo-Hookean + C2": Material(NeoHookean(mu=mu, lam=lam), C2(eps=0.9)),
        "corotated": Material(Corotated(mu=mu, lam=lam)),
        "fixed corotated": Material(FixedCorotated(mu=mu, lam=lam)),
    }
    summary = {"E": 1.0e5, "nu": 0.45, "compression": compression_path(materials)}

    starts = {
        "inverted": np.array([[0.8, 0.3], [0.2, -0.6]]),
        "stretched": np.array([[2.5, 0.2], [0.0, 0.4]]),
        "flattened": np.array([[1.6, 0.9], [1.5, 0.85]]),
    }
    summary["relaxation"] = {}
    for start_name, F0 in starts.items():
        for name in ("Neo-Hookean + C2", "corotated"):
            summary["relaxation"][f"{name}, {start_name}"] = relax(materials[name], F0)

    OUTPUT.mkdir(parents=True, exist_ok=True)
    (OUTPUT / "summary.json").write_text(json.dumps(summary, indent=1))
    figures = plot(summary, OUTPUT)

    print("Uniaxial compression σ = (t, 1, 1): energy density at t = 0.5, 0, -0.5")
    stretch = np.array(summary["compression"]["stretch"])
    for name, curve in summary["compression"]["curves"].items():
        values = [curve["energy"][int(np.argmin(abs(stretch - t)))] for t in (0.5, 0.0, -0.5)]
        print(
            f"  {name:22s}"
            + "".join(f"{value if value is not None else float('inf'):14.5g}" for value in values)
        )
    print("2D element relaxation (projected Newton, energy line search):")
    failures = 0
    for name, run in summary["relaxation"].items():
        rest = np.allclose(np.abs(run["final_sigma"]), 1.0, atol=1e-6)
        failures += not rest
        print(
            f"  {name:32s} iterations {run['iterations']:3d}  final σ "
            f"{np.round(run['final_sigma'], 6)}  through inversion: "
            f"{run['passed_through_inversion']}  {'at rest' if rest else 'NOT at rest'}"
        )
    print("wrote", OUTPUT / "summary.json", *figures)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
