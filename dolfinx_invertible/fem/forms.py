"""DOLFINx forms of the elastic energy, residual and tangent of a :class:`Material`."""

from __future__ import annotations

from mpi4py import MPI

import basix
import dolfinx
import numpy as np

from dolfinx_invertible import _compat
from dolfinx_invertible.constitutive.material import Material
from dolfinx_invertible.constitutive.svd_path import compile_svd_path_ahead
from dolfinx_invertible.fem import kernels

__all__ = ["HyperelasticForms", "default_quadrature_degree"]

_SUPPORTED_CELLS = ("triangle", "tetrahedron", "quadrilateral", "hexahedron")
_SUPPORTED_DEGREES = (1, 2)


_SIMPLICES = ("interval", "triangle", "tetrahedron")


def default_quadrature_degree(degree: int, cell_type) -> int:
    """Return the quadrature degree that integrates the elastic forms of degree-k Lagrange.

    ``cell_type`` is the cell's name (``"tetrahedron"``, ...) or a DOLFINx/Basix cell-type enum.
    On simplices 2(k − 1), at least 1: exact for the stiffness of linear elasticity on affine
    cells. On quadrilaterals and hexahedra 2k: the gradients of Q_k have degree k in the other
    directions, and fewer points leave hourglass modes (one point on a P1 hexahedron gives a
    singular tangent). The forms, the cell diagnostics and the inversion-free step limit all take
    their default from here.
    """
    name = getattr(cell_type, "name", cell_type)
    if name not in _SIMPLICES + ("quadrilateral", "hexahedron"):
        raise ValueError(f"no default quadrature degree for cell type {cell_type!r}")
    if name in _SIMPLICES:
        return max(1, 2 * (degree - 1))
    return 2 * degree


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
        Displacement, a ``dolfinx.fem.Function`` on a vector Lagrange space of degree 1 or 2
        (P1, P2 on triangles and tetrahedra, Q1, Q2 on quadrilaterals and hexahedra) with one
        component per space dimension; 2D means plane strain.
    material
        The :class:`~dolfinx_invertible.Material`. Parameters given as scalar
        ``dolfinx.fem.Constant`` are read at every assembly (set ``mu.value`` between solves,
        as in a UFL form); nothing is recompiled.
    quadrature_degree
        Degree of the cell quadrature rule (Basix's rule of that degree on the reference cell).
        Default (:func:`default_quadrature_degree`): 2(k − 1), at least 1, on triangles and
        tetrahedra; 2k on quadrilaterals and hexahedra, whose gradients need it (one point on a
        P1 hexahedron would leave hourglass modes and a singular tangent). A higher degree
        costs one evaluation of the material per extra point.
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
        nothing is recompiled.
    parameter_constants
        The user's scalar Constants the material reads parameters from, passed to DOLFINx after
        :attr:`constants` (read at every assembly).

    Each form is built, and its kernel compiled for this dimension and element (or loaded from
    numba's disk cache), the first time it is used.
    """

    def __init__(
        self,
        u,
        material: Material,
        *,
        quadrature_degree: int | None = None,
        project: bool = True,
    ):
        if not isinstance(material, Material):
            raise TypeError(f"material must be a dolfinx_invertible.Material, got {material!r}")
        cell, degree, gdim = _check_space(u)
        if quadrature_degree is None:
            quadrature_degree = default_quadrature_degree(degree, cell)
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
        self.counters = kernels.counter_row()
        # The user's Constants the parameters are read from, passed to DOLFINx after ours.
        self.parameter_constants = list(material.parameter_constants())
        self.constants = dolfinx.fem.Constant(
            mesh,
            kernels.pack_constants(
                self.tables,
                gdim,
                material,
                self.project,
                self.counters,
                sources=self._sources(material),
                user_constants=len(self.parameter_constants),
            ),
        )
        self._forms: dict[str, object] = {}
        # A serial process compiles the SVD path and the tangent kernel (the two largest, and
        # every Newton step needs them) in helpers while it compiles the residual kernel; under
        # MPI every rank already compiles on its own core.
        if MPI.COMM_WORLD.size == 1:
            ids = (material.model.model_id, material.extension_id)
            compile_svd_path_ahead(*ids, gdim)
            kernels.compile_kernel_ahead("tangent", gdim, *ids)

    def _sources(self, material: Material):
        """Where the kernels read each parameter: an offset into the user Constants, or not."""
        sources = np.full(kernels.PARAMETER_COUNT, kernels.NO_SOURCE)
        for index, constant in material.parameter_sources().items():
            position = next(
                (k for k, known in enumerate(self.parameter_constants) if known is constant), None
            )
            if position is None:
                raise ValueError(
                    f"{material!r} reads a Constant these forms were not built with; build new "
                    "forms for it"
                )
            sources[index] = position
        if material.derived_stiffness():
            sources[kernels.PARAMETER_COUNT - 1] = kernels.DERIVED_STIFFNESS
        return sources

    def _form(self, kind: str, spaces: list):
        # Built, and its kernel compiled, on first use only: a scene without a line search or an
        # energy report never compiles the energy kernel.
        if kind not in self._forms:
            mesh = self.u.function_space.mesh
            address = kernels.kernel_address(
                kind, mesh.geometry.dim, self.material.model.model_id, self.material.extension_id
            )
            if not self._forms:  # the kernels need the SVD path's address before they first run
                kernels.set_svd_path(self.constants, self.material, mesh.geometry.dim)
            self._forms[kind] = _compat.custom_form(
                spaces, address, [self.u], [self.constants, *self.parameter_constants], mesh
            )
        return self._forms[kind]

    @property
    def energy(self):
        """Form of the total elastic energy ∫Ψ(F) dX."""
        return self._form("energy", [])

    @property
    def residual(self):
        """Form of dΠ/du."""
        return self._form("residual", [self.u.function_space])

    @property
    def jacobian(self):
        """Form of the tangent d²Π/du²."""
        space = self.u.function_space
        return self._form("tangent", [space, space])

    def path_counts(self) -> dict[str, tuple[int, int]]:
        """Count the points evaluated and those that went through the SVD, per kernel.

        On this rank, since the last :meth:`reset_path_counts`: ``{"residual": (points, svd)}``.

        Points that skipped the SVD took the invariant fast path (the extension provably
        inactive, and for a projected tangent, the exact tangent already positive definite).
        """
        return kernels.counts_by_kind(self.counters)

    def reset_path_counts(self) -> None:
        """Zero the counters behind :meth:`path_counts`."""
        self.counters[:] = 0.0

    def set_projection(self, project: bool) -> None:
        """Switch the tangent between SPD-projected and exact, without recompiling."""
        self.project = bool(project)
        self.constants.value[kernels.PROJECT_SLOT] = float(self.project)

    def set_material(self, material: Material) -> None:
        """Switch to another material of the same kind (model and extension type).

        Only the parameter values change, so nothing is recompiled. Parameters the new material
        reads from Constants must read Constants these forms were built with.
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
        sources = self._sources(material)
        start = kernels.PARAMETERS_START
        parameters = material.parameters
        self.constants.value[start : start + len(parameters)] = parameters
        slot = kernels.PARAMETER_SOURCES_SLOT
        self.constants.value[slot : slot + kernels.PARAMETER_COUNT] = sources
        self.material = material
