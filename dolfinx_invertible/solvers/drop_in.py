"""Drop-ins for DOLFINx's own nonlinear problem classes: the invertible material plus UFL terms.

A DOLFINx script that solves hyperelasticity writes its residual F as a UFL form (the elastic
term ∫ P : ∇v dX plus loads) and hands it to DOLFINx's nonlinear classes. Replacing the elastic
term by this package's material takes two changed lines: drop the elastic term from F, and
construct the problem with :class:`NonlinearProblem` of this module (``material=`` added)
instead of DOLFINx's. The kernels' residual and tangent are assembled with the UFL terms into
the same PETSc vector and matrix.

- :class:`NewtonSolverNonlinearProblem` has the interface ``dolfinx.nls.petsc.NewtonSolver``
  drives (``F(x, b)``, ``J(x, A)``, ``form(x)``, ``L``, ``a``): DOLFINx's
  ``fem.petsc.NonlinearProblem`` up to 0.9 and its ``NewtonSolverNonlinearProblem`` from 0.10.
- :class:`SNESNonlinearProblem` has the interface of DOLFINx's SNES-based
  ``fem.petsc.NonlinearProblem`` from 0.10 (``solve()``, ``solver``, ``A``, ``b``, ``x``).
- :data:`NonlinearProblem` is the one of the running DOLFINx's own ``NonlinearProblem``.

The Jacobian is the **exact** tangent by default (``tangent="exact"``): DOLFINx's plain Newton
has no line search, and with the SPD-projected tangent (``tangent="projected"``) it converges only
linearly wherever the projection acts. For robustness through inversion, prefer
:class:`~dolfinx_invertible.HyperelasticProblem` (energy line search, projected fallback, step
cutting).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import dolfinx
import ufl
from petsc4py import PETSc

from dolfinx_invertible import _compat
from dolfinx_invertible.constitutive.material import Material
from dolfinx_invertible.fem.forms import HyperelasticForms
from dolfinx_invertible.solvers.problem import EnergyProblem

__all__ = ["NewtonSolverNonlinearProblem", "NonlinearProblem", "SNESNonlinearProblem"]

_TANGENTS = ("exact", "projected")


def _problem(F, u, bcs, material, tangent, quadrature_degree, J, form_compiler_options,
             jit_options) -> tuple[EnergyProblem, HyperelasticForms]:  # fmt: skip
    """Return the form sums: the kernels' residual and tangent plus the user's UFL terms."""
    if not isinstance(material, Material):
        raise TypeError(f"material must be a dolfinx_invertible.Material, got {material!r}")
    if tangent not in _TANGENTS:
        raise ValueError(f"tangent must be 'exact' or 'projected', got {tangent!r}")
    forms = HyperelasticForms(
        u, material, quadrature_degree=quadrature_degree, project=tangent == "projected"
    )
    options = _compat.form_compilation_options(form_compiler_options, jit_options)
    residuals = [forms.residual]
    jacobians = [forms.jacobian]
    if F is not None:
        residuals.append(dolfinx.fem.form(F, **options))
        if J is None:
            J = ufl.derivative(F, u)
            if ufl.algorithms.expand_derivatives(J).empty():
                J = None  # dead loads: no tangent contribution
        if J is not None:
            jacobians.append(dolfinx.fem.form(J, **options))
    return EnergyProblem(u, None, residuals, jacobians, bcs), forms


class NewtonSolverNonlinearProblem:
    """The problem ``dolfinx.nls.petsc.NewtonSolver`` solves: material + UFL residual terms.

    Parameters
    ----------
    F
        UFL residual of everything but the elastic term (loads, springs; linear in the test
        function of ``u``'s space), or None.
    u
        The displacement (vector Lagrange Function).
    bcs
        Dirichlet conditions.
    material
        The :class:`~dolfinx_invertible.Material` whose residual the kernels add.
    tangent
        ``"exact"`` (default; Newton's quadratic convergence) or ``"projected"``.
    quadrature_degree
        Degree of the kernels' cell rule (see
        :class:`~dolfinx_invertible.fem.forms.HyperelasticForms`); UFL terms keep their own.
    J
        UFL Jacobian of ``F``; default ``ufl.derivative(F, u)``.
    form_compiler_options, jit_options
        Passed to ``dolfinx.fem.form`` for the UFL terms.

    Attributes
    ----------
    L, a
        The compiled residual and Jacobian forms the solver lays its vector and matrix out from
        (the kernels' forms, whose pattern holds the UFL terms' too).
    forms
        The kernels' :class:`~dolfinx_invertible.fem.forms.HyperelasticForms`.
    """

    def __init__(
        self,
        F,
        u,
        bcs: Sequence[Any] = (),
        *,
        material: Material,
        tangent: str = "exact",
        quadrature_degree: int | None = None,
        J=None,
        form_compiler_options: dict | None = None,
        jit_options: dict | None = None,
    ):
        self._problem, self.forms = _problem(
            F, u, list(bcs), material, tangent, quadrature_degree, J, form_compiler_options,
            jit_options,
        )  # fmt: skip
        self.u = u
        self.bcs = list(bcs)

    @property
    def L(self):
        """The compiled residual form the solver's vector is laid out from."""
        return self.forms.residual

    @property
    def a(self):
        """The compiled Jacobian form the solver's matrix is laid out from."""
        return self.forms.jacobian

    def form(self, x: PETSc.Vec) -> None:
        """Update ghost values before assembly (as DOLFINx's own problem does)."""
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)

    def F(self, x: PETSc.Vec, b: PETSc.Vec) -> None:
        """Assemble the residual at ``x`` into ``b`` (Dirichlet rows hold x − g)."""
        self._problem.F(None, x, b)

    def J(self, x: PETSc.Vec, A: PETSc.Mat) -> None:
        """Assemble the Jacobian at ``x`` into ``A``."""
        self._problem.J(None, x, A, A)


