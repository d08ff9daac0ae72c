# ---
# jupyter:
#   jupytext:
#     formats: py:light
#     text_representation:
#       extension: .py
#       format_name: light
# ---

# # Porting the FEniCSx hyperelasticity tutorial
#
# The FEniCSx tutorial's cantilever (J. S. Dokken, "Hyperelasticity"): a 20 × 1 × 1 beam,
# clamped at x = 0, under a dead-load traction T = (0, 0, −1.5 n) on its end x = 20 for
# n = 1, …, 9, compressible Neo-Hookean with E = 10 kPa, ν = 0.3, quadrature degree 4, solved
# by DOLFINx's `NewtonSolver` (atol = rtol = 1e-8, incremental criterion). The script solves it
# three ways and prints the Newton iterations per load step:
#
# - **dolfinx**: the tutorial itself, the Neo-Hookean energy in UFL, plain Newton with LU;
# - **drop-in**: the same script with the elastic energy's lines (ψ, P) replaced by one
#   `Material` line, F reduced to the loads, and this package's
#   `NewtonSolverNonlinearProblem` (with `material=`) in place of DOLFINx's problem class;
#   DOLFINx's `NewtonSolver` drives it and takes the same iterates (on DOLFINx up to 0.9,
#   `dolfinx_invertible.NonlinearProblem` is the same class, named like DOLFINx's);
# - **minimiser**: this package's `HyperelasticProblem` with its defaults (energy line search
#   with the full step taken when it is good, scale-invariant stopping tests, direct solve at
#   this size), in the tutorial's own load loop.
#
# Run it (`--mesh` picks one of the three meshes; all three by default):
#
#     .venv/bin/python demos/port_tutorial.py --mesh p1-hexahedron
#
# Each mesh takes up to a minute or two serially.

# +
import argparse
import time

# mpi4py before dolfinx: the PyPI DOLFINx wheel loads its MPI library through mpi4py.
from mpi4py import MPI

import dolfinx
import dolfinx.fem.petsc
import dolfinx.nls.petsc
import numpy as np
import ufl

from dolfinx_invertible import (
    HyperelasticProblem,
    Material,
    NeoHookean,
    NewtonSolverNonlinearProblem,
    lame,
    vector_function_space,
)

LENGTH = 20.0
E, NU = 1.0e4, 0.3
LOADS = [-1.5 * n for n in range(1, 10)]
QUADRATURE = 4
MESHES = {  # name: (cell type, degree)
    "p1-hexahedron": (dolfinx.mesh.CellType.hexahedron, 1),
    "q2-hexahedron": (dolfinx.mesh.CellType.hexahedron, 2),
    "p2-tetrahedron": (dolfinx.mesh.CellType.tetrahedron, 2),
}
# DOLFINx 0.10 renamed the problem class its NewtonSolver solves.
DolfinxNewtonProblem = getattr(
    dolfinx.fem.petsc, "NewtonSolverNonlinearProblem", dolfinx.fem.petsc.NonlinearProblem
)
# -

# The tutorial's set-up: mesh, space, clamped end, traction on the other end.


# +
def tutorial(cell_type, degree):
    mesh = dolfinx.mesh.create_box(
        MPI.COMM_WORLD, [[0.0, 0.0, 0.0], [LENGTH, 1.0, 1.0]], [20, 5, 5], cell_type
    )
    V = vector_function_space(mesh, degree)
    u = dolfinx.fem.Function(V)
    left = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 0.0))
    right = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], LENGTH))
    tags = dolfinx.mesh.meshtags(mesh, 2, right, np.full(len(right), 2, dtype=np.int32))
    bc = dolfinx.fem.dirichletbc(np.zeros(3), dolfinx.fem.locate_dofs_topological(V, 2, left), V)
    T = dolfinx.fem.Constant(mesh, np.zeros(3))
    metadata = {"quadrature_degree": QUADRATURE}
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags, metadata=metadata)
    dx = ufl.Measure("dx", domain=mesh, metadata=metadata)
    return mesh, u, bc, T, ds, dx


def tutorial_newton(problem, comm):
    solver = dolfinx.nls.petsc.NewtonSolver(comm, problem)
    solver.atol = solver.rtol = 1e-8
    solver.convergence_criterion = "incremental"
    ksp = solver.krylov_solver
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    return solver


