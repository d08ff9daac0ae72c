"""Energy terms with time and state of their own: the protocol a scene run drives them by.

An :class:`~dolfinx_invertible.solvers.problem.EnergyTerm` adds to Π what no form expresses
(a contact barrier). Some such terms also have a time (moving obstacles, friction lagged per
step), a state a continued run needs (an adapted stiffness) and figures of their own (the
smallest distance so far). A :class:`StatefulTerm` says so through the methods below; a scene
run (:func:`~dolfinx_invertible.scenes.runner.run_scene`) finds them among the terms the scene
declares and

- calls :meth:`~StatefulTerm.start_step` with the stepper's update, before every attempt of a
  step and after a failed one;
- calls :meth:`~StatefulTerm.check_start` once, before the first step;
- adds :meth:`~StatefulTerm.step_quantities` to every step's log line and
  :meth:`~StatefulTerm.summary_quantities` to the summary;
- saves :meth:`~StatefulTerm.checkpoint_state` in the run's checkpoint and gives it back to
  :meth:`~StatefulTerm.restore` when the run continues.

A failed solve's message adds :meth:`~StatefulTerm.describe_state` at its last iterate
(:meth:`~dolfinx_invertible.solvers.problem.EnergyProblem.locate`), so that it says where the
term stood, e.g. which bodies were closest.

Each method has a default that does nothing, so a term implements what it has. Outside a scene
run, a script calls them itself (e.g. ``boundary_update=term.start_step``).

A term whose Hessian has negative curvature (a contact barrier: its distance is concave along
the surfaces) can add the exact Hessian or its SPD projection; :class:`ProjectableHessian` lets
it follow the problem's tangent, exact in Newton's local phase and projected outside it, so that
Newton converges quadratically near a solution instead of linearly.
"""

from __future__ import annotations

from typing import Any

__all__ = ["ProjectableHessian", "StatefulTerm", "stateful_terms"]


class StatefulTerm:
    """Base class of the energy terms with time, state and figures of their own."""

    def start_step(self, t: float) -> None:
        """Start a step ending at (pseudo-)time ``t`` from the current ``u`` (collective).

        ``u`` holds the attempt's initial guess, which the term may adjust. Also called with a
        step's start after a failed attempt, and with the current time when a run starts or
        continues.
        """

    def check_start(self) -> None:
        """Raise ``ValueError`` if the initial state is not one the term can start from."""

    def step_quantities(self) -> dict[str, Any]:
        """Return the term's figures of the current state for the step log (collective).

        Called once per stored step (the initial state included); the term may accumulate
        them for :meth:`summary_quantities`.
        """
        return {}

    def summary_quantities(self) -> dict[str, Any]:
        """Return the term's figures of the whole run for the summary."""
        return {}

    def checkpoint_state(self) -> dict[str, Any]:
        """Return what a continued run needs besides the displacement, as JSON values."""
        return {}

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`checkpoint_state`."""

    def describe_state(self) -> str:
        """Return one clause on the term's state at the current ``u`` (collective).

        Called where a solve failed, at its last iterate; empty says nothing.
        """
        return ""


class ProjectableHessian:
    """A term's choice between its exact Hessian and its SPD projection.

    ``project_hessian`` ``None`` follows the problem:
    :class:`~dolfinx_invertible.HyperelasticProblem` with ``project="auto"`` calls
    :meth:`set_projection` with the tangent it assembles (exact in Newton's local phase, where
    the minimiser replaces a direction that is not a descent direction by the projected
    tangent's); with a fixed ``project`` it asks for the projected Hessian, since nothing would
    replace a bad direction. ``True`` or ``False`` fix the choice. Until a problem says
    otherwise, a term that follows adds the projected Hessian.
    """

    def _choose_projection(self, project_hessian: bool | None) -> None:
        if not (project_hessian is None or isinstance(project_hessian, bool)):
            raise ValueError(
                f"project_hessian must be None, True or False, got {project_hessian!r}"
            )
        self.project_hessian = project_hessian
        #: Whether the Hessian added now is the SPD-projected one.
        self.projected = True if project_hessian is None else project_hessian

    def set_projection(self, projected: bool) -> None:
        """Add the projected (``True``) or exact Hessian from now on, unless the choice is fixed."""
        if self.project_hessian is None:
            self.projected = bool(projected)


def stateful_terms(terms) -> list[StatefulTerm]:
    """Return the terms among ``terms`` that are :class:`StatefulTerm` instances, in order."""
    return [term for term in terms if isinstance(term, StatefulTerm)]
