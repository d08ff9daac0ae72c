"""Pieces shared by the DOLFINx benchmarks (assembly, solve, scaling, compile, memory).

The benchmark cases on a unit cube of tetrahedra:

(a) ``a_ufl``: UFL Neo-Hookean compiled by FFCx;
(b) ``b_fast``: our Neo-Hookean + C2 at a state where no point is near the threshold (J ≈ 1.03);
(r) ``b_random``: the same near rest with random noise (J ≈ 1 ± 0.04, stresses of both signs):
    many exact tangents are indefinite in their rotational modes, which the projection clamps;
(c) ``c_svd``: our Neo-Hookean + C2 at a state where every point is inside the extension
    (J ≈ 0.86), so every point goes through the SVD and the C2 Taylor expansion;
(d) ``d_zero``: a kernel that writes nothing (DOLFINx's gathering and insertion floor).

Every case comes with a Dirichlet condition on the face x = 0 that holds the state's own values
there, so imposing it (as a Newton step does) leaves the state, and hence the case, unchanged.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import resource
import signal
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from benchmarks import command_line
from benchmarks.threads import THREAD_VARIABLES

CASES = ("a_ufl", "b_fast", "b_random", "c_svd", "d_zero")
# Uniform stretch of the benchmark states: 1.01 keeps every point on the fast path (J ≈ 1.03),
# 0.95 puts every point below J = 0.9, inside the C2 extension.
STRETCH = {"a_ufl": 1.01, "b_fast": 1.01, "b_random": 1.0, "c_svd": 0.95, "d_zero": 1.01}
# Amplitude of the random displacement of ``b_random`` per unit of cell size h = 1/cells
# (J ≈ 1 ± 0.04 at any mesh size).
RANDOM_AMPLITUDE = 0.012
YOUNGS_MODULUS = 1.0e3
POISSON_RATIO = 0.3
C2_EPS = 0.9

# What a benchmark child process needs: one thread per rank, and OpenMPI's consent to run as
# root on the machines this project runs on.
CHILD_ENVIRONMENT = {
    **THREAD_VARIABLES,
    "OMPI_ALLOW_RUN_AS_ROOT": "1",
    "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
}


@dataclasses.dataclass
class Case:
    """One benchmark case: the state ``u`` and the compiled forms of its potential."""

    name: str
    u: Any
    energy: list
    residual: list
    jacobian: list
    bcs: list
    keep_alive: tuple = ()  # objects the compiled forms point into


def _zero_kernel(A_, w_, c_, coordinates_, entity_local_index, permutation):
    """Write nothing: what is left is DOLFINx's gathering and insertion."""


def _zero_kernel_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
    """As :func:`_zero_kernel`, for DOLFINx's kernel signature with ``custom_data``."""


def unit_cube_space(comm, cells: int, degree: int):
    """Vector Lagrange space of degree ``degree`` on the unit cube of cells³ × 6 tetrahedra."""
    import dolfinx

    from dolfinx_invertible import _compat

    mesh = dolfinx.mesh.create_unit_cube(comm, cells, cells, cells)
    return _compat.vector_function_space(mesh, degree)


def material():
    """Return the benchmark material: Neo-Hookean + C2, and its Lamé parameters."""
    from dolfinx_invertible import C2, Material, NeoHookean, lame

    mu, lam = lame(YOUNGS_MODULUS, POISSON_RATIO)
    return Material(NeoHookean(mu=mu, lam=lam), C2(C2_EPS)), mu, lam


def _pseudo_random(x, seed: float) -> np.ndarray:
    # A hash of the coordinates in [0, 1): the same on any mesh partition.
    value = np.sin(x[0] * 127.1 + x[1] * 311.7 + x[2] * 74.7 + seed) * 43758.5453
    return value - np.floor(value)


def state(space, stretch: float, random: bool = False):
    """Return a displacement with uniform stretch plus a small smooth perturbation.

    ``random``: instead of the smooth perturbation, pseudo-random noise of amplitude
    :data:`RANDOM_AMPLITUDE` · h at every node (h = 1/cells of the unit cube).
    """
    import dolfinx

    u = dolfinx.fem.Function(space)
    if random:
        cells = round(space.mesh.topology.index_map(3).size_global / 6) ** (1.0 / 3.0)
        amplitude = RANDOM_AMPLITUDE / max(1.0, round(cells))
        u.interpolate(
            lambda x: (
                (stretch - 1.0) * x
                + amplitude * np.stack([_pseudo_random(x, seed) - 0.5 for seed in (0.0, 1.0, 2.0)])
            )
        )
    else:
        u.interpolate(lambda x: (stretch - 1.0) * x + 0.01 * np.sin(3.0 * x[::-1]))
    u.x.scatter_forward()
    return u


