"""PETSc options for the solvers: our defaults and how they meet the user's and the command line's.

Options are set in this order, later ones winning: :data:`DEFAULT_PETSC_OPTIONS` with the
linear solver of :func:`linear_solver_options`, the options a caller passes, then options
already in PETSc's database under the solver's prefix (such as
``-dolfinx_invertible_snes_monitor`` on the command line).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

from petsc4py import PETSc

from dolfinx_invertible.choices import LINEAR_SOLVERS
from dolfinx_invertible.solvers.petsc_options import options_in_database

__all__ = [
    "DEFAULT_OPTIONS_PREFIX",
    "DEFAULT_PETSC_OPTIONS",
    "DIRECT_SOLVE_LIMIT",
    "MinimizerOptions",
    "linear_solver_options",
]

DEFAULT_OPTIONS_PREFIX = "dolfinx_invertible_"

# The line search is the minimiser's own (energy backtracking in the step's pre-check), so
# SNES takes the step it is handed ("basic"). The convergence test is the minimiser's own too
# (scale-invariant tolerances); snes_rtol and snes_atol still apply where given. A failed or
# non-descent linear solve is answered by the minimiser (projected tangent, or a reported
# failure), so SNES must not stop at the first one.
DEFAULT_PETSC_OPTIONS: dict[str, Any] = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "basic",
    "snes_rtol": 1.0e-9,
    "snes_stol": 0.0,
    # A safeguard: a solve's budget is its progress (convergence.py, the "stalled" stage).
    "snes_max_it": 200,
    "snes_max_linear_solve_fail": 1_000_000,
}

#: Global number of unknowns up to which ``linear_solver="auto"`` factorises (3D; 2D allows 4×).
#: Measured on the collapsed cube, 2 ranks (docs/performance.md, "Scale"): at 2 187 unknowns a
#: step costs 0.18 s direct and 0.15 s iterative, at 6 591 1.53 s against 0.51 s, at 14 739
#: 6.1 s against 1.6 s (MUMPS's numeric factorisation is 91 % of the direct path's time). Below
#: the limit the direct solve costs about as much and is immune to what slows AMG:
#: near-incompressibility (λ/μ of 500 and more) and P2 elements.
DIRECT_SOLVE_LIMIT = 5_000


def _direct_solver_package(comm_size: int) -> str | None:
    for package in ("mumps", "superlu_dist"):
        if PETSc.Sys.hasExternalPackage(package):
            return package
    # PETSc's own factorisation is serial only.
    return "petsc" if comm_size == 1 else None


def linear_solver_options(
    linear_solver: str, pc: str, global_size: int, dimension: int, comm_size: int
) -> dict[str, Any]:
    """Return the KSP/PC options of a linear solver choice.

    Parameters
    ----------
    linear_solver
        ``"direct"`` (a sparse factorisation: MUMPS, SuperLU_dist or PETSc's own in serial),
        ``"iterative"`` (conjugate gradients preconditioned by ``pc``) or ``"auto"``: direct up
        to :data:`DIRECT_SOLVE_LIMIT` unknowns (four times that in 2D) when a parallel-capable
        factorisation is available, iterative above.
    pc
        Preconditioner of the iterative solver: ``"gamg"`` (with the rigid-body
        near-nullspace), ``"hypre"`` (BoomerAMG) or any PETSc PC type.
    global_size
        Number of unknowns over all ranks.
    dimension
        Space dimension, 2 or 3.
    comm_size
        Number of MPI ranks.
    """
    LINEAR_SOLVERS.check(linear_solver)
    package = _direct_solver_package(comm_size)
    if linear_solver == "auto":
        limit = DIRECT_SOLVE_LIMIT * (4 if dimension == 2 else 1)
        linear_solver = "direct" if package is not None and global_size <= limit else "iterative"
    if linear_solver == "direct":
        if package is None:
            raise ValueError(
                "linear_solver='direct' needs MUMPS or SuperLU_dist in parallel; this PETSc has "
                "neither (use linear_solver='iterative')"
            )
        # Cholesky (LDLᵀ in MUMPS): the tangents are symmetric but the exact one may be
        # indefinite. SuperLU_dist and PETSc's own have no symmetric indefinite solver: LU.
        factor = "cholesky" if package == "mumps" else "lu"
        options = {"ksp_type": "preonly", "pc_type": factor, "pc_factor_mat_solver_type": package}
        if package == "mumps":
            # Null-pivot detection, which PETSc needs to report the factor's inertia (the
            # minimiser reads it to tell an indefinite exact tangent).
            options["mat_mumps_icntl_24"] = 1
            # Working space 3x MUMPS's estimate (its default: 1.2x): at 1.2x the LDLᵀ of a
            # contact pile's indefinite tangent failed (INFOG(1) = -9, work array too small) at
            # every cut of a step, at 3x it passes (docs/contact.md). "auto" takes this path
            # only below DIRECT_SOLVE_LIMIT, where the extra memory is small.
            options["mat_mumps_icntl_14"] = 200
        return options
    # Each Newton system to 1e-10. Looser solves measured (docs/performance.md, "Scale"): 1e-6
    # or min(1e-6, a tenth of the Newton target over the residual) save 18-26 % of a step on
    # the collapse but let the last step of a load step raise the energy by 1e-10 of itself on
    # newer PETSc; PETSc's Eisenstat-Walker forcing was over 8 times slower.
    options: dict[str, Any] = {"ksp_type": "cg", "ksp_rtol": 1.0e-10, "pc_type": pc}
    if pc == "hypre":
        options["pc_hypre_type"] = "boomeramg"
    if pc == "gamg":
        # GAMG's Chebyshev smoothers bound the spectrum by 1.1 times an estimate of the largest
        # eigenvalue, which strongly compressed, nearly incompressible tangents (λ/μ ≥ 500)
        # make an underestimate: the smoother then amplifies the top of the spectrum and the
        # preconditioner stops being positive definite (CG: DIVERGED_INDEFINITE_PC). A bound of
        # 1.3 keeps it definite, for about 10 % more iterations on well-conditioned problems.
        options["mg_levels_ksp_chebyshev_esteig"] = "0,0.2,0,1.3"
        # Rebuild the hierarchy with every new tangent. Reused, its prolongators' eigenvalue
        # estimates (which bound the Chebyshev smoothers) belong to an earlier tangent, and on
        # a body through inversion the preconditioner then stops being positive definite (CG:
        # DIVERGED_INDEFINITE_PC at most Newton steps of the collapse at 16³ × 6 cells).
        options["pc_gamg_reuse_interpolation"] = False
    return options


class MinimizerOptions:
    """The PETSc options of a minimiser: defaults, linear solver and the caller's, in order.

    Parameters
    ----------
    problem
        The :class:`~dolfinx_invertible.solvers.problem.EnergyProblem`; one without energy gets
        PETSc's ``l2`` line search (nothing to backtrack on).
    petsc_options
        The caller's options, without prefix or leading dash.
    prefix
        The solver's prefix in PETSc's database.
    linear_solver, pc
        See :func:`linear_solver_options`.

    Attributes
    ----------
    values
        Every option, the caller's last.
    linear_solver
        ``"direct"`` or ``"iterative"``: what :func:`linear_solver_options` chose.
    absolute_tolerance
        ``snes_atol`` where the caller or the database gives it, else ``None``.
    """

    def __init__(
        self,
        problem,
        petsc_options: dict[str, Any] | None,
        prefix: str,
        linear_solver: str,
        pc: str,
    ) -> None:
        space = problem.u.function_space
        chosen = linear_solver_options(
            linear_solver,
            pc,
            space.dofmap.index_map.size_global * space.dofmap.index_map_bs,
            space.mesh.geometry.dim,
            problem.comm.size,
        )
        self.linear_solver = "direct" if chosen["ksp_type"] == "preonly" else "iterative"
        self.prefix = prefix
        self.values = dict(DEFAULT_PETSC_OPTIONS)
        if not problem.has_energy:
            self.values["snes_linesearch_type"] = "l2"
        self.values.update(chosen)
        given = {name.lstrip("-"): value for name, value in (petsc_options or {}).items()}
        self.values.update(given)
        database = PETSc.Options(prefix)
        atol = database.getReal("snes_atol") if database.hasName("snes_atol") else None
        atol = given.get("snes_atol") if atol is None else atol
        self.absolute_tolerance = None if atol is None else float(atol)

    def in_effect(self) -> contextlib.AbstractContextManager[None]:
        """Put the options in PETSc's database for the duration (:func:`options_in_database`)."""
        return options_in_database(self.prefix, self.values)

    def configure(self, snes: PETSc.SNES) -> str:
        """Apply the options to ``snes`` (and its KSP and PC); return the line search type."""
        with self.in_effect():
            snes.setFromOptions()
            # petsc4py 3.18 has no getter for the line search, so read what setFromOptions read.
            return PETSc.Options(self.prefix).getString("snes_linesearch_type")

    @contextlib.contextmanager
    def override(self, snes: PETSc.SNES, options: dict[str, Any]) -> Iterator[None]:
        """Apply further ``options`` to ``snes`` for the duration, then the previous ones."""
        saved = dict(self.values)
        self.values.update({name.lstrip("-"): value for name, value in options.items()})
        try:
            self.configure(snes)
            yield
        finally:
            self.values = saved
            self.configure(snes)
