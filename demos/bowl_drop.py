"""A soft cube dropped into a bowl: it falls, hits the bottom, rocks and settles.

A cube of side 0.4 centred at the origin, at rest, inside the bowl |x| ≤ 1 (the inside of the
unit sphere about the origin), falls under gravity (0, 0, −9.81) m/s²; Neo-Hookean with the C2
extension, backward Euler, frictionless contact through the IPC barrier with continuous
collision detection on every Newton step. Prints the smallest gap over the run and the number
of penetrations (boundary vertices found inside the bowl after any accepted step, or at any
Newton iterate): both counts must be 0, and the script exits non-zero otherwise.

    .venv/bin/python demos/bowl_drop.py
    mpirun -n 2 .venv/bin/python demos/bowl_drop.py
"""

from __future__ import annotations

import dataclasses
import sys
import time

# mpi4py before dolfinx: the PyPI DOLFINx wheel loads its MPI library through mpi4py.
from mpi4py import MPI

import dolfinx
import numpy as np

from dolfinx_invertible import (
    C2,
    ImplicitDynamics,
    Material,
    NeoHookean,
    lame,
    vector_function_space,
)
from dolfinx_invertible.contact import ContactTerm, Sphere

SIDE = 0.4  # m
CELLS = 4  # per side: 4³ × 6 tetrahedra
YOUNGS_MODULUS, POISSON = 5.0e4, 0.4  # Pa: a soft gel
DENSITY = 1000.0  # kg/m³
GRAVITY = (0.0, 0.0, -9.81)  # m/s²
DT = 0.01  # s
END_TIME = 2.0  # s
DAMPING = 1.0  # 1/s, mass proportional: lets the rocking die out within the run


@dataclasses.dataclass
class BowlDrop:
    """The pieces of the scene, for reuse: the body, the obstacles and the contact."""

    mesh: dolfinx.mesh.Mesh
    u: dolfinx.fem.Function
    material: Material
    obstacles: list
    term: ContactTerm
    step_limit: object


def setup(comm: MPI.Comm = MPI.COMM_WORLD, cells: int = CELLS) -> BowlDrop:
    """Return the cube at rest in the bowl, with its contact term and collision-free step."""
    half = 0.5 * SIDE
    mesh = dolfinx.mesh.create_box(comm, [[-half] * 3, [half] * 3], [cells] * 3)
    u = dolfinx.fem.Function(vector_function_space(mesh, 1), name="displacement")
    mu, lam = lame(E=YOUNGS_MODULUS, nu=POISSON)
    material = Material(NeoHookean(mu=mu, lam=lam), extension=C2(eps=0.9))
    obstacles = [Sphere((0.0, 0.0, 0.0), 1.0, inside=True)]
    term = ContactTerm(u, obstacles, material)
    return BowlDrop(mesh, u, material, obstacles, term, term.step_limit())


def run(scene: BowlDrop, end_time: float = END_TIME, dt: float = DT) -> dict:
    """Drop the cube and return the run's figures (over all ranks)."""
    term = scene.term

    def move_obstacles(t):
        term.set_time(t)
        term.separate()  # a no-op for this fixed bowl; needed once obstacles move

    dynamics = ImplicitDynamics(
        scene.u,
        scene.material,
        density=DENSITY,
        dt=dt,
        gravity=GRAVITY,
        damping=DAMPING,
        terms=[term],
        step_limits=[scene.step_limit],
        boundary_update=move_obstacles,
    )
    figures = {
        "steps": 0,
        "newton_iterations": 0,
        "minimum_gap": term.minimum_gap(),
        "penetrations": 0,
        "iterate_penetrations": 0,
        "iterates": 0,
        "peak_kinetic_energy": 0.0,
    }

    def monitor(snes, iteration, norm):
        dynamics.problem.energy_problem.update_solution(snes.getSolution())
        figures["iterates"] += 1
        figures["iterate_penetrations"] += term.penetrations()
        figures["minimum_gap"] = min(figures["minimum_gap"], term.minimum_gap())

    dynamics.problem.solver.snes.setMonitor(monitor)
    start = time.perf_counter()

    def on_step(t, result):
        figures["steps"] += 1
        figures["newton_iterations"] += result.newton_iterations
        figures["penetrations"] += term.penetrations()
        figures["minimum_gap"] = min(figures["minimum_gap"], term.minimum_gap())
        kinetic = dynamics.kinetic_energy
        figures["peak_kinetic_energy"] = max(figures["peak_kinetic_energy"], kinetic)
        # Collective calls on every rank, printing on one.
        gap, touching = term.minimum_gap(), term.active_vertices()
        if scene.mesh.comm.rank == 0 and figures["steps"] % 20 == 0:
            print(
                f"t = {t:5.2f} s  Newton {result.newton_iterations:3d}  "
                f"min gap {gap:.2e} m  in contact {touching:3d}  kinetic {kinetic:.2e} J",
                flush=True,
            )

    dynamics.advance(end_time, on_step)
    figures["wall_time"] = time.perf_counter() - start
    figures["kinetic_energy"] = dynamics.kinetic_energy
    figures["cuts"] = dynamics.controller.cuts
    figures["contact_force"] = term.contact_force().tolist()
    figures["weight"] = DENSITY * SIDE**3 * abs(GRAVITY[2])
    lowest = term.comm.allreduce(float(np.min(term.positions()[:, 2])), op=MPI.MIN)
    figures["lowest_point"] = lowest
    return figures


def main() -> int:
    """Run the scene and print its figures; non-zero exit on any penetration."""
    comm = MPI.COMM_WORLD
    scene = setup(comm)
    barrier = scene.term.barrier
    if comm.rank == 0:
        print(
            f"cube {SIDE} m, {CELLS}³ × 6 tetrahedra on {comm.size} rank(s); barrier "
            f"d̂ = {barrier.distance:.3e} m, κ = {barrier.stiffness:.3e}",
            flush=True,
        )
    figures = run(scene)
    if comm.rank == 0:
        force = figures["contact_force"]
        print(
            f"{figures['steps']} steps ({figures['cuts']} cuts), "
            f"{figures['newton_iterations']} Newton iterations, "
            f"wall {figures['wall_time']:.1f} s\n"
            f"smallest gap over the run {figures['minimum_gap']:.3e} m; penetrations after "
            f"accepted steps {figures['penetrations']}, at Newton iterates "
            f"{figures['iterate_penetrations']} (of {figures['iterates']})\n"
            f"end: kinetic energy {figures['kinetic_energy']:.2e} J "
            f"(peak {figures['peak_kinetic_energy']:.2e} J), lowest point "
            f"z = {figures['lowest_point']:.4f} m, bowl force {force[2]:.1f} N "
            f"vs weight {figures['weight']:.1f} N",
            flush=True,
        )
    return 0 if figures["penetrations"] == 0 and figures["iterate_penetrations"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
