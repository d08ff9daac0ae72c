"""Time-to-solution benchmark: UFL Neo-Hookean against our kernels through the same solver.

``python -m dolfinx_invertible bench solve [--cells 16] [--thickness-cells 4] [--steps 4]
[--repeats 3] [--json PATH]`` solves Cook's membrane in 3D, an uninverted quasi-static scene:
the tapered panel with corners (0, 0), (48, 44), (48, 60), (0, 44), 10 thick, clamped at x = 0
and sheared by a uniform vertical traction on the face x = 48, P1 tetrahedra (cells × cells ×
thickness-cells hexahedra, 6 tetrahedra each; the quick defaults give 4 335 dofs, the full size
``--cells 32 --thickness-cells 8`` 29 403 dofs), in equal load steps, twice:

(i) UFL Neo-Hookean compiled by FFCx,
(ii) our Neo-Hookean + C2 kernels (exact tangent, as the UFL route has),

each through :class:`~dolfinx_invertible.solvers.problem.EnergyProblem`,
:class:`~dolfinx_invertible.solvers.minimizer.EnergyMinimizer` (default options) and
:func:`~dolfinx_invertible.solvers.stepping.solve_load_steps`, with the same traction potential
as a UFL form. Every form is compiled and assembled once before timing; the two routes
alternate over the repeats and the medians are reported, with Newton and Krylov iterations,
the ratio ours / UFL, and the relative difference of the two displacements (they solve the
same equations to snes_rtol 1e-9, so they must agree closely).

The inverted scene (``--scene inverted``; ``all``, the default, runs both) tracks time to
solution with the extension active: a unit cube of ``--inverted-cells``³ × 6 P1 tetrahedra whose
vertices start scattered pseudo-randomly (a hash of the coordinates, the same on any partition)
into the centred box of a quarter of its size, so that about half the cells are inverted, Neo-
Hookean + C2 (ε = 0.9, E = 1e3, ν = 0.45, ρ = 1), released at rest and integrated by backward
Euler (:class:`~dolfinx_invertible.solvers.dynamics.ImplicitDynamics`, dt = 0.01, projected
tangent) for ``--inverted-steps`` steps. Only our kernels can run it (UFL's Neo-Hookean is
undefined there): the report has the median wall time, Newton and Krylov iterations and the
share of quadrature-point evaluations per kernel that went through the SVD
(``SolveResult.svd_share``, averaged over the steps).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from benchmarks import common

# Cook's membrane (mm): the classical plane geometry, extruded.
LENGTH, LEFT_HEIGHT, RIGHT_BOTTOM, RIGHT_TOP, THICKNESS = 48.0, 44.0, 44.0, 60.0, 10.0
YOUNGS_MODULUS, POISSON_RATIO = 1.0e3, 0.4
# Shear traction on the loaded face at full load (per unit reference area): tip deflection of
# about a fifth of the length, large strains but no inversion.
TRACTION = 16.0
AGREEMENT_TOLERANCE = 1.0e-6


def cook_mesh(comm, cells: int, thickness_cells: int):
    """Return the 3D Cook's membrane as a mapped box of tetrahedra."""
    import dolfinx

    mesh = dolfinx.mesh.create_box(
        comm,
        [np.zeros(3), np.ones(3)],
        [cells, cells, thickness_cells],
        dolfinx.mesh.CellType.tetrahedron,
    )
    x = mesh.geometry.x
    xi, eta, zeta = x[:, 0].copy(), x[:, 1].copy(), x[:, 2].copy()
    bottom = RIGHT_BOTTOM * xi
    top = LEFT_HEIGHT + (RIGHT_TOP - LEFT_HEIGHT) * xi
    x[:, 0] = LENGTH * xi
    x[:, 1] = bottom + eta * (top - bottom)
    x[:, 2] = THICKNESS * zeta
    return mesh


