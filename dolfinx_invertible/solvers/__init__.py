"""Nonlinear solvers: energy minimisation with PETSc SNES, load stepping, dynamics.

- :mod:`.problem`: :class:`EnergyProblem`, the sum of compiled forms SNES evaluates;
- :mod:`.minimizer`: :class:`EnergyMinimizer`, SNES Newton wired to the three below;
- :mod:`.directions`: which tangent an iteration uses, and the projected and blended
  directions that replace a failed one;
- :mod:`.line_search`: energy backtracking with a watchdog;
- :mod:`.convergence`: residual tolerances scaled to the problem;
- :mod:`.monitors`: what observers are told (:class:`NewtonIteration`, :class:`StepCap`,
  :class:`StepAttempt`);
- :mod:`.options`: default PETSc options and how they combine with the user's;
- :mod:`.nullspace`: rigid-body modes for algebraic multigrid;
- :mod:`.results`: :class:`SolveResult` and :class:`SolverError`;
- :mod:`.hyperelastic`: :class:`HyperelasticProblem`, material + boundary conditions + UFL terms;
- :mod:`.terms`: :class:`StatefulTerm`, energy terms with time and state of their own;
- :mod:`.stepping`: the step controller (cut on failure, grow after easy steps);
- :mod:`.stepper`: :class:`Stepper`, the one protocol of load steps and time steps;
- :mod:`.quasi_static`: :class:`QuasiStatic`, load steps (and :func:`solve_load_steps`);
- :mod:`.dynamics`: :class:`ImplicitDynamics`, implicit time stepping;
- :mod:`.integrators`: backward Euler, BDF2 and Newmark as incremental potentials, one module
  each;
- :mod:`.step_limit`: step caps, the inversion-free one among them.
"""

# The PyPI DOLFINx wheel finds its MPI library only once mpi4py has loaded it: mpi4py first.
from mpi4py import MPI  # noqa: F401

from dolfinx_invertible.solvers.dynamics import ImplicitDynamics
from dolfinx_invertible.solvers.hyperelastic import HyperelasticProblem, external_forms
from dolfinx_invertible.solvers.integrators import (
    BDF2,
    INTEGRATORS,
    BackwardEuler,
    Integrator,
    Newmark,
)
from dolfinx_invertible.solvers.minimizer import EnergyMinimizer
from dolfinx_invertible.solvers.monitors import (
    DIRECTION_KINDS,
    NewtonIteration,
    StepAttempt,
    StepCap,
)
from dolfinx_invertible.solvers.nullspace import rigid_body_near_nullspace
from dolfinx_invertible.solvers.options import (
    DEFAULT_OPTIONS_PREFIX,
    DEFAULT_PETSC_OPTIONS,
    DIRECT_SOLVE_LIMIT,
)
from dolfinx_invertible.solvers.problem import EnergyProblem, EnergyTerm
from dolfinx_invertible.solvers.quasi_static import QuasiStatic, solve_load_steps
from dolfinx_invertible.solvers.results import (
    STAGES,
    SolverError,
    SolveResult,
    ksp_reason_name,
    snes_reason_name,
)
from dolfinx_invertible.solvers.step_limit import InversionFreeStep, StepLimit, volume_polynomial
from dolfinx_invertible.solvers.stepper import Stepper
from dolfinx_invertible.solvers.stepping import Solvable, StepController, take_step
from dolfinx_invertible.solvers.terms import StatefulTerm
from dolfinx_invertible.solvers.trust_region import TrustRegion

__all__ = [
    "BDF2",
    "DEFAULT_OPTIONS_PREFIX",
    "DEFAULT_PETSC_OPTIONS",
    "DIRECTION_KINDS",
    "DIRECT_SOLVE_LIMIT",
    "INTEGRATORS",
    "STAGES",
    "BackwardEuler",
    "EnergyMinimizer",
    "EnergyProblem",
    "EnergyTerm",
    "HyperelasticProblem",
    "ImplicitDynamics",
    "Integrator",
    "InversionFreeStep",
    "NewtonIteration",
    "Newmark",
    "QuasiStatic",
    "Solvable",
    "SolveResult",
    "SolverError",
    "StepAttempt",
    "StepCap",
    "StepController",
    "StepLimit",
    "Stepper",
    "StatefulTerm",
    "TrustRegion",
    "external_forms",
    "ksp_reason_name",
    "rigid_body_near_nullspace",
    "snes_reason_name",
    "solve_load_steps",
    "take_step",
    "volume_polynomial",
]
