"""Time a run's checkpoint: write and read the four fields of implicit dynamics on a box.

The checkpoint of a dynamic scene (``dolfinx_invertible.scenes.checkpoints``) holds the
displacement and velocity of the current and the previous step, P1 on the mesh, and a small
JSON state; this writes exactly those four fields with
``dolfinx_invertible.io.checkpoint.write_checkpoint`` five times (median and smallest time),
reads them back once, and times each rank's part written after every step
(``write_checkpoint_part``, not synced; the slowest rank). Run from the repository root,
serially or under MPI::

    python -m benchmarks.checkpoint --resolution 26            # 105 456 tetrahedra
    mpirun -n 2 python -m benchmarks.checkpoint --resolution 26
"""

import argparse
import tempfile
import time
from pathlib import Path

from mpi4py import MPI

import dolfinx
import numpy as np

from dolfinx_invertible import vector_function_space
from dolfinx_invertible.io.checkpoint import (
    owned_nodes,
    read_checkpoint,
    write_checkpoint,
    write_checkpoint_part,
)

FIELDS = ("displacement", "velocity", "older_displacement", "older_velocity")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=int, default=26, help="cells per edge of the cube")
    parser.add_argument("--repeat", type=int, default=5, help="writes to time")
    arguments = parser.parse_args()
    comm = MPI.COMM_WORLD
    n = arguments.resolution
    mesh = dolfinx.mesh.create_box(comm, [[0.0] * 3, [1.0] * 3], [n, n, n])
    space = vector_function_space(mesh, 1)
    random = np.random.default_rng(comm.rank)
    fields = {}
    for name in FIELDS:
        fields[name] = dolfinx.fem.Function(space)
        fields[name].x.array[:] = random.random(fields[name].x.array.shape)
    folder = comm.bcast(tempfile.mkdtemp() if comm.rank == 0 else None, root=0)
    path = Path(folder) / "checkpoint.npz"
    times = []
    for _ in range(arguments.repeat):
        comm.barrier()
        start = time.perf_counter()
        size = write_checkpoint(path, fields, {"time": 0.1}, comm)
        comm.barrier()
        times.append(time.perf_counter() - start)
    comm.barrier()
    start = time.perf_counter()
    read_checkpoint(path, fields, comm)
    comm.barrier()
    read = time.perf_counter() - start
    part = Path(folder) / f"part-{comm.rank}.npz"
    part_times = []
    # As a run's step parts: the node coordinates tabulated once, the values every step.
    nodes = {name: owned_nodes(function) for name, function in fields.items()}
    for _ in range(arguments.repeat):
        start = time.perf_counter()
        write_checkpoint_part(part, nodes, {"time": 0.1}, sync=False)
        part_times.append(time.perf_counter() - start)
    part_time = comm.allreduce(float(np.median(part_times)), op=MPI.MAX)
    comm.barrier()
    part.unlink()
    if comm.rank == 0:
        cells = mesh.topology.index_map(3).size_global
        unknowns = space.dofmap.index_map.size_global * space.dofmap.index_map_bs
        print(
            f"ranks {comm.size}  cells {cells}  unknowns {unknowns}  write median "
            f"{np.median(times):.3f} s (min {min(times):.3f} s)  read {read:.3f} s  "
            f"size {size / 1e6:.2f} MB  part per step {part_time:.3f} s"
        )
        path.unlink()
        Path(folder).rmdir()


if __name__ == "__main__":
    main()
