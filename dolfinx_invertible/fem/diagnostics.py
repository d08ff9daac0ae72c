"""Per-cell diagnostics of a displacement field: inversion, extension regions and energy.

The deformation gradient F = I + ∇u is evaluated at the points of a quadrature rule on every
locally owned cell, and the constitutive batch API (:class:`~dolfinx_invertible.Material`)
is applied to all points at once. The results are one value per owned cell, ready to be written
as DG0 fields by :class:`~dolfinx_invertible.io.xdmf.ResultWriter`.
"""

from __future__ import annotations

from collections.abc import Mapping

from mpi4py import MPI

import basix
import dolfinx.fem
import numpy as np
import ufl

from dolfinx_invertible import _compat
from dolfinx_invertible.constitutive.material import Material, NoEnergyError
from dolfinx_invertible.constitutive.principal import UNDEFINED_REGION
from dolfinx_invertible.constitutive.svd import polar_svd
from dolfinx_invertible.fem.forms import default_quadrature_degree

__all__ = [
    "DIAGNOSTIC_NAMES",
    "ENERGY_SENTINEL",
    "cell_diagnostics",
    "summary",
]

#: Keys of the dictionary returned by :func:`cell_diagnostics`, in order.
DIAGNOSTIC_NAMES = ("min_J", "inverted", "energy_density", "min_singular_value", "region")

#: Energy density reported for a cell where the energy is +inf (a plain model with J ≤ 0).
#: XDMF readers and ParaView's colour maps cope badly with inf, so the largest finite double
#: stands in for it.
ENERGY_SENTINEL = float(np.finfo(np.float64).max)


def cell_diagnostics(
    u: dolfinx.fem.Function,
    material: Material,
    quadrature_degree: int | None = None,
) -> dict[str, np.ndarray]:
    """Diagnostics of the deformation ``x ↦ x + u(x)`` for each locally owned cell.

    Collective on the mesh communicator (the expression for F is JIT-compiled on rank 0).

    Parameters
    ----------
    u
        Displacement, a vector-valued Function with one component per dimension (2D or 3D,
        geometric dimension equal to the topological one).
    material
        The constitutive model whose energy density and regions are reported.
    quadrature_degree
        Degree of the quadrature rule (basix default rule for the cell type) whose points are
        sampled; ``None`` means the forms' default
        (:func:`~dolfinx_invertible.fem.forms.default_quadrature_degree`). The degree of the rule
        the solver assembles with gives diagnostics at exactly the points the solver sees.

    Returns
    -------
    dict of str to ndarray
        Arrays of shape (number of owned cells,), float64, indexed by local cell index:

        ``min_J``
            Smallest det F over the points.
        ``inverted``
            1.0 if det F ≤ 0 at any point, else 0.0.
        ``energy_density``
            Quadrature-weighted mean of Ψ(F) over the points (the cell average of Ψ on affine
            cells). 0.0 for a stress-only material (IFE), which has no energy; a cell where Ψ is
            +inf at some point (a plain model with J ≤ 0) gets :data:`ENERGY_SENTINEL`, the
            largest finite double, since inf does not survive XDMF viewers well.
        ``min_singular_value``
            Smallest signed singular value over the points (negative when inverted).
        ``region``
            Largest region code over the points (0 the plain model, > 0 the extension active),
            except that -1 (the plain model undefined, J ≤ 0) wins whenever it occurs at any
            point, so that a partly undefined cell never shows as the plain model.

    Raises
    ------
    ValueError
        If ``u`` is not a displacement field of the mesh dimension, the degree is negative, or
        F has non-finite entries.
    """
    mesh = u.function_space.mesh
    dimension = mesh.topology.dim
    if mesh.geometry.dim != dimension or dimension not in (2, 3):
        raise ValueError(
            "cell_diagnostics needs a 2D or 3D mesh whose geometric dimension equals its "
            f"topological one, got gdim={mesh.geometry.dim}, tdim={dimension}"
        )
    if u.ufl_shape != (dimension,):
        raise ValueError(
            f"u must be a displacement with {dimension} components, got value shape {u.ufl_shape}"
        )
    if quadrature_degree is None:
        quadrature_degree = default_quadrature_degree(
            _compat.element_degree(u.function_space), mesh.topology.cell_type
        )
    elif int(quadrature_degree) != quadrature_degree or quadrature_degree < 0:
        raise ValueError(f"quadrature_degree must be an integer >= 0, got {quadrature_degree!r}")

    cell_type = _compat.basix_element(u.function_space).cell_type
    points, weights = basix.make_quadrature(cell_type, int(quadrature_degree))
    # Built on every rank, even one without cells: the JIT compilation is collective.
    expression = dolfinx.fem.Expression(ufl.Identity(dimension) + ufl.grad(u), points)

    num_owned = mesh.topology.index_map(dimension).size_local
    num_points = len(weights)
    if num_owned == 0:
        return {name: np.zeros(0) for name in DIAGNOSTIC_NAMES}
    cells = np.arange(num_owned, dtype=np.int32)
    values = _compat.evaluate_expression(expression, mesh, cells)
    F = np.ascontiguousarray(values.reshape(num_owned * num_points, dimension, dimension))

    J = np.linalg.det(F).reshape(num_owned, num_points)
    _, sigma, _ = polar_svd(F)
    smallest_sigma = sigma[:, -1].reshape(num_owned, num_points)
    region = material.regions(F).reshape(num_owned, num_points)
    undefined = np.any(region == UNDEFINED_REGION, axis=1)

    return {
        "min_J": J.min(axis=1),
        "inverted": np.any(J <= 0.0, axis=1).astype(np.float64),
        "energy_density": _mean_energy(material, F, weights, num_owned),
        "min_singular_value": smallest_sigma.min(axis=1),
        "region": np.where(undefined, UNDEFINED_REGION, region.max(axis=1)).astype(np.float64),
    }