class Route:
    """One way of solving Cook's membrane: its own displacement, forms, problem and solver."""

    def __init__(self, name: str, space, load, traction_potential_of, elastic_forms_of) -> None:
        import dolfinx

        from dolfinx_invertible.solvers import EnergyMinimizer, EnergyProblem, external_forms

        self.name = name
        self.u = dolfinx.fem.Function(space)
        self.load = load
        energy, residual, jacobian, keep_alive = elastic_forms_of(self.u)
        extra_energy, extra_residual, _ = external_forms(self.u, traction_potential_of(self.u))
        self.keep_alive = keep_alive
        self.problem = EnergyProblem(
            self.u,
            [energy, extra_energy],
            [residual, extra_residual],
            [jacobian],
            [clamp(space)],
        )
        self.solver = EnergyMinimizer(self.problem)

    def warm_up(self) -> None:
        """Assemble everything once: first-use costs stay out of the timings."""
        vector = self.problem.create_vector()
        matrix = self.problem.create_matrix()
        x = vector.copy()
        self.problem.F(None, x, vector)
        self.problem.J(None, x, matrix, matrix)
        self.problem.total_energy()
        self.u.x.array[:] = 0.0

    def solve(self, steps: int) -> dict:
        """Solve from u = 0 in ``steps`` load steps; wall time and iteration counts."""
        from dolfinx_invertible.solvers import solve_load_steps

        self.u.x.array[:] = 0.0
        self.load.value = 0.0
        comm = self.u.function_space.mesh.comm
        comm.Barrier()
        start = time.perf_counter()
        results = solve_load_steps(self.solver, self._set_load, steps)
        elapsed = time.perf_counter() - start
        return {
            "seconds": elapsed,
            "load_steps": len(results),
            "newton_iterations": sum(result.newton_iterations for result in results),
            "krylov_iterations": sum(result.linear_iterations for result in results),
        }

    def _set_load(self, pseudo_time: float) -> None:
        self.load.value = pseudo_time


def clamp(space):
    """Zero displacement on the face x = 0."""
    import dolfinx

    mesh = space.mesh
    facets = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 0.0))
    dofs = dolfinx.fem.locate_dofs_topological(space, 2, facets)
    return dolfinx.fem.dirichletbc(np.zeros(3), dofs, space)


INVERTED_YOUNGS_MODULUS, INVERTED_POISSON_RATIO, INVERTED_DT = 1.0e3, 0.45, 0.01


def _pseudo_random(x, seed: float) -> np.ndarray:
    # A hash of the coordinates: the same scatter whatever the mesh partition.
    value = np.sin(x[0] * 127.1 + x[1] * 311.7 + x[2] * 74.7 + seed) * 43758.5453
    return value - np.floor(value)


def _scatter(x) -> np.ndarray:
    """Displacement moving every vertex to a pseudo-random point of [0.375, 0.625]³."""
    return np.stack(
        [0.5 + 0.25 * (_pseudo_random(x, seed) - 0.5) - x[i] for i, seed in enumerate((0, 1, 2))]
    )


def run_inverted(cells: int, steps: int, repeats: int) -> dict:
    """Time the inverted scene ``repeats`` times after one untimed warm-up step."""
    from mpi4py import MPI

    import dolfinx

    from dolfinx_invertible import C2, ImplicitDynamics, Material, NeoHookean, _compat, lame

    comm = MPI.COMM_WORLD
    mesh = dolfinx.mesh.create_unit_cube(comm, cells, cells, cells)
    space = _compat.vector_function_space(mesh, 1)
    mu, lam = lame(INVERTED_YOUNGS_MODULUS, INVERTED_POISSON_RATIO)
    material = Material(NeoHookean(mu=mu, lam=lam), C2(common.C2_EPS))

    def dynamics_from_scatter():
        u = dolfinx.fem.Function(space)
        u.interpolate(_scatter)
        u.x.scatter_forward()
        dynamics = ImplicitDynamics(
            u,
            material,
            density=1.0,
            dt=INVERTED_DT,
            petsc_options={"snes_rtol": 1e-6, "snes_max_it": 200},
        )
        return u, dynamics

    _, warm = dynamics_from_scatter()
    warm.advance(INVERTED_DT)
    samples = []
    for _ in range(repeats):
        u, dynamics = dynamics_from_scatter()
        comm.Barrier()
        start = time.perf_counter()
        results = dynamics.advance(steps * INVERTED_DT)
        elapsed = time.perf_counter() - start
        elapsed = comm.allreduce(elapsed, op=MPI.MAX)
        shares: dict[str, list[float]] = {}
        for result in results:
            for kind, share in result.svd_share.items():
                if share is not None:
                    shares.setdefault(kind, []).append(share)
        inverted = _inverted_cells(u, material)
        samples.append(
            {
                "seconds": elapsed,
                "time_steps": len(results),
                "newton_iterations": sum(result.newton_iterations for result in results),
                "krylov_iterations": sum(result.linear_iterations for result in results),
                "svd_share": {kind: float(np.mean(values)) for kind, values in shares.items()},
                "inverted_cells_at_end": inverted,
            }
        )
    last = samples[-1]
    return {
        "scene": "unit cube scattered into [0.375, 0.625]^3, Neo-Hookean + C2, backward Euler",
        "cells": mesh.topology.index_map(3).size_global,
        "dofs": space.dofmap.index_map.size_global * space.dofmap.index_map_bs,
        "initial_inverted_cells": _inverted_cells(dynamics_from_scatter()[0], material),
        "time_steps": steps,
        "dt": INVERTED_DT,
        "repeats": repeats,
        "median_seconds": statistics.median(sample["seconds"] for sample in samples),
        "all_seconds": [sample["seconds"] for sample in samples],
        "newton_iterations": last["newton_iterations"],
        "krylov_iterations": last["krylov_iterations"],
        "svd_share": last["svd_share"],
        "inverted_cells_at_end": last["inverted_cells_at_end"],
    }


