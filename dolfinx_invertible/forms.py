"""DOLFINx forms of the elastic energy, residual and tangent of a :class:`Material`."""

from __future__ import annotations

import basix
import dolfinx

from dolfinx_invertible import _compat, kernels
from dolfinx_invertible.material import Material

__all__ = ["HyperelasticForms", "default_quadrature_degree"]

_SUPPORTED_CELLS = ("triangle", "tetrahedron", "quadrilateral", "hexahedron")
_SUPPORTED_DEGREES = (1, 2)


def default_quadrature_degree(degree: int) -> int:
    """2(k − 1), at least 1: exact for the stiffness of linear elasticity on affine simplices."""
    return max(1, 2 * (degree - 1))


def _check_space(u) -> tuple[str, int, int]:
    space = u.function_space
    mesh = space.mesh
    cell = mesh.topology.cell_type.name
    tdim = mesh.topology.dim
    gdim = mesh.geometry.dim
    family, degree = _compat.element_family_and_degree(space)
    supported = (
        f"supported: vector Lagrange of degree {_SUPPORTED_DEGREES} on {_SUPPORTED_CELLS}, "
        "one component per space dimension, affine (degree-1) geometry"
    )
    if cell not in _SUPPORTED_CELLS:
        raise ValueError(f"cell type {cell!r} is not supported; {supported}")
    if family not in ("Lagrange", "Q", "CG") or degree not in _SUPPORTED_DEGREES:
        raise ValueError(f"element {family} of degree {degree} is not supported; {supported}")
    if tdim != gdim or space.dofmap.index_map_bs != gdim:
        raise ValueError(
            f"u must have {gdim} components on a {tdim}D mesh in {gdim}D space; {supported}"
        )
    if _compat.coordinate_element_degree(mesh) != 1:
        raise ValueError(f"the mesh geometry must be affine (degree 1); {supported}")
    return cell, degree, gdim


class HyperelasticForms:
    """Energy, residual and tangent forms of a material for a displacement field ``u``.

    Parameters
    ----------
    u
        Displacement, a ``dolfinx.fem.Function`` on a vector Lagrange space (P1 or P2) with one
        component per space dimension; 2D means plane strain.
    material
        The :class:`~dolfinx_invertible.Material`.
    quadrature_degree
        Degree of the cell quadrature rule; default 2(k − 1), at least 1.
    project
        Use the SPD-projected tangent (default) or the exact derivative of the residual.

    Attributes
    ----------
    energy
        Form of the total elastic energy ∫Ψ(F) dX (``dolfinx.fem.assemble_scalar``, then sum
        over ranks).
    residual
        Form of dΠ/du (``dolfinx.fem.petsc.assemble_vector``).
    jacobian
        Form of the tangent (``dolfinx.fem.petsc.assemble_matrix``).
    constants
        The ``dolfinx.fem.Constant`` the kernels read: a header, the material parameters
        [μ, λ, ε, k] and the reference tables. :meth:`set_material` changes the parameters;
        nothing is ever recompiled (one compiled kernel serves every element and material).
    """

    def __init__(
        self, u, material: Material, quadrature_degree: int | None = None, project: bool = True
    ):
        if not isinstance(material, Material):
            raise TypeError(f"material must be a dolfinx_invertible.Material, got {material!r}")
        cell, degree, gdim = _check_space(u)
        if quadrature_degree is None:
            quadrature_degree = default_quadrature_degree(degree)
        if int(quadrature_degree) != quadrature_degree or quadrature_degree < 0:
            raise ValueError(f"quadrature_degree must be an integer >= 0, got {quadrature_degree}")
        self.u = u
        self.material = material
        self.quadrature_degree = int(quadrature_degree)
        self.project = bool(project)
        mesh = u.function_space.mesh
        element = _compat.basix_element(u.function_space)
        geometry_element = basix.create_element(
            basix.ElementFamily.P, element.cell_type, 1, basix.LagrangeVariant.equispaced
        )
        self.tables = kernels.ReferenceTables.from_basix(
            element, geometry_element, self.quadrature_degree
        )
        self.constants = dolfinx.fem.Constant(
            mesh, kernels.pack_constants(self.tables, gdim, material, self.project)
        )
        space = u.function_space
        arguments = ([u], [self.constants], mesh)
        self.energy = _compat.custom_form([], kernels.kernel_address("energy"), *arguments)
        self.residual = _compat.custom_form([space], kernels.kernel_address("residual"), *arguments)
        self.jacobian = _compat.custom_form(
            [space, space], kernels.kernel_address("tangent"), *arguments
        )

    def set_projection(self, project: bool) -> None:
        """Switch the tangent between SPD-projected and exact, without recompiling."""
        self.project = bool(project)
        self.constants.value[kernels.PROJECT_SLOT] = float(self.project)

    def set_material(self, material: Material) -> None:
        """Switch to another material of the same kind (model and extension type).

        Only the parameter values change, so nothing is recompiled.
        """
        same_kind = (
            material.model.model_id == self.material.model.model_id
            and material.extension_id == self.material.extension_id
            and material.positive_only == self.material.positive_only
        )
        if not same_kind:
            raise ValueError(
                f"{material!r} is not of the same kind as {self.material!r}; build new forms"
            )
        start = kernels.HEADER
        self.constants.value[start : start + len(material.parameters)] = material.parameters
        self.material = material
