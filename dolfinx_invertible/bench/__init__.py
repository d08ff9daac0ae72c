"""Benchmarks, run as ``python -m dolfinx_invertible bench NAME`` (each has ``--help``).

Each benchmark module has ``add_arguments(parser)`` and ``command(arguments)``, prints a table
and writes JSON (``--json PATH``, otherwise JSON on stdout and the table on stderr). Ratios are
against a baseline measured in the same run; every report records the load average before and
after. Modules import DOLFINx only inside their functions, so listing them is cheap and the
material benchmark runs without DOLFINx.

- ``material``: the constitutive kernels, numba against the NumPy reference (:mod:`.reference`);
- ``assembly``, ``points``, ``solve``, ``scaling``, ``compile``, ``memory``: the DOLFINx side;
- :mod:`.common`: cases, timing and reporting shared by the DOLFINx benchmarks;
- :mod:`.threads`: one thread per process.
"""

#: name -> one-line description; the module of the same name implements it.
BENCHMARKS = {
    "material": "Neo-Hookean + C2 material kernels: numba vs NumPy reference",
    "assembly": "residual, tangent and Newton step: our kernels vs FFCx's UFL Neo-Hookean and a "
    "zero kernel",
    "points": "per-point cost of each kernel stage (SVD, extension, stress, tangent): the profile",
    "solve": "time to solution on Cook's membrane: UFL Neo-Hookean vs our kernels, same solver",
    "scaling": "MPI speed-up of assembly and a Newton step, mpirun -n 1 vs -n 2",
    "compile": "cold and warm kernel compilation, and concurrent ranks on an empty numba cache",
    "memory": "peak resident memory of building and one Newton step of a large P1 problem",
}

__all__ = ["BENCHMARKS"]
