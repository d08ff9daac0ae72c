"""README example: a cantilever under a UFL tip traction (kept identical to the README)."""

# mpi4py before dolfinx: the PyPI DOLFINx wheel loads its MPI library through mpi4py.
from mpi4py import MPI

import dolfinx
import numpy as np
import ufl

from dolfinx_invertible import (
    C2,
    HyperelasticProblem,
    Material,
    NeoHookean,
    ResultWriter,
    cell_diagnostics,
    lame,
    solve_load_steps,
    summary,
    vector_function_space,
)

# Your mesh, space, boundary conditions and load terms, as in any DOLFINx script.
mesh = dolfinx.mesh.create_box(MPI.COMM_WORLD, [[0, 0, 0], [1, 0.2, 0.2]], [20, 4, 4])
# The same call on every supported DOLFINx (VectorFunctionSpace became functionspace in 0.7).
V = vector_function_space(mesh, 1)
u = dolfinx.fem.Function(V, name="displacement")
clamped = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 0.0))
bc = dolfinx.fem.dirichletbc(np.zeros(3), dolfinx.fem.locate_dofs_topological(V, 2, clamped), V)
tip = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 1.0))
tags = dolfinx.mesh.meshtags(mesh, 2, tip, np.full(len(tip), 1, dtype=np.int32))
ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags)
traction = dolfinx.fem.Constant(mesh, np.zeros(3))

# The material, and the problem: elastic kernels + your UFL potential in one PETSc system.
mu, lam = lame(E=1.0e4, nu=0.45)
material = Material(NeoHookean(mu=mu, lam=lam), extension=C2(eps=0.9))
problem = HyperelasticProblem(
    u,
    material,
    bcs=[bc],
    external_energy=-ufl.dot(traction, u) * ds(1),
    petsc_options={"snes_rtol": 1e-8},  # any SNES/KSP/PC option; prefix dolfinx_invertible_
)

with ResultWriter("output/cantilever.xdmf", mesh) as writer:  # + output/cantilever.jsonl

    def set_load(t):  # pseudo-time t in (0, 1]
        traction.value[:] = (0.0, 0.0, -40.0 * t)

    def write(t, result):
        diagnostics = cell_diagnostics(u, material)
        record = summary(diagnostics, mesh.comm)
        record.update(
            energy=result.energy,
            newton=result.newton_iterations,
            ksp=result.linear_iterations,
            svd_share=result.svd_share,  # share of points that needed the SVD, per kernel
        )
        writer.write(t, u, diagnostics, record)

    solve_load_steps(problem, set_load, steps=4, on_step=write)

if mesh.comm.rank == 0:
    print("steps written:", writer.steps_written)
