"""What a scene declares: its geometry, its defaults, its loads; :mod:`.runner` does the rest.

A scene is a subclass of :class:`Scene` in a module of its own under
:mod:`dolfinx_invertible.scenes`, written with the public API only, so that each doubles as an
example. It sets the class attributes (name, description, paper figure, defaults, whether it is
dynamic) and overrides the hooks it needs; everything a scene does not declare it does not get
(no mass in a quasi-static scene, no gravity unless asked for, no energy kernel unless a line
search or a report reads it).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from dolfinx_invertible.meshes import is_mesh_file, read_mesh
from dolfinx_invertible.scenes.parameters import Parameters

__all__ = ["Scene"]


class Scene:
    """Base class of the scenes; one instance per run.

    Class attributes
    ----------------
    name
        Command-line name, e.g. ``"collapse"``.
    description
        One line for ``dolfinx-invertible list``.
    figure
        The paper figure it reproduces, or what benchmark it is.
    dynamic
        Implicit dynamics (``True``) or quasi-static load stepping (``False``).
    timed_by_end
        Whether the scene's loading is scheduled in shares of ``t_end`` (a plate that presses
        over the first half of the run, say): a resumed run keeps its ``t_end``.
    relaxation
        A body released from a deformed state: the summary gets ``rest_distance``,
        ``recovered`` and the relaxation outcome.
    defaults
        Values of :class:`~dolfinx_invertible.scenes.parameters.Parameters` this scene changes.
    choices
        Allowed values of the scene-specific parameters (``mesh``, ``dimension``); a parameter
        not listed here does not apply to the scene.
    takes_mesh_file
        Whether ``--mesh PATH`` (a gmsh ``.msh`` or XDMF file) may replace the scene's body:
        scenes whose loads do not depend on the body's shape. Such a scene's
        :meth:`create_mesh` fits the file's body into the box its own body occupies
        (:meth:`read_mesh_file`).
    takes_self_contact
        Whether ``--self-contact`` may keep the body's surface from passing through itself.
    takes_friction
        Whether the scene has contact with obstacles, which ``--friction`` makes frictional
        (contact between surfaces, several bodies or ``--self-contact``, takes it too).
    several_bodies
        Whether the scene is made of ``count`` bodies (``--count N``) in contact with each
        other: :meth:`surface_contact` is always on.
    self_contact_refusal
        Why a scene refuses ``--self-contact`` where a user may expect it (the error says so).

    Parameters
    ----------
    parameters
        The values of this run (defaults filled in).
    comm
        The MPI communicator.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    figure: ClassVar[str] = ""
    dynamic: ClassVar[bool] = True
    timed_by_end: ClassVar[bool] = False
    relaxation: ClassVar[bool] = False
    defaults: ClassVar[dict[str, Any]] = {}
    choices: ClassVar[dict[str, Sequence[Any]]] = {}
    takes_mesh_file: ClassVar[bool] = False
    takes_self_contact: ClassVar[bool] = False
    self_contact_refusal: ClassVar[str] = ""
    several_bodies: ClassVar[bool] = False
    takes_friction: ClassVar[bool] = False

    def __init__(self, parameters: Parameters, comm):
        self.parameters = parameters
        self.comm = comm
        #: The mesh :meth:`create_mesh` made (set by the runner before the other hooks).
        self.mesh = None
        self._surface_contact = None

    @classmethod
    def check_parameters(cls, parameters: Parameters) -> None:
        """Raise ``ValueError`` if a scene-specific parameter does not apply to this scene."""
        if parameters.count != Parameters.count and not cls.several_bodies:
            raise ValueError(f"--count: the {cls.name} scene has one body")
        if parameters.friction > 0.0 and not (
            cls.takes_friction or cls.several_bodies or parameters.self_contact
        ):
            raise ValueError(
                f"--friction: the {cls.name} scene has no contact"
                + (" (add --self-contact)" if cls.takes_self_contact else "")
            )
        if parameters.self_contact and not cls.takes_self_contact:
            reason = cls.self_contact_refusal or f"the {cls.name} scene does not offer it"
            raise ValueError(f"--self-contact: {reason}")
        names = tuple(cls.choices.get("mesh", (Parameters.mesh,)))
        if parameters.mesh in names:
            return
        if is_mesh_file(parameters.mesh):
            if not cls.takes_mesh_file:
                raise ValueError(f"--mesh: the {cls.name} scene does not take a mesh file")
            return
        files = " or a .msh/.xdmf file" if cls.takes_mesh_file else ""
        raise ValueError(f"--mesh must be {' or '.join(names)}{files}, got {parameters.mesh!r}")

    @property
    def mesh_file(self) -> Path | None:
        """Return the user's mesh file (``--mesh PATH``), or None for the scene's own body."""
        if self.takes_mesh_file and is_mesh_file(self.parameters.mesh):
            return Path(self.parameters.mesh)
        return None

    def read_mesh_file(
        self, box: tuple[Sequence[float], Sequence[float]], anchor: Sequence[int]
    ) -> Any:
        """Return the body in :attr:`mesh_file`, checked and fitted into ``box``.

        Scaled the same in every direction to the largest size that fits the box (low, high),
        and placed per direction by ``anchor``: −1 against the box's low side, 0 centred, +1
        against its high side (see :func:`~dolfinx_invertible.meshes.read_mesh`).
        """
        return read_mesh(self.comm, self.mesh_file, box=box, anchor=anchor)

    # -- what every scene provides ----------------------------------------------------------
    def create_mesh(self):
        """Return the reference mesh."""
        raise NotImplementedError

    # -- optional hooks ---------------------------------------------------------------------
    def initial_displacement(self) -> Callable[[np.ndarray], np.ndarray] | None:
        """Return u₀(x) for ``Function.interpolate`` (x has shape (3, n)), or None for 0."""
        return None

    def initial_velocity(self) -> Callable[[np.ndarray], np.ndarray] | None:
        """Return v₀(x) for ``Function.interpolate``, or None for rest (dynamic scenes)."""
        return None

    def boundary_conditions(self, space) -> tuple[list, Callable[[float], None] | None]:
        """Return the Dirichlet conditions and a function setting their values at time t."""
        return [], None

    def external_energy(self, u):
        """Return a UFL potential in ``u`` (tractions, springs) or None."""
        return None

    def set_load(self, t: float) -> None:
        """Set loads for pseudo-time t in [0, 1] (quasi-static scenes)."""

    @classmethod
    def end_time(cls, parameters: Parameters) -> float:
        """Return where a run stops: ``parameters.stop_time`` (dynamic) or pseudo-time 1."""
        return parameters.stop_time if cls.dynamic else 1.0

    def gravity(self) -> Sequence[float] | None:
        """Return the body acceleration g, or None (dynamic scenes)."""
        return None

    def terms(self, u) -> list:
        """Return energy terms that are not forms (e.g. contact barriers), built on ``u``.

        A term that is a :class:`~dolfinx_invertible.solvers.terms.StatefulTerm` is driven by
        the run: its time update before every attempt, its start-up check, its figures in the
        step log and the summary, its state in the checkpoint. By default the contact between
        the bodies' surfaces (:meth:`surface_contact`) where the scene has it; a subclass that
        adds terms of its own extends this list.
        """
        contact = self.surface_contact(u)
        return [] if contact is None else [contact]

    def step_limits(self, u) -> list:
        """Return step caps (e.g. continuous collision detection), built on ``u``.

        Called after :meth:`terms`; by default the cap of the surface contact, if any.
        """
        contact = self.surface_contact(u)
        return [] if contact is None else [contact.step_limit()]

    def surface_contact(self, u):
        """Return the contact between the bodies' surfaces on ``u`` (made once), or None.

        With ``--self-contact``, or always in a scene of several bodies: a
        :class:`~dolfinx_invertible.contact.BodyContactTerm` whose barrier stiffness follows
        the run's Young's modulus; it refuses surfaces that cross at the start and logs
        ``min_distance`` and ``intersections`` at every stored step.
        """
        if not (self.parameters.self_contact or self.several_bodies):
            return None
        if self._surface_contact is None:
            from dolfinx_invertible.contact import BodyContactTerm

            self._surface_contact = BodyContactTerm(
                u,
                youngs_modulus=self.parameters.E,
                friction=self.parameters.friction,
                friction_velocity=self.parameters.friction_velocity,
            )
        return self._surface_contact

    def drawn_obstacles(self) -> list:
        """Return what pictures draw beside the body: objects with ``gap(x, t)``.

        The contact scenes' obstacles by default; a scene whose loads are not obstacles (a
        pressing plate) may give a shape to draw for them.
        """
        obstacles = getattr(self, "obstacles", None)
        return list(obstacles()) if callable(obstacles) else []

    def problem_options(self) -> dict[str, Any]:
        """Return further options of the problem (e.g. ``quadrature_degree``)."""
        return {}

    def record(self, run) -> None:
        """Look at the :class:`~.run.Run` after every accepted step (e.g. to sample it)."""

    def checkpoint_state(self) -> dict[str, Any]:
        """Return what :meth:`record` accumulated that the summary reads, as JSON values.

        A continued run (``--resume``) gives it back to :meth:`restore`; a scene whose
        quantities come from the state alone has none.
        """
        return {}

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`checkpoint_state`."""

    def quantities(self, run) -> dict[str, Any]:
        """Return the scene's own summary values at the end (collective)."""
        return {}

    def files(self, run) -> dict[str, Any]:
        """Return extra data to save next to the output, name -> array (rank 0 writes them)."""
        return {}
