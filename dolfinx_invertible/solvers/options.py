"""PETSc options for the solvers: our defaults and how they meet the user's and the command line's.

Options are set in this order, later ones winning: :data:`DEFAULT_PETSC_OPTIONS`, the options a
caller passes, then options already in PETSc's database under the solver's prefix (such as
``-dolfinx_invertible_snes_monitor`` on the command line).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

from petsc4py import PETSc

__all__ = ["DEFAULT_OPTIONS_PREFIX", "DEFAULT_PETSC_OPTIONS", "options_in_database"]

DEFAULT_OPTIONS_PREFIX = "dolfinx_invertible_"

# ksp_rtol is tight because an inexact linear solve caps Newton's quadratic rate. snes_stol is 0
# because a line search that shortens the step also makes the step norm small far from a
# solution; convergence is decided on the residual alone.
DEFAULT_PETSC_OPTIONS: dict[str, Any] = {
    "snes_type": "newtonls",
    "snes_rtol": 1.0e-9,
    "snes_atol": 1.0e-10,
    "snes_stol": 0.0,
    "snes_max_it": 50,
    "ksp_type": "cg",
    "ksp_rtol": 1.0e-10,
}


@contextlib.contextmanager
def options_in_database(prefix: str, options: dict[str, Any]) -> Iterator[None]:
    """Put ``options`` under ``prefix`` in PETSc's global database for the duration.

    Names already present (from the command line or the caller's own ``PETSc.Options``) are left
    alone, so they take precedence. Ours are removed afterwards so they cannot leak into another
    solver that shares the prefix; they are pushed again around every solve because PETSc reads
    some options lazily, e.g. those of multigrid levels, which GAMG creates during setup.
    """
    database = PETSc.Options(prefix)
    added = []
    for name, value in options.items():
        if database.hasName(name):
            continue
        database.setValue(name, value)
        added.append(name)
    try:
        yield
    finally:
        for name in added:
            database.delValue(name)