class SNESNonlinearProblem:
    """DOLFINx's SNES-based ``NonlinearProblem`` (0.10 on) with the material added.

    Parameters
    ----------
    F, u, material, tangent, quadrature_degree, J, form_compiler_options, jit_options
        As for :class:`NewtonSolverNonlinearProblem`.
    petsc_options_prefix
        Options prefix of the SNES (mandatory, as in DOLFINx).
    bcs
        Dirichlet conditions.
    petsc_options
        Options set on the SNES (PETSc's defaults otherwise, as in DOLFINx: ``newtonls`` with
        its ``bt`` line search on the residual norm).

    Attributes
    ----------
    solver
        The PETSc SNES.
    A, b, x
        Jacobian matrix, residual vector and solution vector.
    """

    def __init__(
        self,
        F,
        u,
        *,
        material: Material,
        petsc_options_prefix: str,
        bcs: Sequence[Any] | None = None,
        tangent: str = "exact",
        quadrature_degree: int | None = None,
        J=None,
        petsc_options: dict | None = None,
        form_compiler_options: dict | None = None,
        jit_options: dict | None = None,
    ):
        if not petsc_options_prefix:
            raise ValueError("PETSc options prefix cannot be empty")
        bcs = list(bcs or [])
        self._problem, self.forms = _problem(
            F, u, bcs, material, tangent, quadrature_degree, J, form_compiler_options,
            jit_options,
        )  # fmt: skip
        self.u = u
        self._A = self._problem.create_matrix()
        self._b = self._problem.create_vector()
        self._x = self._problem.create_vector()
        self._snes = PETSc.SNES().create(u.function_space.mesh.comm)
        self._snes.setOptionsPrefix(petsc_options_prefix)
        self._snes.setFunction(self._problem.F, self._b)
        self._snes.setJacobian(self._problem.J, self._A, self._A)
        options = PETSc.Options(petsc_options_prefix)
        for name, value in (petsc_options or {}).items():
            options[name] = value
        self._snes.setFromOptions()
        for name in petsc_options or {}:
            options.delValue(name)

    def solve(self):
        """Solve from the current ``u``; return ``u`` (check ``solver.getConvergedReason()``)."""
        _compat.petsc_vector(self.u).copy(self._x)
        _compat.set_dirichlet_values(self._x, self._problem.bcs)
        _compat.snes_solve(self._snes, self._x)
        self._problem.update_solution(self._x)
        return self.u

    @property
    def solver(self) -> PETSc.SNES:
        """The PETSc SNES."""
        return self._snes

    @property
    def A(self) -> PETSc.Mat:
        """The Jacobian matrix."""
        return self._A

    @property
    def b(self) -> PETSc.Vec:
        """The residual vector."""
        return self._b

    @property
    def x(self) -> PETSc.Vec:
        """The solution vector (not sharing memory with ``u``)."""
        return self._x


#: The drop-in for the running DOLFINx's own ``dolfinx.fem.petsc.NonlinearProblem``.
NonlinearProblem = (
    SNESNonlinearProblem if _compat.NONLINEAR_PROBLEM_IS_SNES else NewtonSolverNonlinearProblem
)
