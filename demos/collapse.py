"""A cube collapsed to a point, or with scattered vertices, recovers its shape (paper Fig. 5).

Two scenes, each at rest and unsupported:

* ``point``: every vertex of a unit cube at 5 % of its distance from the centre (F = 0.05 I,
  0.0125 % of the rest volume);
* ``scatter``: every vertex moved to a pseudo-random point of a box of a quarter of the size
  (about half of the elements start inverted).

Backward Euler with the C2-extended Neo-Hookean model lets the cube spring back to its rest
shape; the IFE stress extension runs on the same scenes for comparison. Runs under MPI:

    mpirun -n 2 .venv/bin/python demos/collapse.py [--cells 4] [--nu 0.45] [--steps 40]

Writes ``output/collapse/<scene>_<extension>.xdmf`` (displacement and per-cell diagnostics for
ParaView) and ``output/collapse/<scene>_<extension>.jsonl`` (one line per step: time, energy,
Newton and KSP iterations, inverted cells, wall time), and prints a summary table. Exits
non-zero if a C2 run does not recover (no inverted cells and min J > 0.95 at the end).
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

# mpi4py before dolfinx: the PyPI DOLFINx wheel loads its MPI library through mpi4py.
from mpi4py import MPI

import dolfinx
import numpy as np

from dolfinx_invertible import (
    C2,
    IFE,
    ImplicitDynamics,
    Material,
    NeoHookean,
    ResultWriter,
    SolverError,
    cell_diagnostics,
    lame,
    summary,
    vector_function_space,
)

OUTPUT = pathlib.Path(__file__).resolve().parent.parent / "output" / "collapse"


def _pseudo_random(x, seed: float) -> np.ndarray:
    # A hash of the coordinates: the same scatter whatever the mesh partition.
    value = np.sin(x[0] * 127.1 + x[1] * 311.7 + x[2] * 74.7 + seed) * 43758.5453
    return value - np.floor(value)


def initial_displacement(scene: str, scale: float):
    if scene == "point":
        return lambda x: -(1.0 - scale) * (x - 0.5)
    return lambda x: np.stack(
        [0.5 + 0.25 * (_pseudo_random(x, seed) - 0.5) - x[i] for i, seed in enumerate((0, 1, 2))]
    )


def run(scene, extension, arguments, comm) -> dict:
    mesh = dolfinx.mesh.create_unit_cube(comm, arguments.cells, arguments.cells, arguments.cells)
    u = dolfinx.fem.Function(vector_function_space(mesh, 1))
    u.interpolate(initial_displacement(scene, arguments.scale))
    mu, lam = lame(arguments.youngs_modulus, arguments.nu)
    material = Material(NeoHookean(mu=mu, lam=lam), extension)
    dynamics = ImplicitDynamics(
        u,
        material,
        density=arguments.density,
        dt=arguments.dt,
        petsc_options={"snes_rtol": 1e-6, "snes_max_it": 200},
    )
    name = f"{scene}_{type(extension).__name__}"
    started = time.perf_counter()
    totals = {"newton": 0, "linear": 0}
    outcome = "recovered"
    with ResultWriter(OUTPUT / f"{name}.xdmf", mesh) as writer:

        def write(t, result=None):
            diagnostics = cell_diagnostics(u, material)
            record = summary(diagnostics, comm)
            if result is not None:
                totals["newton"] += result.newton_iterations
                totals["linear"] += result.linear_iterations
                record.update(
                    energy=result.energy,
                    newton_iterations=result.newton_iterations,
                    linear_iterations=result.linear_iterations,
                    svd_share=result.svd_share,
                )
            record["kinetic_energy"] = dynamics.kinetic_energy
            record["wall_time"] = time.perf_counter() - started
            writer.write(t, u, diagnostics, record)
            return record

        first = write(0.0)
        try:
            dynamics.advance(arguments.steps * arguments.dt, on_step=write)
        except SolverError as error:
            outcome = f"failed: {error}"
        final = write(dynamics.time + 1e-9 * arguments.dt) if outcome != "recovered" else None
    final = summary(cell_diagnostics(u, material), comm)
    if outcome == "recovered" and not (final["inverted_cells"] == 0 and final["min_J"] > 0.95):
        outcome = "did not recover"
    return {
        "scene": scene,
        "extension": type(extension).__name__,
        "initial_inverted": first["inverted_cells"],
        "initial_min_J": first["min_J"],
        "final_inverted": final["inverted_cells"],
        "final_min_J": final["min_J"],
        "time": dynamics.time,
        "newton": totals["newton"],
        "linear": totals["linear"],
        "wall": time.perf_counter() - started,
        "outcome": outcome,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cells", type=int, default=4, help="cells per edge (default 4)")
    parser.add_argument("--nu", type=float, default=0.45, help="Poisson ratio (default 0.45)")
    parser.add_argument("--youngs-modulus", type=float, default=1.0e3)
    parser.add_argument("--density", type=float, default=1.0)
    parser.add_argument("--dt", type=float, default=0.01)
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--scale", type=float, default=0.05, help="initial F = scale * I")
    arguments = parser.parse_args()
    comm = MPI.COMM_WORLD
    OUTPUT.mkdir(parents=True, exist_ok=True)
    results = [
        run(scene, extension, arguments, comm)
        for scene in ("point", "scatter")
        for extension in (C2(0.9), IFE(0.9))
    ]
    if comm.rank == 0:
        print(
            f"unit cube, {arguments.cells}^3 x 6 tetrahedra, nu = {arguments.nu}, "
            f"point scene F0 = {arguments.scale} I, dt = {arguments.dt}, {comm.size} rank(s)"
        )
        print(
            "scene    extension  inverted t=0 -> end   min J t=0 -> end    Newton    KSP  "
            "wall [s]  outcome"
        )
        for r in results:
            print(
                f"{r['scene']:8s} {r['extension']:9s}  {r['initial_inverted']:6d} -> "
                f"{r['final_inverted']:<6d}"
                f"  {r['initial_min_J']:8.2e} -> {r['final_min_J']:6.4f}"
                f"  {r['newton']:6d} {r['linear']:6d} {r['wall']:9.1f}  {r['outcome']}"
            )
        print("wrote", *sorted(str(path) for path in OUTPUT.iterdir()))
    c2_recovered = all(r["outcome"] == "recovered" for r in results if r["extension"] == "C2")
    return 0 if c2_recovered else 1


if __name__ == "__main__":
    sys.exit(main())
