"""Per-point cost of each stage of the kernels: where the time of a cell kernel goes.

``python -m dolfinx_invertible bench points [--points 48000] [--repeats 7]`` times, for
Neo-Hookean + C2 (ε = 0.9) in 3D, the point functions the DOLFINx cell kernels call, on F =
s·I + 0.01·N(0, 1) (s = 1.01: no point near the threshold, stresses tensile; s = 1.00: near rest,
stresses of both signs, so about two thirds of the exact tangents have negative twist
stiffnesses to project; s = 0.95: every point inside the extension):

- the SVD alone;
- the principal-space derivatives of order 0, 1, 2 (after the SVD);
- the whole point energy, stress and tangent (projected and exact) as the kernels call them.

This is the profile behind the assembly ratios: it says which stage bounds a kernel. Times are
CPU time of the timing thread (``time.thread_time``), which other load on a shared machine
inflates far less than wall time.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from benchmarks import common
from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.compiled import python_callable
from dolfinx_invertible.constitutive.pointwise import point_energy, point_stress, point_tangent
from dolfinx_invertible.constitutive.principal import principal_derivatives
from dolfinx_invertible.constitutive.svd import polar_svd_point
from dolfinx_invertible.constitutive.svd_path import svd_path_address

STRETCHES = {
    "fast path (s = 1.01)": 1.01,
    "near rest (s = 1.00)": 1.0,
    "inside the extension (s = 0.95)": 0.95,
}


@python_callable
def _svd_stage(F):
    work = ws.new_workspace(ws.stack_buffer())
    checksum = 0.0
    for n in range(F.shape[0]):
        sigma = ws.vector(work, ws.SIGMA, 3)
        polar_svd_point(F[n], 3, ws.matrix(work, ws.U, 3), sigma, ws.matrix(work, ws.V, 3))
        checksum += sigma[0]
    return checksum


_STAGE_FUNCTIONS: dict = {}


# The ids are captured integers, literals inside the compiled closures as in the kernels (a
# Python int argument would be retyped on every call).
def _stage_functions(model_id: int, extension_id: int):
    key = (model_id, extension_id)
    if key in _STAGE_FUNCTIONS:
        return _STAGE_FUNCTIONS[key]

    def principal_stage(F, params, order):
        work = ws.new_workspace(ws.stack_buffer())
        checksum = 0.0
        for n in range(F.shape[0]):
            sigma = ws.vector(work, ws.SIGMA, 3)
            polar_svd_point(F[n], 3, ws.matrix(work, ws.U, 3), sigma, ws.matrix(work, ws.V, 3))
            psi, _ = principal_derivatives(
                model_id, extension_id, False, sigma, 3, params, order, work
            )
            checksum += psi
        return checksum

    def point_stage(F, params, svd_path, kind, project):
        work = ws.new_workspace(ws.stack_buffer())
        P = np.empty((3, 3))
        C = np.empty((9, 9))
        checksum = 0.0
        svd_points = 0
        for n in range(F.shape[0]):
            if kind == 0:
                psi, _, through_svd = point_energy(
                    F[n], 3, model_id, extension_id, False, params, svd_path, work
                )
            elif kind == 1:
                psi, _, through_svd = point_stress(
                    F[n], 3, model_id, extension_id, False, params, svd_path, work, P
                )
            else:
                psi, _, through_svd = point_tangent(
                    F[n], 3, model_id, extension_id, False, params, project, svd_path, work, P, C
                )
            checksum += psi
            svd_points += through_svd
        return checksum, svd_points

    functions = (python_callable(principal_stage), python_callable(point_stage))
    _STAGE_FUNCTIONS[key] = functions
    return functions


def _stages(F: np.ndarray, material) -> dict:
    principal_stage, point_stage = _stage_functions(material.model.model_id, material.extension_id)
    params = material.parameters
    svd_path = svd_path_address(material.model.model_id, material.extension_id, 3)
    # Orders as arrays' elements: run-time integers, as the kernels pass them.
    orders = np.arange(3)
    return {
        "SVD": lambda: _svd_stage(F),
        "SVD + principal energy": lambda: principal_stage(F, params, orders[0]),
        "SVD + principal gradient": lambda: principal_stage(F, params, orders[1]),
        "SVD + principal Hessian": lambda: principal_stage(F, params, orders[2]),
        "point energy": lambda: point_stage(F, params, svd_path, 0, False),
        "point stress": lambda: point_stage(F, params, svd_path, 1, False),
        "point tangent, exact": lambda: point_stage(F, params, svd_path, 2, False),
        "point tangent, projected": lambda: point_stage(F, params, svd_path, 2, True),
    }


def run(points: int, repeats: int) -> dict:
    """Nanoseconds per point of every stage in both states (medians of interleaved repeats)."""
    from dolfinx_invertible import C2, Material, NeoHookean, lame

    mu, lam = lame(1.0e3, 0.3)
    material = Material(NeoHookean(mu=mu, lam=lam), C2(0.9))
    generator = np.random.default_rng(7)
    report = {"points": points, "repeats": repeats, "machine": common.machine()}
    results = {}
    for state, stretch in STRETCHES.items():
        F = stretch * np.eye(3) + 0.01 * generator.standard_normal((points, 3, 3))
        stages = _stages(F, material)
        shares = {}
        for name, stage in stages.items():
            outcome = stage()  # compile, or load from the cache
            if isinstance(outcome, tuple):
                shares[name] = outcome[1] / points
        samples = {name: [] for name in stages}
        for _ in range(repeats):
            for name, stage in stages.items():
                start = time.thread_time()
                stage()
                samples[name].append(time.thread_time() - start)
        results[state] = {
            name: {
                "nanoseconds_per_point": 1e9 * statistics.median(values) / points,
                "svd_share": shares.get(name),
            }
            for name, values in samples.items()
        }
    report["stages"] = results
    common.record_load_after(report)
    return report


def table(report: dict) -> str:
    """Human-readable table of :func:`run`'s report."""
    states = list(report["stages"])
    lines = [
        f"per-point stages, Neo-Hookean + C2 (eps 0.9), 3D, {report['points']} points, medians "
        f"of {report['repeats']} interleaved repeats, "
        f"{common.load_text(report)}",
        f"{'stage':28s}" + "".join(f"{state:>34s}" for state in states),
    ]
    for name in report["stages"][states[0]]:
        cells = []
        for state in states:
            entry = report["stages"][state][name]
            share = entry["svd_share"]
            note = "" if share is None else f" (SVD {100 * share:.0f} %)"
            cells.append(f"{entry['nanoseconds_per_point']:.0f} ns{note}".rjust(34))
        lines.append(f"{name:28s}" + "".join(cells))
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``bench points``."""
    parser.add_argument("--points", type=int, default=48000, help="points (default 48000)")
    parser.add_argument("--repeats", type=int, default=7, help="timed repeats (default 7)")
    parser.add_argument("--json", help="write the JSON report here (default: stdout)")


def command(arguments: argparse.Namespace) -> int:
    """Run ``bench points``."""
    report = run(arguments.points, arguments.repeats)
    common.emit(report, table(report), arguments.json)
    return 0
