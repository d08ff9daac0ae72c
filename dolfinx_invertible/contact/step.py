"""Continuous collision detection along Newton directions: a step cap (the solvers' ``StepLimit``).

Before the energy line search, the minimiser asks every step limit for the largest α ≤ 1 it
allows along u + α · sign · direction. Each boundary vertex of the contact term then moves on
the straight path x + α p; :class:`CollisionFreeStep` returns ``fraction`` of the first α at
which any of them reaches an obstacle at its position at the term's time, over all ranks, so
that the line search only ever evaluates states with every gap positive.
"""

from __future__ import annotations

from typing import Protocol

from mpi4py import MPI

import numpy as np
from petsc4py import PETSc

from dolfinx_invertible.constitutive.validation import check_open_unit_interval
from dolfinx_invertible.contact.boundary import BoundaryVertices
from dolfinx_invertible.contact.obstacles import Obstacles

__all__ = ["CollisionFreeStep", "ContactState"]


class ContactState(Protocol):
    """What the step cap reads of a contact term (a :class:`~.term.ContactTerm` is one).

    Attributes
    ----------
    boundary
        The :class:`~dolfinx_invertible.contact.boundary.BoundaryVertices` this rank moves.
    obstacles
        The :class:`~dolfinx_invertible.contact.obstacles.Obstacles`.
    time
        The time at which the obstacles are evaluated.
    comm
        The communicator over which the step is reduced.
    """

    boundary: BoundaryVertices
    obstacles: Obstacles
    time: float
    comm: MPI.Comm

    def positions(self) -> np.ndarray:
        """Return the current positions of this rank's boundary vertices, (n, d)."""


class CollisionFreeStep:
    """Largest step along a direction for which no boundary vertex crosses an obstacle.

    Parameters
    ----------
    term
        The contact term (:class:`~dolfinx_invertible.contact.term.ContactTerm`, or anything
        with the attributes of :class:`ContactState`) whose vertices, obstacles and time are
        checked.
    fraction
        The share of the first crossing a step may reach, in (0, 1).
    """

    def __init__(self, term: ContactState, *, fraction: float = 0.9) -> None:
        self.term = term
        self.fraction = check_open_unit_interval("fraction", fraction)

    def largest_step(self, direction: PETSc.Vec, sign: float = 1.0) -> float:
        """Largest α ≤ 1 for ``u + α · sign · direction`` (a PETSc Vec), over all ranks."""
        term = self.term
        values = direction.getArray(readonly=True)
        motion = float(sign) * values[term.boundary.dofs]
        local = term.obstacles.collision_free_step(
            term.positions(), motion, term.time, fraction=self.fraction
        )
        return term.comm.allreduce(local, op=MPI.MIN)