def load_loop(solve, T):
    """The tutorial's loop: set the traction, solve, record the iterations."""
    iterations = []
    for value in LOADS:
        T.value[2] = value
        iterations.append(solve())
    return iterations


# -

# ## The tutorial as it is, and the two lines that change for the drop-in


# +
def run_dolfinx(cell_type, degree):
    mesh, u, bc, T, ds, dx = tutorial(cell_type, degree)
    v = ufl.TestFunction(u.function_space)
    I = ufl.Identity(3)
    F_ = ufl.variable(I + ufl.grad(u))
    C = F_.T * F_
    J = ufl.det(F_)
    mu, lmbda = (dolfinx.fem.Constant(mesh, value) for value in lame(E, NU))
    psi = (mu / 2) * (ufl.tr(C) - 3) - mu * ufl.ln(J) + (lmbda / 2) * ufl.ln(J) ** 2
    P = ufl.diff(psi, F_)
    F = ufl.inner(ufl.grad(v), P) * dx - ufl.inner(v, T) * ds(2)
    problem = DolfinxNewtonProblem(F, u, [bc])
    solver = tutorial_newton(problem, mesh.comm)
    return u, load_loop(lambda: _converged(*solver.solve(u)), T)


def run_drop_in(cell_type, degree):
    mesh, u, bc, T, ds, dx = tutorial(cell_type, degree)
    v = ufl.TestFunction(u.function_space)
    mu, lmbda = (dolfinx.fem.Constant(mesh, value) for value in lame(E, NU))
    material = Material(NeoHookean(mu=mu, lam=lmbda))  # changed: the elastic term
    F = -ufl.inner(v, T) * ds(2)  # changed: F holds the loads only
    problem = NewtonSolverNonlinearProblem(
        F, u, [bc], material=material, quadrature_degree=QUADRATURE
    )  # changed: this package's class, material=
    solver = tutorial_newton(problem, mesh.comm)
    return u, load_loop(lambda: _converged(*solver.solve(u)), T)


def run_minimiser(cell_type, degree):
    mesh, u, bc, T, ds, dx = tutorial(cell_type, degree)
    mu, lmbda = lame(E, NU)
    problem = HyperelasticProblem(
        u,
        Material(NeoHookean(mu=mu, lam=lmbda)),
        [bc],
        external_energy=-ufl.inner(T, u) * ds(2),
        quadrature_degree=QUADRATURE,
    )

    def solve():
        result = problem.solve()
        if not result.converged:
            raise RuntimeError(result.describe())
        return result.newton_iterations

    return u, load_loop(solve, T)


def _converged(iterations, converged):
    if not converged:
        raise RuntimeError("DOLFINx's NewtonSolver did not converge")
    return iterations


# -

# ## Run and compare: iterations per load step and the tip displacement


# +
def tip_deflection(u):
    """Mean z-displacement of the end x = L."""
    mesh = u.function_space.mesh
    V = u.function_space
    dofs = dolfinx.fem.locate_dofs_geometrical(V, lambda x: np.isclose(x[0], LENGTH))
    owned = dofs[dofs < V.dofmap.index_map.size_local]
    values = u.x.array.reshape(-1, 3)[owned, 2]
    total = mesh.comm.allreduce(values.sum(), op=MPI.SUM)
    count = mesh.comm.allreduce(len(values), op=MPI.SUM)
    return total / count


def compare(name):
    cell_type, degree = MESHES[name]
    rows = {}
    for route, run in (("dolfinx", run_dolfinx), ("drop-in", run_drop_in),
                       ("minimiser", run_minimiser)):  # fmt: skip
        start = time.perf_counter()
        u, iterations = run(cell_type, degree)
        rows[route] = (iterations, tip_deflection(u), time.perf_counter() - start)
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--mesh", choices=list(MESHES), action="append")
    arguments = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    results = {}
    for name in arguments.mesh or list(MESHES):
        results[name] = rows = compare(name)
        if comm.rank == 0:
            print(f"{name}: Newton iterations per load step, total, tip u_z, wall time")
            for route, (iterations, tip, wall) in rows.items():
                print(f"  {route:<10} {' '.join(f'{i:2d}' for i in iterations)}  "
                      f"total {sum(iterations):3d}  u_z {tip:.6f}  {wall:6.1f} s")  # fmt: skip
    return results


if __name__ == "__main__":
    main()
# -
