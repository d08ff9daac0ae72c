"""Assembly benchmark: our kernels against FFCx's UFL Neo-Hookean and a zero kernel.

``python -m dolfinx_invertible bench assembly [--cells 20] [--repeats 7]`` times, on one mesh in
one process with interleaved repeats (medians reported):

(a) UFL Neo-Hookean compiled by FFCx;
(b) our Neo-Hookean + C2 at a state where no point is near the threshold (J ≈ 1.03);
(c) our Neo-Hookean + C2 at a state where every point is in the extension (J ≈ 0.86), so every
    point goes through the SVD and the C2 Taylor expansion;
(d) a kernel that writes nothing (DOLFINx's insertion floor).

for residual and tangent assembly, on P1 tetrahedra (cells³ × 6) and on P2 tetrahedra with about
the same number of dofs, and prints JSON plus the ratios b/a, c/a, c/d.
"""

from __future__ import annotations

import argparse
import functools
import json
import statistics
import time

import numpy as np


def _zero_kernel(A_, w_, c_, coordinates_, entity_local_index, permutation):
    """Writes nothing: what is left is DOLFINx's gathering and insertion."""


def _zero_kernel_with_data(A_, w_, c_, coordinates_, entity_local_index, permutation, data):
    """As :func:`_zero_kernel`, for DOLFINx's kernel signature with ``custom_data``."""


def _cases(cells: int, degree: int):
    import dolfinx
    import dolfinx.fem.petsc
    import ufl
    from mpi4py import MPI

    from dolfinx_invertible import C2, HyperelasticForms, Material, NeoHookean, _compat, lame
    from dolfinx_invertible.kernels import compile_kernel

    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, cells, cells, cells)
    V = _compat.vector_function_space(mesh, "Lagrange", degree)
    mu, lam = lame(1.0e3, 0.3)
    quadrature_degree = max(1, 2 * (degree - 1))

    def state(stretch):
        u = dolfinx.fem.Function(V)
        u.interpolate(lambda x: (stretch - 1.0) * x + 0.01 * np.sin(3.0 * x[::-1]))
        u.x.scatter_forward()
        return u

    material = Material(NeoHookean(mu=mu, lam=lam), C2(0.9))
    forms = {}
    u_fast = state(1.01)
    F = ufl.Identity(3) + ufl.grad(u_fast)
    J = ufl.det(F)
    psi = mu / 2 * (ufl.tr(F.T * F) - 3) - mu * ufl.ln(J) + lam / 2 * ufl.ln(J) ** 2
    energy = psi * ufl.dx(metadata={"quadrature_degree": quadrature_degree})
    residual = ufl.derivative(energy, u_fast)
    forms["a_ufl"] = (
        dolfinx.fem.form(residual),
        dolfinx.fem.form(ufl.derivative(residual, u_fast)),
    )
    fast = HyperelasticForms(u_fast, material, quadrature_degree)
    forms["b_fast"] = (fast.residual, fast.jacobian)
    u_svd = state(0.95)
    svd = HyperelasticForms(u_svd, material, quadrature_degree)
    forms["c_svd"] = (svd.residual, svd.jacobian)
    zero_kernel = compile_kernel((_zero_kernel, _zero_kernel_with_data))
    zero = [
        _compat.custom_form(spaces, zero_kernel.address, [u_fast], [fast.constants], mesh)
        for spaces in ([V], [V, V])
    ]
    forms["d_zero"] = tuple(zero)
    regions = {
        name: int(np.count_nonzero(material.regions(np.eye(3) * stretch)))
        for name, stretch in (("b_fast", 1.01), ("c_svd", 0.95))
    }
    dofs = V.dofmap.index_map.size_global * V.dofmap.index_map_bs
    cells_total = mesh.topology.index_map(3).size_global
    return forms, dofs, cells_total, regions, (svd, fast)


def _time(function) -> float:
    start = time.perf_counter()
    function()
    return time.perf_counter() - start


def _assemble_residual(vector, form) -> None:
    import dolfinx.fem.petsc

    with vector.localForm() as local:
        local.set(0.0)
    dolfinx.fem.petsc.assemble_vector(vector, form)


def _assemble_tangent(matrix, form) -> None:
    import dolfinx.fem.petsc

    matrix.zeroEntries()
    dolfinx.fem.petsc.assemble_matrix(matrix, form)
    matrix.assemble()


def _interleaved_samples(forms: dict, repeats: int) -> dict:
    """Seconds per repeat for each case; cases interleaved so machine noise hits all alike."""
    import dolfinx.fem.petsc

    jobs = {}
    for name, (residual, jacobian) in forms.items():
        vector = dolfinx.fem.petsc.create_vector(residual)
        matrix = dolfinx.fem.petsc.create_matrix(jacobian)
        jobs[name] = {
            "residual": functools.partial(_assemble_residual, vector, residual),
            "tangent": functools.partial(_assemble_tangent, matrix, jacobian),
        }
        for job in jobs[name].values():  # warm-up: JIT, caches, sparsity
            job()
    samples = {name: {kind: [] for kind in kinds} for name, kinds in jobs.items()}
    for _ in range(repeats):
        for name, kinds in jobs.items():
            for kind, job in kinds.items():
                samples[name][kind].append(_time(job))
    return samples


def run(cells: int, repeats: int) -> dict:
    report = {"benchmark": "assembly", "repeats": repeats, "meshes": {}}
    for degree, mesh_cells in ((1, cells), (2, max(1, cells // 2))):
        forms, dofs, cells_total, regions, keep_alive = _cases(mesh_cells, degree)
        samples = _interleaved_samples(forms, repeats)
        medians = {
            name: {kind: statistics.median(values) for kind, values in kinds.items()}
            for name, kinds in samples.items()
        }
        ratios = {}
        for kind in ("residual", "tangent"):
            ratios[kind] = {
                "b/a": medians["b_fast"][kind] / medians["a_ufl"][kind],
                "c/a": medians["c_svd"][kind] / medians["a_ufl"][kind],
                "c/d": medians["c_svd"][kind] / medians["d_zero"][kind],
            }
        report["meshes"][f"P{degree}"] = {
            "cells": cells_total,
            "dofs": dofs,
            "quadrature_degree": max(1, 2 * (degree - 1)),
            "extension_active_in": regions,
            "median_seconds": medians,
            "ratios": ratios,
        }
        del keep_alive
    return report


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--cells", type=int, default=20, help="P1 cells per edge (default 20)")
    parser.add_argument("--repeats", type=int, default=7, help="timed repeats (default 7)")


def command(arguments: argparse.Namespace) -> int:
    report = run(arguments.cells, arguments.repeats)
    print(json.dumps(report, indent=2))
    for name, mesh in report["meshes"].items():
        print(f"{name}: {mesh['cells']} cells, {mesh['dofs']} dofs", flush=True)
        for kind, ratios in mesh["ratios"].items():
            seconds = ", ".join(
                f"{case} {mesh['median_seconds'][case][kind]:.4f} s"
                for case in mesh["median_seconds"]
            )
            shown = ", ".join(f"{key} = {value:.2f}" for key, value in ratios.items())
            print(f"  {kind:8s} {seconds}; {shown}")
    return 0
