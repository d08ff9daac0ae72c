"""Nonlinear solvers: energy minimisation with PETSc SNES, load stepping, dynamics.

- :mod:`.problem`: :class:`EnergyProblem`, the sum of compiled forms SNES evaluates;
- :mod:`.newton`: :class:`EnergyMinimizer`, SNES Newton with an energy line search;
- :mod:`.options`: default PETSc options and how they combine with the user's;
- :mod:`.nullspace`: rigid-body modes for algebraic multigrid;
- :mod:`.results`: :class:`SolveResult` and :class:`SolverError`;
- :mod:`.hyperelastic`: :class:`HyperelasticProblem`, material + boundary conditions + UFL terms;
- :mod:`.stepping`: quasi-static load steps with step cutting;
- :mod:`.step_limit`: the inversion-free step cap;
- :mod:`.dynamics`: implicit time stepping.
"""

from dolfinx_invertible.solvers.dynamics import ImplicitDynamics
from dolfinx_invertible.solvers.hyperelastic import HyperelasticProblem, external_forms
from dolfinx_invertible.solvers.newton import EnergyMinimizer
from dolfinx_invertible.solvers.nullspace import rigid_body_near_nullspace
from dolfinx_invertible.solvers.options import DEFAULT_OPTIONS_PREFIX, DEFAULT_PETSC_OPTIONS
from dolfinx_invertible.solvers.problem import EnergyProblem
from dolfinx_invertible.solvers.results import SolverError, SolveResult, snes_reason_name
from dolfinx_invertible.solvers.step_limit import InversionFreeStep, volume_polynomial
from dolfinx_invertible.solvers.stepping import solve_load_steps

__all__ = [
    "DEFAULT_OPTIONS_PREFIX",
    "DEFAULT_PETSC_OPTIONS",
    "EnergyMinimizer",
    "EnergyProblem",
    "HyperelasticProblem",
    "ImplicitDynamics",
    "InversionFreeStep",
    "SolveResult",
    "SolverError",
    "external_forms",
    "rigid_body_near_nullspace",
    "snes_reason_name",
    "solve_load_steps",
    "volume_polynomial",
]