def clamp_to_state(u) -> Any:
    """Dirichlet condition on x = 0 holding ``u``'s own values there."""
    import dolfinx

    space = u.function_space
    mesh = space.mesh
    facets = dolfinx.mesh.locate_entities_boundary(
        mesh, mesh.topology.dim - 1, lambda x: np.isclose(x[0], 0.0)
    )
    dofs = dolfinx.fem.locate_dofs_topological(space, mesh.topology.dim - 1, facets)
    values = dolfinx.fem.Function(space)
    values.x.array[:] = u.x.array
    return dolfinx.fem.dirichletbc(values, dofs)


def ufl_neo_hookean_energy(u, mu: float, lam: float, quadrature_degree: int):
    """Return the UFL Neo-Hookean energy ∫ μ/2 (tr C − 3) − μ ln J + λ/2 (ln J)² dX."""
    import ufl

    gradient = ufl.Identity(len(u)) + ufl.grad(u)
    log_volume = ufl.ln(ufl.det(gradient))
    psi = (
        mu / 2 * (ufl.tr(gradient.T * gradient) - len(u))
        - mu * log_volume
        + lam / 2 * log_volume**2
    )
    return psi * ufl.dx(metadata={"quadrature_degree": quadrature_degree})


def ufl_forms(energy, u) -> tuple[Any, Any, Any]:
    """Compiled energy, residual and tangent of a UFL potential in ``u``."""
    import dolfinx
    import ufl

    residual = ufl.derivative(energy, u)
    return (
        dolfinx.fem.form(energy),
        dolfinx.fem.form(residual),
        dolfinx.fem.form(ufl.derivative(residual, u)),
    )


def build_case(name: str, space, project: bool = True) -> Case:
    """Forms and state of one benchmark case (see the module docstring) on ``space``.

    ``project`` chooses the SPD-projected (default, as the assembly benchmark has always
    measured) or the exact tangent of our kernels.
    """
    from dolfinx_invertible import HyperelasticForms, _compat
    from dolfinx_invertible.fem.forms import default_quadrature_degree
    from dolfinx_invertible.fem.kernels import compile_kernel

    if name not in CASES:
        raise ValueError(f"unknown case {name!r}; expected one of {CASES}")
    degree = _compat.element_degree(space)
    quadrature_degree = default_quadrature_degree(degree, space.mesh.topology.cell_type)
    elastic, mu, lam = material()
    u = state(space, STRETCH[name], random=name == "b_random")
    bcs = [clamp_to_state(u)]
    if name == "a_ufl":
        energy, residual, jacobian = ufl_forms(
            ufl_neo_hookean_energy(u, mu, lam, quadrature_degree), u
        )
        return Case(name, u, [energy], [residual], [jacobian], bcs)
    forms = HyperelasticForms(u, elastic, quadrature_degree=quadrature_degree, project=project)
    if name in ("b_fast", "b_random", "c_svd"):
        return Case(name, u, [forms.energy], [forms.residual], [forms.jacobian], bcs, (forms,))
    zero_kernel = compile_kernel((_zero_kernel, _zero_kernel_with_data))
    mesh = space.mesh
    residual, jacobian = (
        _compat.custom_form(spaces, zero_kernel.address, [u], [forms.constants], mesh)
        for spaces in ([space], [space, space])
    )
    return Case(name, u, [], [residual], [jacobian], bcs, (forms, zero_kernel))


def extension_share(name: str) -> float:
    """Share of points inside the C2 extension for a case's uniform stretch (0 or 1)."""
    elastic, _, _ = material()
    return float(np.count_nonzero(elastic.regions(np.eye(3) * STRETCH[name])))


def seconds(function: Callable[[], object], comm=None) -> float:
    """Wall time of one call; under MPI the slowest rank's, started together."""
    if comm is not None:
        comm.Barrier()
    start = time.perf_counter()
    function()
    elapsed = time.perf_counter() - start
    if comm is not None and comm.size > 1:
        from mpi4py import MPI

        elapsed = comm.allreduce(elapsed, op=MPI.MAX)
    return elapsed


def interleaved(jobs: dict[tuple[str, str], Callable[[], object]], repeats: int, comm=None) -> dict:
    """Seconds per repeat of each job ``(case, operation)``, interleaved so noise hits all alike.

    Every repeat runs the operations in turn (in the order first given), each over all cases,
    and the cases' order rotates by one per repeat. So a job follows a job of its own kind: a
    Newton step sets up a solver of tens of MB, which evicts from the caches what the next
    assembly then reads from memory again, and in plain case order every case's assembly but
    the first case's would follow one. Which case opens a repeat, after the last job of the
    previous one, rotates. The order is the same on every rank.
    """
    samples: dict[tuple[str, str], list[float]] = {key: [] for key in jobs}
    cases = list(dict.fromkeys(case for case, _ in jobs))
    operations = list(dict.fromkeys(operation for _, operation in jobs))
    for repeat in range(repeats):
        shift = repeat % len(cases)
        for operation in operations:
            for case in cases[shift:] + cases[:shift]:
                if (case, operation) in jobs:
                    samples[case, operation].append(seconds(jobs[case, operation], comm))
    return samples


