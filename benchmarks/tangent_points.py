"""CPU time per point of the batch tangent, exact and projected, in three states near rest.

``python benchmarks/tangent_points.py [repeats]``: Neo-Hookean + C2 (ε = 0.9, E = 1e3, ν = 0.3),
48 000 points of F = s·I + 0.01·N(0, 1) for s = 1.00, 1.01, 0.97, ``Material.tangent``, medians.
"""

import sys
import time

import numpy as np

import dolfinx_invertible as di


def main() -> None:
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 9
    mu, lam = di.lame(E=1e3, nu=0.3)
    material = di.Material(di.NeoHookean(mu=mu, lam=lam), extension=di.C2(eps=0.9))
    generator = np.random.default_rng(1)
    points = 48000
    for name, stretch in (("random near rest", 1.0), ("fast path", 1.01), ("compressed", 0.97)):
        F = stretch * np.eye(3) + 0.01 * generator.standard_normal((points, 3, 3))
        for project in (False, True):
            material.tangent(F[:10], project=project)
            times = []
            for _ in range(repeats):
                started = time.thread_time()
                material.tangent(F, project=project)
                times.append(time.thread_time() - started)
            kind = "projected" if project else "exact"
            print(f"{name} (s = {stretch}), {kind}: {1e9 * np.median(times) / points:.0f} ns")


if __name__ == "__main__":
    main()
