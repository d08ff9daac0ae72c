"""Benchmark of the material kernels: numba against the independent NumPy reference.

Times energy, stress and projected tangent of Neo-Hookean with the C2 extension on random 3D
deformation gradients, numba (:class:`dolfinx_invertible.Material`) against the vectorised NumPy
reference of the tests (``tests/constitutive/numpy_reference.py``, which the tests check on its
own before they judge the compiled material by it), interleaved, on one thread. Speeds are only
reported if both implementations agree on a subsample.
"""

from __future__ import annotations

import argparse
import gc
import importlib.util
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from benchmarks import common


def _load_numpy_reference():
    # By its path: the tests' folders are not packages, and the repository root need not be on
    # sys.path.
    path = Path(__file__).resolve().parents[1] / "tests" / "constitutive" / "numpy_reference.py"
    specification = importlib.util.spec_from_file_location("numpy_reference", path)
    module = importlib.util.module_from_spec(specification)
    specification.loader.exec_module(module)
    return module


numpy_reference = _load_numpy_reference()

# Results that differ by more than this (relative, see numpy_reference.max_relative_difference)
# mean one of the two implementations is wrong, and timing wrong code is meaningless.
AGREEMENT_TOLERANCE = 1e-8
# Material used by the benchmark; the values only set the scale, not the cost.
YOUNGS_MODULUS = 1.0
POISSON_RATIO = 0.3
C2_EPS = 0.9
# F = I + spread * N(0, 1): with 0.35 about half of the points fall below J = 0.9 and about 2 % are
# inverted, so both branches of the extension carry real weight (the report gives exact shares).
SPREAD = 0.35
WARMUP_POINTS = 64
AGREEMENT_POINTS = 20_000


def _time_once(function: Callable[[], object]) -> float:
    # Collections triggered by the other implementation's garbage must not land in this timing.
    gc.collect()
    gc.disable()
    try:
        start = time.perf_counter()
        result = function()
        elapsed = time.perf_counter() - start
    finally:
        gc.enable()
    del result
    return elapsed


def random_deformations(points: int, seed: int, dimension: int = 3) -> np.ndarray:
    """Random deformation gradients ``F = I + SPREAD * N(0, 1)``, shape ``(points, d, d)``."""
    rng = np.random.default_rng(seed)
    return np.eye(dimension) + SPREAD * rng.standard_normal((points, dimension, dimension))


def run_material(points: int, repeats: int, seed: int) -> dict:
    """Time numba against the NumPy reference for Neo-Hookean + C2 on random 3D points.

    Parameters
    ----------
    points : int
        Number of deformation gradients.
    repeats : int
        Timed repeats per operation and implementation (interleaved).
    seed : int
        Seed of the random deformation gradients.

    Returns
    -------
    dict
        JSON-ready report. ``"agreement_ok"`` is ``False`` (and no timings are present) if the two
        implementations disagree beyond :data:`AGREEMENT_TOLERANCE`.
    """
    from dolfinx_invertible import C2, Material, NeoHookean, lame

    mu, lam = lame(YOUNGS_MODULUS, POISSON_RATIO)
    material = Material(NeoHookean(mu=mu, lam=lam), extension=C2(eps=C2_EPS))
    F = random_deformations(points, seed)
    determinants = np.linalg.det(F)

    implementations: dict[str, dict[str, Callable[[np.ndarray], np.ndarray]]] = {
        "numba": {
            "energy": material.energy,
            "stress": material.stress,
            "tangent": lambda G: material.tangent(G, project=True),
        },
        "numpy": {
            "energy": lambda G: numpy_reference.energy(G, mu, lam, C2_EPS),
            "stress": lambda G: numpy_reference.stress(G, mu, lam, C2_EPS),
            "tangent": lambda G: numpy_reference.tangent(G, mu, lam, C2_EPS, project=True),
        },
    }
    operations = list(implementations["numba"])

    report: dict = {
        "benchmark": "material",
        "material": {
            "model": "NeoHookean",
            "mu": mu,
            "lam": lam,
            "youngs_modulus": YOUNGS_MODULUS,
            "poisson_ratio": POISSON_RATIO,
            "extension": "C2",
            "eps": C2_EPS,
        },
        "points": points,
        "dimension": 3,
        "repeats": repeats,
        "seed": seed,
        "sample": {
            "distribution": f"F = I + {SPREAD} * standard normal",
            "share_J_below_eps": float(np.mean(determinants < C2_EPS)),
            "share_inverted": float(np.mean(determinants <= 0.0)),
        },
    }

    # First calls compile (or load from numba's cache); keep that out of the timings.
    warmup = F[:WARMUP_POINTS]
    report["compile_seconds"] = {
        operation: _time_once(lambda f=function: f(warmup))
        for operation, function in implementations["numba"].items()
    }
    for function in implementations["numpy"].values():
        function(warmup)

    subsample = F[: min(points, AGREEMENT_POINTS)]
    differences = {
        operation: numpy_reference.max_relative_difference(
            implementations["numba"][operation](subsample),
            implementations["numpy"][operation](subsample),
        )
        for operation in operations
    }
    agreement_ok = all(value <= AGREEMENT_TOLERANCE for value in differences.values())
    report["agreement"] = {
        "subsample_points": int(subsample.shape[0]),
        "tolerance": AGREEMENT_TOLERANCE,
        "max_relative_difference": differences,
    }
    report["agreement_ok"] = agreement_ok
    report["machine"] = common.machine()
    if not agreement_ok:
        return report

    timings: dict[str, dict[str, list[float]]] = {
        operation: {name: [] for name in implementations} for operation in operations
    }
    for repeat in range(repeats):
        for operation in operations:
            # Alternate which implementation goes first so neither always inherits a warm cache.
            order = ["numba", "numpy"] if repeat % 2 == 0 else ["numpy", "numba"]
            for name in order:
                function = implementations[name][operation]
                timings[operation][name].append(_time_once(lambda f=function: f(F)))

    results = {}
    for operation in operations:
        entry = {}
        for name in implementations:
            median = statistics.median(timings[operation][name])
            entry[name] = {
                "median_seconds": median,
                "points_per_second": points / median,
                "all_seconds": timings[operation][name],
            }
        entry["numba_over_numpy_throughput"] = (
            entry["numba"]["points_per_second"] / entry["numpy"]["points_per_second"]
        )
        results[operation] = entry
    report["operations"] = results
    return report