def medians(samples: dict) -> dict:
    """Median of each list in a (possibly nested) dict of lists."""
    return {
        key: medians(value) if isinstance(value, dict) else statistics.median(value)
        for key, value in samples.items()
    }


def peak_rss_bytes() -> int:
    """Peak resident set size of this process so far (Linux reports ru_maxrss in KiB)."""
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    import platform

    return platform.processor() or "unknown"


def machine() -> dict:
    """Load average, CPU, versions and thread settings, for the record."""
    import platform

    import numba

    info: dict[str, Any] = {
        "load_average": list(os.getloadavg()),
        "cpu_model": _cpu_model(),
        "logical_cpus": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "numba_threads": numba.get_num_threads(),
        "thread_environment": {name: os.environ.get(name) for name in THREAD_VARIABLES},
    }
    try:
        import dolfinx

        info["dolfinx"] = dolfinx.__version__
    except ImportError:
        pass
    return info


def record_load_after(report: dict) -> None:
    """Add the load average now to ``report["machine"]`` (after the measurements)."""
    report["machine"]["load_average_after"] = list(os.getloadavg())


def load_text(report: dict) -> str:
    """Return "load average X before, Y after" of a report, for its table heading."""
    machine_info = report["machine"]
    return (
        f"load average {machine_info['load_average'][0]:.2f} before, "
        f"{machine_info['load_average_after'][0]:.2f} after"
    )


def rows_table(benchmark: str, report: dict, header: str, row_text) -> str:
    """Return a report of rows as a table: a heading with the load, ``header``, one line a row."""
    lines = [f"{benchmark} benchmark, {load_text(report)}", header]
    lines += [row_text(row) for row in report["rows"]]
    return "\n".join(lines)


def child_environment(**extra: str) -> dict:
    """Return the current environment plus :data:`CHILD_ENVIRONMENT` and ``extra``."""
    environment = dict(os.environ)
    environment.update(CHILD_ENVIRONMENT)
    environment.update(extra)
    return environment


def bench_command(subcommand: str, arguments: Sequence[str], ranks: int | None) -> list[str]:
    """Command line running ``python -m dolfinx_invertible bench subcommand ...``.

    ``ranks`` None runs it as a plain process, otherwise under ``mpirun -n ranks``. The process
    runs :func:`benchmarks.command_line`.
    """
    command = command_line([subcommand, *arguments])
    if ranks is None:
        return command
    return ["mpirun", "-n", str(ranks), *command]


def run_child(command: Sequence[str], environment: dict, timeout: float) -> float:
    """Run a benchmark child to completion; returns its wall time, raises with its output.

    The child runs in a process group of its own, and a child that outlives ``timeout`` loses
    the whole group: killing ``mpirun`` alone leaves its ranks running, which would then share
    the machine with every later row. Raises :class:`ChildTimeoutError` then.
    """
    start = time.perf_counter()
    process = subprocess.Popen(
        list(command),
        env=environment,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        stdout, stderr = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        _end_group(process)
        stdout, stderr = process.communicate()
        raise ChildTimeoutError(
            f"{' '.join(command)} did not finish within {timeout:g} s:\n"
            f"{stdout[-3000:]}\n{stderr[-3000:]}"
        ) from None
    except BaseException:
        _end_group(process)
        raise
    elapsed = time.perf_counter() - start
    if process.returncode != 0:
        raise RuntimeError(
            f"{' '.join(command)} exited with {process.returncode}:\n"
            f"{stdout[-3000:]}\n{stderr[-3000:]}"
        )
    return elapsed


class ChildTimeoutError(RuntimeError):
    """A benchmark child did not finish within its time limit (its processes are ended)."""


def _end_group(process: subprocess.Popen, grace: float = 10.0) -> None:
    """End the process group of ``process``: SIGTERM, and SIGKILL to what is left after it."""
    for sent in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(process.pid, sent)
        except ProcessLookupError:  # nothing left in the group
            return
        with contextlib.suppress(subprocess.TimeoutExpired):
            process.wait(timeout=grace)


def emit(report: dict, table: str, json_path: str | None) -> None:
    """Write the JSON report to ``json_path`` (table on stdout) or to stdout (table on stderr).

    Either way stdout stays machine-readable when no path is given.
    """
    text = json.dumps(report, indent=2)
    if json_path:
        with open(json_path, "w", encoding="utf-8") as file:
            file.write(text + "\n")
        print(table, flush=True)
    else:
        print(text, flush=True)
        print(table, file=sys.stderr, flush=True)


def ratio_text(value: float | None) -> str:
    """Return a ratio for a table, or a dash where it is undefined."""
    return "—" if value is None else f"{value:.2f}"
