"""Time the contact between surfaces on a large mesh: the surface's gather and the term's work.

``BodyContactTerm`` (IPC Toolkit) needs the whole surface on every rank: gathered once when
the term is built, and the owned surface vertices' positions gathered at every evaluation. On
two cubes of ``--resolution`` cells a side (6 n³ tetrahedra each) stacked with a gap of a tenth
of the barrier distance, so that the barrier acts over a whole face, this times (median of
``--repeat``, the slowest rank): the term's construction, one gather of the positions, and one
evaluation of the energy, the gradient, the Hessian's assembly and the CCD step cap, with the
elastic assembly of the same mesh as the baseline measured in the same run. Run from the
repository root, serially or under MPI::

    python -m benchmarks.body_contact --resolution 30            # 2 × 162 000 tetrahedra
    mpirun -n 2 python -m benchmarks.body_contact --resolution 30
"""

import argparse
import time

from mpi4py import MPI

import dolfinx
import dolfinx.fem
import numpy as np
import ufl

from dolfinx_invertible import _compat
from dolfinx_invertible.contact import BodyContactTerm
from dolfinx_invertible.meshes.blocks import cubes_mesh


def _median_time(comm, action, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        comm.barrier()
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return comm.allreduce(float(np.median(times)), op=MPI.MAX)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=int, default=30, help="cells per edge of a cube")
    parser.add_argument("--repeat", type=int, default=5, help="repetitions to time")
    arguments = parser.parse_args()
    comm = MPI.COMM_WORLD
    n = arguments.resolution
    spacing_guess = 1.0 / n
    centres = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0 + 0.01 * spacing_guess]])
    mesh = cubes_mesh(comm, centres, 1.0, n)
    space = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(space)

    comm.barrier()
    start = time.perf_counter()
    term = BodyContactTerm(u, youngs_modulus=1.0)
    built = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)

    gather = _median_time(comm, term.positions, arguments.repeat)
    # Every evaluation at a new state: forget the collision set of the last one.
    energy = _median_time(comm, lambda: (_forget(term), term.energy()), arguments.repeat)
    residual = np.zeros_like(u.x.array)
    gradient = _median_time(comm, lambda: (_forget(term), term.add_residual(residual)),
                            arguments.repeat)  # fmt: skip
    mass = dolfinx.fem.form(ufl.inner(ufl.TrialFunction(space), ufl.TestFunction(space)) * ufl.dx)
    matrix = _compat.create_matrix(mass)

    def hessian():
        _forget(term)
        matrix.zeroEntries()
        term.add_tangent(matrix, np.zeros(0, dtype=np.int32))
        matrix.assemble()

    tangent = _median_time(comm, hessian, arguments.repeat)
    direction = _compat.petsc_vector(u)
    direction.array[2::3] = -1e-3
    cap = _median_time(comm, lambda: term.step_limit().largest_step(direction), arguments.repeat)
    elastic = _median_time(
        comm,
        lambda: (matrix.zeroEntries(), _compat.assemble_matrix_into(matrix, mass, [], 1.0)),
        arguments.repeat,
    )
    pairs = term.active_pairs()
    if comm.rank == 0:
        cells = mesh.topology.index_map(3).size_global
        unknowns = space.dofmap.index_map.size_global * 3
        print(
            f"ranks {comm.size}  cells {cells}  unknowns {unknowns}  surface vertices "
            f"{len(term.surface)}  pairs within d̂ {pairs}\n"
            f"  build {built:.3f} s  gather {gather * 1e3:.2f} ms  energy {energy:.3f} s  "
            f"gradient {gradient:.3f} s  Hessian {tangent:.3f} s  CCD {cap:.3f} s\n"
            f"  baseline: a mass matrix's assembly on the same mesh {elastic:.3f} s"
        )


def _forget(term) -> None:
    term._collisions_at = None


if __name__ == "__main__":
    main()