def _print_material_table(report: dict) -> None:
    sample = report["sample"]
    print(
        f"material benchmark: {report['points']} points (3D), {report['repeats']} repeats, "
        f"{100 * sample['share_J_below_eps']:.1f} % below J = {report['material']['eps']}, "
        f"{100 * sample['share_inverted']:.1f} % inverted, 1 thread",
        file=sys.stderr,
    )
    header = f"{'operation':<10}{'numba [s]':>12}{'numpy [s]':>12}{'numba Mpt/s':>14}"
    header += f"{'numpy Mpt/s':>14}{'speed-up':>10}"
    print(header, file=sys.stderr)
    for operation, entry in report["operations"].items():
        print(
            f"{operation:<10}"
            f"{entry['numba']['median_seconds']:>12.4f}"
            f"{entry['numpy']['median_seconds']:>12.4f}"
            f"{entry['numba']['points_per_second'] / 1e6:>14.3f}"
            f"{entry['numpy']['points_per_second'] / 1e6:>14.3f}"
            f"{entry['numba_over_numpy_throughput']:>9.1f}x",
            file=sys.stderr,
        )
    compile_seconds = ", ".join(f"{k} {v:.2f} s" for k, v in report["compile_seconds"].items())
    print(f"numba first calls (compile or cache load): {compile_seconds}", file=sys.stderr)


def table(report: dict) -> str:
    """Return the report as a human-readable table."""
    sample = report["sample"]
    lines = [
        f"material benchmark: {report['points']} points (3D), {report['repeats']} repeats, "
        f"{100 * sample['share_J_below_eps']:.1f} % below J = {report['material']['eps']}, "
        f"{100 * sample['share_inverted']:.1f} % inverted, 1 thread",
        f"{'operation':<10}{'numba [s]':>12}{'numpy [s]':>12}{'numba Mpt/s':>14}"
        f"{'numpy Mpt/s':>14}{'speed-up':>10}",
    ]
    for operation, entry in report["operations"].items():
        lines.append(
            f"{operation:<10}"
            f"{entry['numba']['median_seconds']:>12.4f}"
            f"{entry['numpy']['median_seconds']:>12.4f}"
            f"{entry['numba']['points_per_second'] / 1e6:>14.3f}"
            f"{entry['numpy']['points_per_second'] / 1e6:>14.3f}"
            f"{entry['numba_over_numpy_throughput']:>9.1f}x"
        )
    compile_seconds = ", ".join(f"{k} {v:.2f} s" for k, v in report["compile_seconds"].items())
    lines.append(f"numba first calls (compile or cache load): {compile_seconds}")
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``bench material``."""
    parser.add_argument("--points", type=int, default=1_000_000, help="number of F (default 1e6)")
    parser.add_argument("--repeats", type=int, default=5, help="timed repeats (default 5)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--json", help="write the JSON report here (default: stdout)")


def command(arguments: argparse.Namespace) -> int:
    """Run ``bench material``; returns the exit code."""
    report = run_material(arguments.points, arguments.repeats, arguments.seed)
    if not report["agreement_ok"]:
        details = ", ".join(
            f"{operation} {value:.3e}"
            for operation, value in report["agreement"]["max_relative_difference"].items()
        )
        print(
            "numba and NumPy results disagree beyond "
            f"{AGREEMENT_TOLERANCE:g} relative ({details}); refusing to report speed.",
            file=sys.stderr,
        )
        return 1
    common.emit(report, table(report), arguments.json)
    return 0
