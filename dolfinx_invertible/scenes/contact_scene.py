"""What the contact scenes share: the obstacles as an energy term, a step cap and a record.

A :class:`ContactScene` declares its rigid obstacles (:meth:`ContactScene.obstacles`); the base
class turns them into the frictionless IPC barrier
(:class:`~dolfinx_invertible.contact.ContactTerm`, through the ``terms`` hook) and its
continuous collision detection (the ``step_limits`` hook). The term is a
:class:`~dolfinx_invertible.solvers.terms.StatefulTerm`: the run sets the obstacles' time before
every solve attempt, moving boundary vertices that a moving obstacle swept over back out of it
(:meth:`~dolfinx_invertible.contact.ContactTerm.start_step`), and logs the smallest gap, the
boundary vertices inside an obstacle (must stay 0) and those in contact at every stored step;
the summary gets them over the run (``min_gap``, ``penetrations``, ``max_contact_vertices``)
with d̂ and κ (``barrier_distance``, ``barrier_stiffness``). After every accepted step the scene
records the body's centre and its kinetic energy; the summary also gets

- ``final_centre``, ``final_low``, ``final_high``: the mean position of the body's nodes and
  the corners of its bounding box at the end;
- ``rest_distance``: how far the final shape is from the rest shape after the best rigid
  alignment, over the body's diameter
  (:func:`~dolfinx_invertible.scenes.outcome.rest_distance`);
- ``peak_kinetic_energy``, ``final_kinetic_energy``;

and ``contact.npy`` holds one row per stored step: time, smallest gap, vertices in contact,
centre (d entries) and kinetic energy.
"""

from __future__ import annotations

from typing import Any

from mpi4py import MPI

import numpy as np

from dolfinx_invertible.contact import ContactTerm, Obstacle
from dolfinx_invertible.scenes.outcome import bounding_box, rest_distance
from dolfinx_invertible.scenes.scene import Scene

__all__ = ["ContactScene"]


class ContactScene(Scene):
    """A dynamic scene whose body meets rigid obstacles; subclasses declare the obstacles.

    The barrier's stiffness scale is the run's Young's modulus (``--E``), its distance the
    contact module's rule (a tenth of the boundary vertex spacing).

    Attributes
    ----------
    contact
        The :class:`~dolfinx_invertible.contact.ContactTerm` (set by the ``terms`` hook).
    history
        One row per stored step (see the module description).
    """

    dynamic = True
    takes_friction = True

    def __init__(self, parameters, comm):
        super().__init__(parameters, comm)
        self.contact: ContactTerm | None = None
        self.history: list[list[float]] = []
        self.peak_kinetic_energy = 0.0
        self._coordinates: np.ndarray | None = None

    # -- what a contact scene declares ------------------------------------------------------
    def obstacles(self) -> list[Obstacle]:
        """Return the rigid obstacles (called once, after :meth:`create_mesh`)."""
        raise NotImplementedError

    # -- hooks ------------------------------------------------------------------------------
    def terms(self, u) -> list:
        """Return the contact barrier on ``u``, then the scene's other terms."""
        self.contact = ContactTerm(
            u,
            self.obstacles(),
            youngs_modulus=self.parameters.E,
            friction=self.parameters.friction,
            friction_velocity=self.parameters.friction_velocity,
        )
        return [self.contact, *super().terms(u)]

    def step_limits(self, u) -> list:
        """Return the continuous collision detection of the contact term, then the others."""
        return [self.contact.step_limit(), *super().step_limits(u)]

    def record(self, run) -> None:
        """Record gap, contact, centre and kinetic energy of the stored step."""
        kinetic = run.kinetic_energy or 0.0
        self.peak_kinetic_energy = max(self.peak_kinetic_energy, kinetic)
        gap, active = run.record["min_gap"], run.record["contact_vertices"]
        self.history.append([run.time, gap, active, *self.centre(run.u), kinetic])

    def checkpoint_state(self) -> dict[str, Any]:
        """Return the per-step record and the peak kinetic energy."""
        return {"history": self.history, "peak_kinetic_energy": self.peak_kinetic_energy}

    def restore(self, state: dict[str, Any]) -> None:
        """Continue the record from :meth:`checkpoint_state`."""
        self.history = [list(row) for row in state["history"]]
        self.peak_kinetic_energy = float(state["peak_kinetic_energy"])

    def quantities(self, run) -> dict[str, Any]:
        """Return the contact figures of the run (see the module description)."""
        low, high = bounding_box(self.node_positions(run.u), self.comm)
        return {
            "final_centre": self.centre(run.u).tolist(),
            "final_low": low.tolist(),
            "final_high": high.tolist(),
            "rest_distance": rest_distance(run.u),
            "peak_kinetic_energy": self.peak_kinetic_energy,
            "final_kinetic_energy": run.kinetic_energy,
        }

    def files(self, run) -> dict[str, Any]:
        """Return ``contact.npy``, the per-step record."""
        return {"contact.npy": np.asarray(self.history)}

    # -- helpers ----------------------------------------------------------------------------
    def node_positions(self, u) -> np.ndarray:
        """Return the current positions X + u of this rank's owned nodes, (n, d)."""
        space = u.function_space
        owned = space.dofmap.index_map.size_local
        d = space.mesh.geometry.dim
        if self._coordinates is None:
            self._coordinates = space.tabulate_dof_coordinates()[:owned, :d].copy()
        return self._coordinates + u.x.array[: owned * d].reshape(owned, d)

    def centre(self, u) -> np.ndarray:
        """Return the mean position of the body's nodes over all ranks (collective)."""
        positions = self.node_positions(u)
        total = self.comm.allreduce(positions.sum(axis=0), op=MPI.SUM)
        return total / self.comm.allreduce(len(positions), op=MPI.SUM)