def _inverted_cells(u, material) -> int:
    """Cells with det F ≤ 0 at a quadrature point, summed over ranks."""
    from dolfinx_invertible import cell_diagnostics, summary

    return summary(cell_diagnostics(u, material), u.function_space.mesh.comm)["inverted_cells"]


def run(cells: int, thickness_cells: int, steps: int, repeats: int) -> dict:
    """Solve Cook's membrane by both routes, ``repeats`` times each (interleaved).

    Returns
    -------
    dict
        JSON-ready report: per route the median wall time, all times, Newton and Krylov
        iterations; the ratio ours / UFL; the relative displacement difference and whether it is
        within :data:`AGREEMENT_TOLERANCE`.
    """
    from mpi4py import MPI

    import dolfinx
    import ufl

    from dolfinx_invertible import C2, HyperelasticForms, Material, NeoHookean, _compat, lame
    from dolfinx_invertible.fem.forms import default_quadrature_degree

    comm = MPI.COMM_WORLD
    machine = common.machine()
    mesh = cook_mesh(comm, cells, thickness_cells)
    space = _compat.vector_function_space(mesh, 1)
    quadrature_degree = default_quadrature_degree(1, "tetrahedron")
    mu, lam = lame(YOUNGS_MODULUS, POISSON_RATIO)
    material = Material(NeoHookean(mu=mu, lam=lam), C2(common.C2_EPS))
    load = dolfinx.fem.Constant(mesh, 0.0)
    loaded = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], LENGTH))
    tags = dolfinx.mesh.meshtags(mesh, 2, loaded, np.ones(len(loaded), dtype=np.int32))
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags)
    traction = ufl.as_vector((0.0, TRACTION, 0.0))

    def traction_potential(u):
        return -load * ufl.dot(traction, u) * ds(1)

    def ufl_forms(u):
        energy = common.ufl_neo_hookean_energy(u, mu, lam, quadrature_degree)
        return (*common.ufl_forms(energy, u), ())

    def our_forms(u):
        forms = HyperelasticForms(u, material, quadrature_degree=quadrature_degree, project=False)
        return forms.energy, forms.residual, forms.jacobian, (forms,)

    routes = {
        "ufl": Route("ufl", space, load, traction_potential, ufl_forms),
        "ours": Route("ours", space, load, traction_potential, our_forms),
    }
    for route in routes.values():
        route.warm_up()
    runs: dict[str, list[dict]] = {name: [] for name in routes}
    for repeat in range(repeats):
        # Alternate which route goes first so neither always runs on a warmer machine.
        order = list(routes) if repeat % 2 == 0 else list(routes)[::-1]
        for name in order:
            runs[name].append(routes[name].solve(steps))

    difference = _compat.petsc_vector(routes["ours"].u).copy()
    difference.axpy(-1.0, _compat.petsc_vector(routes["ufl"].u))
    reference_norm = _compat.petsc_vector(routes["ufl"].u).norm()
    relative_difference = difference.norm() / reference_norm
    tip = _tip_displacement(routes["ufl"].u)

    report = {
        "benchmark": "solve",
        "scene": "Cook's membrane 3D (48 x 44..60 x 10), clamped at x = 0, sheared at x = 48",
        "material": {"model": "NeoHookean", "E": YOUNGS_MODULUS, "nu": POISSON_RATIO},
        "traction": TRACTION,
        "ranks": comm.size,
        "cells": mesh.topology.index_map(3).size_global,
        "dofs": space.dofmap.index_map.size_global * space.dofmap.index_map_bs,
        "load_steps": steps,
        "repeats": repeats,
        "tip_vertical_displacement": tip,
        "routes": {},
        "machine": machine,
    }
    for name, samples in runs.items():
        report["routes"][name] = {
            "median_seconds": statistics.median(run["seconds"] for run in samples),
            "all_seconds": [run["seconds"] for run in samples],
            "newton_iterations": samples[-1]["newton_iterations"],
            "krylov_iterations": samples[-1]["krylov_iterations"],
            "load_steps_taken": samples[-1]["load_steps"],
        }
    report["ratio_ours_over_ufl"] = (
        report["routes"]["ours"]["median_seconds"] / report["routes"]["ufl"]["median_seconds"]
    )
    report["relative_displacement_difference"] = relative_difference
    report["agreement_tolerance"] = AGREEMENT_TOLERANCE
    report["agreement_ok"] = bool(relative_difference <= AGREEMENT_TOLERANCE)
    common.record_load_after(report)
    return report


