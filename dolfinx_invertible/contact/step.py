"""Continuous collision detection along Newton directions: a step cap (the solvers' ``StepLimit``).

Before the energy line search, the minimiser asks every step limit for the largest α ≤ 1 it
allows along u + α · sign · direction. Each boundary vertex of the contact term then moves on
the straight path x + α p; :class:`CollisionFreeStep` returns ``fraction`` of the first α at
which any of them reaches an obstacle at its position at the term's time, over all ranks, so
that the line search only ever evaluates states with every gap positive.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from mpi4py import MPI

from petsc4py import PETSc

from dolfinx_invertible.constitutive.validation import check_open_unit_interval
from dolfinx_invertible.contact.ccd import collision_free_step

if TYPE_CHECKING:
    from dolfinx_invertible.contact.term import ContactTerm

__all__ = ["CollisionFreeStep"]


class CollisionFreeStep:
    """Largest step along a direction for which no boundary vertex crosses an obstacle.

    Parameters
    ----------
    term
        The :class:`~dolfinx_invertible.contact.term.ContactTerm` whose vertices, obstacles
        and time are checked.
    fraction
        The share of the first crossing a step may reach, in (0, 1).
    """

    def __init__(self, term: ContactTerm, *, fraction: float = 0.9) -> None:
        self.term = term
        self.fraction = check_open_unit_interval("fraction", fraction)

    def largest_step(self, direction: PETSc.Vec, sign: float = 1.0) -> float:
        """Largest α ≤ 1 for ``u + α · sign · direction`` (a PETSc Vec), over all ranks."""
        term = self.term
        values = direction.getArray(readonly=True)
        motion = float(sign) * values[term.boundary.dofs]
        local = collision_free_step(
            term.scene, term.positions(), motion, term.time, fraction=self.fraction
        )
        return term.comm.allreduce(local, op=MPI.MIN)
