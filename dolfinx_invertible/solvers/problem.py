"""The form-sum assembler: Π(u), its gradient and tangent as sums of compiled DOLFINx forms.

Forms of any origin are summed: UFL forms compiled by ``dolfinx.fem.form`` and forms built around
custom cell kernels alike, plus terms that are not forms at all (:class:`EnergyTerm`, e.g. a
contact barrier). Dirichlet conditions are applied the way DOLFINx's own ``NonlinearProblem``
applies them.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import Any, Protocol

from mpi4py import MPI

import dolfinx.fem
import dolfinx.fem.petsc
import numpy as np
from petsc4py import PETSc

from dolfinx_invertible import _compat
from dolfinx_invertible.solvers.results import point_text

__all__ = ["EnergyProblem", "EnergyTerm"]

_SAME_PATTERN = PETSc.Mat.Structure.SAME_NONZERO_PATTERN
_SUBSET_PATTERN = PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN


class EnergyTerm(Protocol):
    """A contribution to Π that is not a DOLFINx form, e.g. a contact barrier.

    Evaluated at the current ``u`` of the problem (owned values and ghosts up to date). A term
    that can add its exact Hessian or its SPD projection also has ``set_projection(projected)``
    (:class:`~dolfinx_invertible.solvers.terms.ProjectableHessian`), which
    :meth:`EnergyProblem.set_term_projection` calls.
    """

    def energy(self) -> float:
        """Return this rank's share of the term's value (the problem sums over ranks)."""
        ...

    def add_residual(self, residual: np.ndarray) -> None:
        """Add the gradient into the local residual array.

        ``residual`` is laid out like ``u.x.array`` (owned then ghost dofs, components
        interleaved); contributions to ghost dofs are summed into their owners afterwards.
        """
        ...

    def add_tangent(self, matrix: PETSc.Mat, constrained: np.ndarray) -> None:
        """Add the (positive semidefinite) Hessian with local indices and ``ADD_VALUES``.

        Rows and columns listed in ``constrained`` (local indices of Dirichlet dofs) must be left
        out. The matrix is flushed before and assembled after this call.
        """
        ...


class _ReusedMatrix:
    """The assembled matrix of a bilinear form that does not read the unknown.

    Such a form (the inertia term's mass matrix, a linear spring) gives the same matrix at every
    iterate: it is assembled again only when something it reads has changed since (its
    constants, e.g. the time step in an inertia weight, its coefficients or the mesh geometry),
    and otherwise added as it is. Assembling even a trivial form costs as much as the insertion
    of every cell's entries into the sparse matrix.
    """

    def __init__(self, form, matrix: PETSc.Mat, mesh) -> None:
        self.form = form
        self.matrix = matrix
        self._mesh = mesh
        self._seen: tuple[np.ndarray, list[np.ndarray], np.ndarray] | None = None

    def _unchanged(
        self, constants: np.ndarray, coefficients: list[np.ndarray], geometry: np.ndarray
    ) -> bool:
        if self._seen is None:
            return False
        seen_constants, seen_coefficients, seen_geometry = self._seen
        return (
            np.array_equal(constants, seen_constants)
            and all(map(np.array_equal, coefficients, seen_coefficients))
            and np.array_equal(geometry, seen_geometry)
        )

    def update(self, bcs: list) -> bool:
        """Assemble the form again if its data changed; return False if it cannot be reused.

        Its Dirichlet rows and columns are zero, with 0 on the diagonal. A form whose entries
        fall outside the sparsity pattern of the problem's matrix cannot be added to it as is.
        """
        constants, coefficients = _compat.form_data(self.form)
        geometry = self._mesh.geometry.x
        # Assembly is collective: every rank reassembles if the data changed on any.
        comm = self.matrix.getComm().tompi4py()
        if comm.allreduce(self._unchanged(constants, coefficients, geometry), op=MPI.LAND):
            return True
        self.matrix.zeroEntries()
        _compat.assemble_matrix_into(self.matrix, self.form, bcs, 0.0)
        self.matrix.assemble()
        if self.matrix.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)["mallocs"] > 0:
            return False
        self._seen = (constants, [array.copy() for array in coefficients], geometry.copy())
        return True

    def add_to(self, matrix: PETSc.Mat) -> None:
        """Add the form's matrix to an assembled ``matrix`` that the first form's pattern fills.

        Our pattern is the first form's, which every matrix that form is assembled into
        contains: with as many nonzeros in all, the two patterns are the same, and the sum needs
        no merge of the rows (thirty times slower).
        """
        total = PETSc.Mat.InfoType.GLOBAL_SUM
        same = self.matrix.getInfo(total)["nz_used"] == matrix.getInfo(total)["nz_used"]
        matrix.axpy(1.0, self.matrix, structure=_SAME_PATTERN if same else _SUBSET_PATTERN)


def _reads(form, u: dolfinx.fem.Function) -> bool:
    """Whether a compiled form has ``u`` among its coefficients."""
    _, coefficients = _compat.form_data(form)
    return any(np.shares_memory(array, u.x.array) for array in coefficients)


def _as_form_list(forms: Any, rank: int, name: str) -> list:
    if forms is None:
        forms = []
    elif not isinstance(forms, (list, tuple)):
        forms = [forms]
    forms = list(forms)
    for form in forms:
        if getattr(form, "rank", rank) != rank:
            raise ValueError(
                f"{name}: expected compiled forms of rank {rank}, got rank {form.rank}"
            )
    return forms


class EnergyProblem:
    """Assembles a potential Π(u), its gradient and its tangent from sums of compiled forms.

    The callbacks have the signatures PETSc SNES expects. Each copies the iterate into ``u``
    (owned values, then a forward ghost update) before assembling, so the forms, whose
    coefficient is ``u``, see the iterate.

    Parameters
    ----------
    u
        The unknown displacement; the forms must depend on it.
    energy
        Compiled scalar forms whose sum is Π(u). ``None`` or empty for materials that only define
        a stress; :class:`EnergyMinimizer` then uses a line search on the residual norm.
    residual
        Compiled linear forms whose sum is dΠ/du (or the stress residual).
    jacobian
        Compiled bilinear forms whose sum is the tangent; all on the space of ``u``. The first
        one sets the sparsity pattern (see :meth:`create_matrix`).
    bcs
        Dirichlet conditions on the space of ``u``.
    terms
        :class:`EnergyTerm` contributions beyond the forms; they add to the energy, the residual
        and the tangent alike.
    """

    def __init__(
        self,
        u: dolfinx.fem.Function,
        energy: Sequence[Any] | Any | None,
        residual: Sequence[Any] | Any,
        jacobian: Sequence[Any] | Any,
        bcs: Sequence[Any] | None = None,
        *,
        terms: Sequence[EnergyTerm] = (),
    ) -> None:
        self.u = u
        self.energy_forms = _as_form_list(energy, 0, "energy")
        self.residual_forms = _as_form_list(residual, 1, "residual")
        self.jacobian_forms = _as_form_list(jacobian, 2, "jacobian")
        if not self.residual_forms:
            raise ValueError("residual: at least one compiled linear form is required")
        if not self.jacobian_forms:
            raise ValueError("jacobian: at least one compiled bilinear form is required")
        self.bcs = list(bcs or [])
        self.terms = list(terms)
        self.comm = u.function_space.mesh.comm
        self._u_vector = _compat.petsc_vector(u)
        self._pattern_checked = False
        # Bilinear forms that do not read u, reused between assemblies (the first form sets the
        # sparsity pattern and is always assembled).
        self._reused = [
            _ReusedMatrix(form, self.create_matrix(), u.function_space.mesh)
            for form in self.jacobian_forms[1:]
            if not _reads(form, u)
        ]
        space = u.function_space
        block_size = space.dofmap.index_map_bs
        local_size = space.dofmap.index_map.size_local + space.dofmap.index_map.num_ghosts
        #: Local indices (owned and ghost, components unrolled) of the Dirichlet dofs.
        self.constrained_dofs = np.unique(
            np.concatenate(
                [np.zeros(0, dtype=np.int32)]
                + [_compat.constrained_local_dofs(bc) for bc in self.bcs]
            )
        ).astype(np.int32)
        owned = space.dofmap.index_map.size_local * block_size
        free = np.ones(local_size * block_size, dtype=bool)
        free[self.constrained_dofs] = False
        #: Mask of the owned dofs (components unrolled) that no Dirichlet condition fixes.
        self.free_owned = free[:owned]

    @property
    def has_energy(self) -> bool:
        """Whether energy forms were given, i.e. whether :meth:`objective` can be evaluated."""
        return bool(self.energy_forms)

    def create_vector(self) -> PETSc.Vec:
        """Return a ghosted vector laid out like the dofs of ``u``."""
        return _compat.create_vector(self.residual_forms[0])

    def create_matrix(self) -> PETSc.Mat:
        """Return a matrix with the sparsity pattern of the first jacobian form.

        Cell and exterior-facet integrals of further forms on the same space fall inside that
        pattern, because every facet belongs to a cell. Interior-facet integrals couple the dofs
        of neighbouring cells, which a cell-only pattern lacks; PETSc is allowed to allocate such
        entries rather than fail, and :meth:`J` warns once if it had to.
        """
        matrix = _compat.create_matrix(self.jacobian_forms[0])
        if len(self.jacobian_forms) > 1:
            matrix.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        return matrix

    def set_term_projection(self, projected: bool) -> None:
        """Tell the terms that can switch to add their projected (or exact) Hessian."""
        for term in self.terms:
            switch = getattr(term, "set_projection", None)
            if switch is not None:
                switch(projected)

    def update_solution(self, x: PETSc.Vec) -> None:
        """Copy the owned values of ``x`` into ``u`` and update the ghosts of ``u``."""
        if x.handle != self._u_vector.handle:
            x.copy(self._u_vector)
        self.u.x.scatter_forward()

    def locate(self, x: PETSc.Vec) -> str:
        """Say where the state ``x`` is worst, for a failed solve's message (collective).

        The node with the largest free residual entry (its reference position and where it is
        now), then what each term with a ``describe_state()`` method reports of the state
        (:class:`~dolfinx_invertible.solvers.terms.StatefulTerm`). Leaves ``u`` at ``x``.
        """
        residual = self.create_vector()
        try:
            self.F(None, x, residual)
            values = np.abs(residual.getArray(readonly=True))
        finally:
            residual.destroy()
        space = self.u.function_space
        block_size = space.dofmap.index_map_bs
        dimension = space.mesh.geometry.dim
        values = np.where(self.free_owned, np.nan_to_num(values, nan=np.inf), 0.0)
        candidate = (-1.0, (), ())
        if len(values):
            index = int(np.argmax(values))
            node = index // block_size
            reference = space.tabulate_dof_coordinates()[node, :dimension]
            offset = self.u.x.array[node * block_size : node * block_size + dimension]
            candidate = (float(values[index]), tuple(reference), tuple(reference + offset))
        value, reference, current = max(self.comm.allgather(candidate), key=lambda item: item[0])
        parts = []
        if value > 0.0:
            parts.append(
                f"the largest residual entry, {value:.3g}, at the node X = {point_text(reference)} "
                f"(now at {point_text(current)})"
            )
        for term in self.terms:
            describe = getattr(term, "describe_state", None)
            if describe is not None:
                parts.append(describe())
        return "; ".join(part for part in parts if part)

    def energy_terms(self) -> np.ndarray:
        """Return each energy form's and term's value at the current ``u``, summed over ranks."""
        local = np.array(
            [dolfinx.fem.assemble_scalar(form) for form in self.energy_forms]
            + [term.energy() for term in self.terms],
            dtype=np.float64,
        )
        return self.comm.allreduce(local, op=MPI.SUM)

    def total_energy(self) -> float | None:
        """Π at the current ``u``, summed over all ranks; ``None`` without energy forms.

        An undefined energy (NaN, e.g. the logarithm of a negative Jacobian determinant) is
        reported as +inf, so a line search treats the state as infinitely bad and backtracks.
        """
        if not self.has_energy:
            return None
        total = float(np.sum(self.energy_terms()))
        return total if not math.isnan(total) else math.inf

    def objective(self, snes: PETSc.SNES | None, x: PETSc.Vec) -> float:
        """SNES objective: Π at ``x``."""
        if not self.has_energy:
            raise ValueError("this problem has no energy forms, so no objective")
        self.update_solution(x)
        return self.total_energy()

    def F(self, snes: PETSc.SNES | None, x: PETSc.Vec, b: PETSc.Vec) -> None:
        """SNES residual: dΠ/du at ``x`` into ``b``, Dirichlet rows holding ``x - g``."""
        self.update_solution(x)
        with b.localForm() as b_local:
            b_local.set(0.0)
        for form in self.residual_forms:
            dolfinx.fem.petsc.assemble_vector(b, form)
        if self.terms:
            with b.localForm() as b_local:
                local = b_local.array
                for term in self.terms:
                    term.add_residual(local)
        # The ghosted u rather than x: lifting reads ghost values, and x need not carry them.
        _compat.lift_residual(b, self.jacobian_forms, self.bcs, self._u_vector)

    def J(self, snes: PETSc.SNES | None, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat) -> None:
        """SNES Jacobian: the summed tangent at ``x`` into ``A`` (and ``P`` if distinct).

        Dirichlet rows and columns are zero with 1 on the diagonal, exactly once: DOLFINx inserts
        rather than adds the diagonal, so every form but the last is assembled with diagonal 0
        and the last with 1, which yields 1 whether the diagonal is inserted or added. A form
        after the first that does not read ``u`` is assembled only when its constants,
        coefficients or the mesh geometry changed, and its matrix added otherwise.
        """
        self.update_solution(x)
        matrices = [A] if P is None or P.handle == A.handle else [A, P]
        reused = [matrix for matrix in self._reused if matrix.update(self.bcs)]
        self._reused = reused  # a form that cannot be reused is assembled from now on
        reused_forms = {id(matrix.form) for matrix in reused}
        assembled = [form for form in self.jacobian_forms if id(form) not in reused_forms]
        last = len(assembled) - 1
        form_mallocs = 0.0
        for matrix in matrices:
            matrix.zeroEntries()
            for index, form in enumerate(assembled):
                diagonal = 1.0 if index == last else 0.0
                _compat.assemble_matrix_into(matrix, form, self.bcs, diagonal)
            # Counted before the terms, whose couplings (contact pairs) may grow the pattern;
            # PETSc counts a matrix's allocations when it is assembled.
            if matrix is A and not self._pattern_checked and len(self.jacobian_forms) > 1:
                A.assemble()
                form_mallocs = A.getInfo()["mallocs"]
            if reused:
                matrix.assemble()
                for reused_matrix in reused:
                    reused_matrix.add_to(matrix)
            for term in self.terms:
                term.add_tangent(matrix, self.constrained_dofs)
                matrix.assemble(PETSc.Mat.AssemblyType.FLUSH)
            matrix.assemble()
        if not self._pattern_checked and len(self.jacobian_forms) > 1:
            self._pattern_checked = True
            mallocs = form_mallocs
            if mallocs > 0:
                warnings.warn(
                    f"the jacobian forms needed {int(mallocs)} allocations beyond the sparsity "
                    "pattern of the first form (interior-facet integrals?); pass the form with "
                    "the widest coupling first",
                    RuntimeWarning,
                    stacklevel=2,
                )