def _tip_displacement(u) -> float:
    """Largest vertical displacement over all dofs (the upper right corner's, for this load)."""
    from mpi4py import MPI

    local = u.x.array.reshape(-1, 3)[:, 1]
    return u.function_space.mesh.comm.allreduce(float(local.max(initial=0.0)), op=MPI.MAX)


def table(report: dict) -> str:
    """Return the report as a human-readable table."""
    lines = [
        f"solve benchmark: {report['scene']}",
        f"{report['cells']} P1 tets, {report['dofs']} dofs, {report['load_steps']} load steps, "
        f"{report['ranks']} rank(s), tip deflection {report['tip_vertical_displacement']:.2f}, "
        f"medians of {report['repeats']}, {common.load_text(report)}",
        f"{'route':<8}{'median [s]':>12}{'all [s]':>28}{'Newton':>8}{'KSP':>8}",
    ]
    for name, route in report["routes"].items():
        all_seconds = " ".join(f"{value:.2f}" for value in route["all_seconds"])
        lines.append(
            f"{name:<8}{route['median_seconds']:>12.3f}{all_seconds:>28}"
            f"{route['newton_iterations']:>8}{route['krylov_iterations']:>8}"
        )
    verdict = "ok" if report["agreement_ok"] else "DISAGREE"
    lines.append(
        f"ours / UFL = {report['ratio_ours_over_ufl']:.2f} (target <= 1.2); relative "
        f"displacement difference {report['relative_displacement_difference']:.2e} "
        f"(<= {report['agreement_tolerance']:g}: {verdict})"
    )
    return "\n".join(lines)


def inverted_table(report: dict) -> str:
    """Return the inverted scene's report as a human-readable table."""
    shares = ", ".join(f"{kind} {100 * share:.0f} %" for kind, share in report["svd_share"].items())
    all_seconds = " ".join(f"{value:.2f}" for value in report["all_seconds"])
    return "\n".join(
        [
            f"inverted scene: {report['scene']}",
            f"{report['cells']} P1 tets, {report['dofs']} dofs, "
            f"{report['initial_inverted_cells']} cells inverted at t = 0, "
            f"{report['time_steps']} steps of dt = {report['dt']:g}, medians of "
            f"{report['repeats']}",
            f"wall time {report['median_seconds']:.3f} s ({all_seconds}), Newton "
            f"{report['newton_iterations']}, KSP {report['krylov_iterations']}, through the SVD: "
            f"{shares}; {report['inverted_cells_at_end']} cells inverted at the end",
        ]
    )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``bench solve``."""
    parser.add_argument(
        "--scene",
        choices=("all", "cook", "inverted"),
        default="all",
        help="Cook's membrane (UFL vs ours), the inverted cube (ours), or both (default)",
    )
    parser.add_argument(
        "--inverted-cells", type=int, default=4, help="inverted cube: cells per edge (default 4)"
    )
    parser.add_argument(
        "--inverted-steps", type=int, default=3, help="inverted cube: time steps (default 3)"
    )
    parser.add_argument(
        "--cells", type=int, default=16, help="cells along length and height (default 16)"
    )
    parser.add_argument(
        "--thickness-cells", type=int, default=4, help="cells through the thickness (default 4)"
    )
    parser.add_argument("--steps", type=int, default=4, help="load steps (default 4)")
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats (default 3)")
    parser.add_argument("--json", help="write the JSON report here (default: stdout)")


def command(arguments: argparse.Namespace) -> int:
    """Run ``bench solve``; exit code 1 if the two routes of Cook's membrane disagree."""
    from mpi4py import MPI

    report: dict = {"benchmark": "solve", "machine": common.machine()}
    tables = []
    agreement = True
    if arguments.scene in ("all", "cook"):
        cook = run(arguments.cells, arguments.thickness_cells, arguments.steps, arguments.repeats)
        report.update(cook)
        tables.append(table(cook))
        agreement = cook["agreement_ok"]
    if arguments.scene in ("all", "inverted"):
        inverted = run_inverted(
            arguments.inverted_cells, arguments.inverted_steps, arguments.repeats
        )
        report["inverted"] = inverted
        tables.append(inverted_table(inverted))
    common.record_load_after(report)
    if MPI.COMM_WORLD.rank == 0:
        common.emit(report, "\n".join(tables), arguments.json)
    return 0 if agreement else 1
