"""Benchmarks: the material kernels against NumPy, and the DOLFINx benchmarks' entry point.

Usage::

    python -m dolfinx_invertible.bench material [--points N] [--repeats R] [--seed S]
    python -m dolfinx_invertible bench {material,assembly,solve,scaling,compile,memory} --help

``assembly``, ``solve``, ``scaling``, ``compile`` and ``memory`` live in their own modules
(``bench_assembly.py`` …, shared pieces in ``bench_common.py``); each prints a table and writes
JSON (``--json PATH``, otherwise to stdout).

``material`` times energy, stress and projected tangent of Neo-Hookean with the C2 extension on
random 3D deformation gradients, numba (:class:`dolfinx_invertible.Material`) against the
independent NumPy reference (:mod:`dolfinx_invertible.numpy_reference`). JSON goes to stdout, a
short table to stderr. Speeds are only reported if both implementations agree on a subsample.

Everything runs on one thread. The question is how much a compiled per-point kernel gains over
vectorised NumPy per core; NumPy's batched SVD and eigen-decompositions run one small LAPACK call
per matrix on a single thread anyway, so letting numba (or BLAS) use more threads would measure
the core count rather than the code, and on a shared small machine it mostly adds noise.
"""

from __future__ import annotations

import os
import sys

# Thread pools (numba's, OpenMP's, OpenBLAS's) size themselves once, when their library is loaded,
# from these variables; setting them later has no effect. They therefore have to be in the
# environment before numpy and numba are imported.
_THREAD_VARIABLES = {
    "NUMBA_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}


def _threads_pinned() -> bool:
    return all(os.environ.get(name) == value for name, value in _THREAD_VARIABLES.items())


# Run as a script and nothing numerical loaded yet: pinning here is early enough. Otherwise (the
# package's __init__ usually imports numpy and numba before this module runs) main() restarts the
# interpreter with the variables set.
if __name__ == "__main__" and not ({"numpy", "numba"} & set(sys.modules)):
    os.environ.update(_THREAD_VARIABLES)
_PINNED_BEFORE_IMPORT = _threads_pinned()

import argparse  # noqa: E402
import gc  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from typing import Callable, Dict, List, Sequence  # noqa: E402

import numpy as np  # noqa: E402

from dolfinx_invertible import numpy_reference  # noqa: E402

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


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _machine_info() -> dict:
    import numba

    return {
        "cpu_model": _cpu_model(),
        "logical_cpus": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "threads": 1,
        "numba_threads": numba.get_num_threads(),
        "thread_environment": {name: os.environ.get(name) for name in _THREAD_VARIABLES},
    }


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

    implementations: Dict[str, Dict[str, Callable[[np.ndarray], np.ndarray]]] = {
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
    report["machine"] = _machine_info()
    if not agreement_ok:
        return report

    timings: Dict[str, Dict[str, List[float]]] = {
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


def _material_command(arguments: argparse.Namespace) -> int:
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
    if arguments.json:
        with open(arguments.json, "w", encoding="utf-8") as file:
            file.write(json.dumps(report, indent=2) + "\n")
    else:
        print(json.dumps(report, indent=2))
    _print_material_table(report)
    return 0


def _add_material_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--points", type=int, default=1_000_000, help="number of F (default 1e6)")
    parser.add_argument("--repeats", type=int, default=5, help="timed repeats (default 5)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--json", help="write the JSON report here (default: stdout)")


def _module_subcommand(module_name: str):
    """Argument setup and command of a benchmark module, imported on first use.

    The modules import DOLFINx only inside their functions, which the material benchmark does
    not need; importing them to build the parser is cheap.
    """
    import importlib

    def module():
        return importlib.import_module(f"dolfinx_invertible.{module_name}")

    return (
        lambda parser: module().add_arguments(parser),
        lambda arguments: module().command(arguments),
    )


# name -> (help, argument setup, command)
SUBCOMMANDS = {
    "material": (
        "Neo-Hookean + C2 material kernels: numba vs NumPy reference",
        _add_material_arguments,
        _material_command,
    ),
    "assembly": (
        "residual, tangent and Newton step: our kernels vs FFCx's UFL Neo-Hookean and a zero "
        "kernel",
        *_module_subcommand("bench_assembly"),
    ),
    "solve": (
        "time to solution on Cook's membrane: UFL Neo-Hookean vs our kernels, same solver",
        *_module_subcommand("bench_solve"),
    ),
    "scaling": (
        "MPI speed-up of assembly and a Newton step, mpirun -n 1 vs -n 2",
        *_module_subcommand("bench_scaling"),
    ),
    "compile": (
        "cold and warm kernel compilation, and concurrent ranks on an empty numba cache",
        *_module_subcommand("bench_compile"),
    ),
    "memory": (
        "peak resident memory of building and one Newton step of a large P1 problem",
        *_module_subcommand("bench_memory"),
    ),
    "points": (
        "per-point cost of each kernel stage (SVD, extension, stress, tangent): the profile",
        *_module_subcommand("bench_points"),
    ),
}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m dolfinx_invertible.bench", description=__doc__.split("\n\n")[0]
    )
    subparsers = parser.add_subparsers(dest="subcommand", required=True)
    for name, (help_text, add_arguments, command) in SUBCOMMANDS.items():
        subparser = subparsers.add_parser(name, help=help_text, description=help_text)
        add_arguments(subparser)
        subparser.set_defaults(command=command)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run a benchmark subcommand; returns the process exit code.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments after the program name, e.g. ``["material", "--points", "1000"]``; defaults to
        ``sys.argv[1:]``.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    arguments = _parser().parse_args(argv)
    if getattr(arguments, "points", 1) < 1 or getattr(arguments, "repeats", 1) < 1:
        print("--points and --repeats must be at least 1", file=sys.stderr)
        return 2
    if not _PINNED_BEFORE_IMPORT:
        # numpy/numba were loaded before the thread variables were set; only a fresh interpreter
        # picks them up.
        os.environ.update(_THREAD_VARIABLES)
        sys.stdout.flush()
        sys.stderr.flush()
        os.execv(sys.executable, [sys.executable, "-m", "dolfinx_invertible.bench", *argv])
    return arguments.command(arguments)


if __name__ == "__main__":
    sys.exit(main())
