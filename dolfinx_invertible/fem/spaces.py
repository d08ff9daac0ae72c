"""Function spaces for displacements and cell fields, the same call on every supported DOLFINx."""

from __future__ import annotations

from dolfinx_invertible import _compat

__all__ = ["scalar_function_space", "vector_function_space"]


def vector_function_space(mesh, degree: int = 1, family: str = "Lagrange"):
    """Return a vector-valued space with one component per geometric dimension.

    ``dolfinx.fem.VectorFunctionSpace(mesh, (family, degree))`` on DOLFINx < 0.7,
    ``dolfinx.fem.functionspace(mesh, (family, degree, (gdim,)))`` from 0.7 on.

    Parameters
    ----------
    mesh
        The mesh.
    degree
        Polynomial degree (1 or 2 for the hyperelastic forms).
    family
        Element family, ``"Lagrange"`` by default.
    """
    return _compat.vector_function_space(mesh, degree, family)


def scalar_function_space(mesh, degree: int = 0, family: str = "DG"):
    """Return a scalar space, by default piecewise constants ("DG", 0) for per-cell fields."""
    return _compat.scalar_function_space(mesh, degree, family)