def _mean_energy(
    material: Material, F: np.ndarray, weights: np.ndarray, num_cells: int
) -> np.ndarray:
    try:
        energy = material.energy(F).reshape(num_cells, len(weights))
    except NoEnergyError:
        return np.zeros(num_cells)
    finite = np.isfinite(energy)
    # Zeroed first so that inf·weight never produces a warning or a NaN in the sum.
    mean = np.where(finite, energy, 0.0) @ weights / weights.sum()
    return np.where(finite.all(axis=1), mean, ENERGY_SENTINEL)


def summary(diagnostics: Mapping[str, np.ndarray], comm: MPI.Comm) -> dict[str, int | float]:
    """Global counts over all ranks of the per-cell ``diagnostics`` of :func:`cell_diagnostics`.

    Collective on ``comm``.

    Returns
    -------
    dict
        ``cells`` (total number of cells), ``inverted_cells`` (cells with a point where
        J ≤ 0), ``extended_cells`` (region > 0), ``undefined_cells`` (region -1), ``min_J`` and
        ``min_singular_value`` (global minima, +inf when there are no cells), as plain Python
        numbers, ready for a JSON log record.

    Raises
    ------
    KeyError
        If one of ``min_J``, ``inverted``, ``region`` or ``min_singular_value`` is missing.
    """
    required = ("min_J", "inverted", "region", "min_singular_value")
    missing = [name for name in required if name not in diagnostics]
    if missing:
        raise KeyError(f"summary needs the diagnostics {', '.join(missing)}")
    region = np.asarray(diagnostics["region"])
    counts = np.array(
        [
            len(region),
            np.count_nonzero(np.asarray(diagnostics["inverted"]) > 0.0),
            np.count_nonzero(region > 0.0),
            np.count_nonzero(region == UNDEFINED_REGION),
        ],
        dtype=np.int64,
    )
    minima = np.array(
        [_local_min(diagnostics["min_J"]), _local_min(diagnostics["min_singular_value"])]
    )
    global_counts = np.empty_like(counts)
    global_minima = np.empty_like(minima)
    comm.Allreduce(counts, global_counts, op=MPI.SUM)
    comm.Allreduce(minima, global_minima, op=MPI.MIN)
    return {
        "cells": int(global_counts[0]),
        "inverted_cells": int(global_counts[1]),
        "extended_cells": int(global_counts[2]),
        "undefined_cells": int(global_counts[3]),
        "min_J": float(global_minima[0]),
        "min_singular_value": float(global_minima[1]),
    }


def _local_min(values) -> float:
    values = np.asarray(values, dtype=np.float64)
    return float(values.min()) if values.size else np.inf
