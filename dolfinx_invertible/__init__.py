"""dolfinx_invertible: energetically consistent invertible hyperelasticity for DOLFINx.

Implements Stomakhin, Howes, Schroeder and Teran, "Energetically Consistent Invertible
Elasticity" (SCA 2012): C1 and C2 extensions of isotropic energies past an inversion threshold,
with the first Piola–Kirchhoff stress and an SPD-projected tangent from a polar SVD.

The batch API (:class:`Material`, the models and extensions, :func:`lame`, :func:`polar_svd`)
needs only NumPy and numba. The DOLFINx layer (forms, problems, solvers, output) is imported on
first use of one of its names, so the batch API never loads DOLFINx.
"""

import importlib
import importlib.metadata

# The batch API is what the constitutive package declares public (its __all__).
from dolfinx_invertible import constitutive as _constitutive
from dolfinx_invertible.constitutive import *  # noqa: F403

try:
    __version__ = importlib.metadata.version("dolfinx_invertible")
except importlib.metadata.PackageNotFoundError:  # a source tree on PYTHONPATH, not installed
    __version__ = "0+unknown"

# The public names of the DOLFINx layer: name -> module that defines it; imported on first
# access. With the batch API, the one list of the package's top-level names.
_LAZY = {
    "HyperelasticForms": "dolfinx_invertible.fem.forms",
    "cell_diagnostics": "dolfinx_invertible.fem.diagnostics",
    "summary": "dolfinx_invertible.fem.diagnostics",
    "vector_function_space": "dolfinx_invertible.fem.spaces",
    "scalar_function_space": "dolfinx_invertible.fem.spaces",
    "HyperelasticProblem": "dolfinx_invertible.solvers.hyperelastic",
    "ImplicitDynamics": "dolfinx_invertible.solvers.dynamics",
    "EnergyMinimizer": "dolfinx_invertible.solvers.minimizer",
    "EnergyProblem": "dolfinx_invertible.solvers.problem",
    "InversionFreeStep": "dolfinx_invertible.solvers.step_limit",
    "SolveResult": "dolfinx_invertible.solvers.results",
    "SolverError": "dolfinx_invertible.solvers.results",
    "solve_load_steps": "dolfinx_invertible.solvers.quasi_static",
    "QuasiStatic": "dolfinx_invertible.solvers.quasi_static",
    "StatefulTerm": "dolfinx_invertible.solvers.terms",
    "StepController": "dolfinx_invertible.solvers.stepping",
    "EnergyTerm": "dolfinx_invertible.solvers.problem",
    "StepLimit": "dolfinx_invertible.solvers.step_limit",
    "ResultWriter": "dolfinx_invertible.io.xdmf",
    "NonlinearProblem": "dolfinx_invertible.solvers.drop_in",
    "NewtonSolverNonlinearProblem": "dolfinx_invertible.solvers.drop_in",
    "SNESNonlinearProblem": "dolfinx_invertible.solvers.drop_in",
    "UFLNeoHookeanForms": "dolfinx_invertible.fem.ufl_forms",
    "reproducible_partitioning": "dolfinx_invertible.fem.mesh",
}


def __getattr__(name: str):
    """Import a name of the DOLFINx layer on first use."""
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'dolfinx_invertible' has no attribute {name!r}")


def __dir__() -> list[str]:
    """List the public names, the lazily imported ones included."""
    return sorted(__all__)


__all__ = [*_constitutive.__all__, *_LAZY]
