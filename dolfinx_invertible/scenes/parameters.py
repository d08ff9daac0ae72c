"""The parameters every scene takes: their units, their command-line options, their validation.

Each field of :class:`Parameters` carries its command-line option in its metadata (help, metavar,
group, the scenes it applies to, and its choices from :mod:`dolfinx_invertible.choices`): the
command line builds every scene's options from them, :meth:`Parameters.validate` checks the
choices against the same registries, and the option table of docs/scenes.md is generated from
them (:func:`option_table`, which ``tools/options_table.py`` writes there).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

from dolfinx_invertible.choices import (
    ELASTIC_ROUTES,
    EXTENSIONS,
    GLOBALIZATIONS,
    LINEAR_SOLVERS,
    MODELS,
    PRECONDITIONERS,
    SCHEMES,
    TANGENTS,
    Choices,
)

__all__ = [
    "OPTION_GROUPS",
    "SCENE_KINDS",
    "Parameters",
    "make_material",
    "option_name",
    "option_table",
    "options_of",
    "shown_default",
]

#: The groups of a scene's options, in the order ``run SCENE --help`` shows them.
OPTION_GROUPS = ("material", "time stepping", "load stepping", "discretisation and solver")

#: Which scenes take an option: the ``scenes`` of its metadata, and the test on a scene class.
SCENE_KINDS: dict[str, tuple[str, Callable[[Any], bool]]] = {
    "all": ("every scene", lambda scene: True),
    "dynamic": ("dynamic scenes", lambda scene: scene.dynamic),
    "quasi-static": ("quasi-static scenes", lambda scene: not scene.dynamic),
    "contact": (
        "scenes with contact",
        lambda scene: scene.takes_friction or scene.several_bodies or scene.takes_self_contact,
    ),
    "several-bodies": ("scenes of several bodies", lambda scene: scene.several_bodies),
    "self-contact": (
        "scenes that offer self-contact",
        lambda scene: scene.takes_self_contact or bool(scene.self_contact_refusal),
    ),
    "scene-choices": ("scenes that offer a choice", lambda scene: False),
}


def _option(
    default: Any,
    help: str | dict[str, str],
    *,
    metavar: str | None = None,
    choices: Choices | None = None,
    group: str | dict[str, str] = "discretisation and solver",
    scenes: str = "all",
    flag: bool = False,
) -> Any:
    """Return a field of :class:`Parameters` with its command-line option.

    ``help`` may name the scene's default as ``{default}``; ``help`` and ``group`` may differ
    between ``"dynamic"`` and ``"quasi-static"`` scenes (a dict by kind); ``scenes`` is a key of
    :data:`SCENE_KINDS`; ``flag``: an option without value that sets True.
    """
    return dataclasses.field(
        default=default,
        metadata={
            "help": help,
            "metavar": metavar,
            "choices": choices,
            "group": group,
            "scenes": scenes,
            "flag": flag,
        },
    )


@dataclasses.dataclass
class Parameters:
    """Every value a scene run uses; a scene's defaults fill what the user leaves out.

    Attributes
    ----------
    model, extension
        Material model and invertible extension (:data:`~dolfinx_invertible.choices.MODELS`,
        :data:`~dolfinx_invertible.choices.EXTENSIONS`).
    E, nu
        Young's modulus [Pa] and Poisson ratio (plane strain in 2D).
    density
        Mass density [kg/m³] (dynamic scenes).
    eps
        Extension threshold: on J (C2, IFE) or on each singular value (C1); ``None``: the
        extension's own default (0.9 for C2 and IFE, 0.4 for C1).
    k
        C1 penalty stiffness [Pa]; ``None``: 20·E.
    dt
        Time step [s] (dynamic scenes): the largest step the controller takes.
    t_end
        End time [s] (dynamic scenes). A scene's loading schedule may be a share of it (the
        stretch bar pulls over the first 5/6, the compress block presses and releases at
        shares of it).
    t_stop
        Stop the run at this time [s] (dynamic scenes), before its end: the scene's schedule
        keeps ``t_end``, so the first steps of a run are the same whatever its length.
        ``None`` (default) or a time past ``t_end``: at ``t_end``. The command line's
        ``--steps N`` of a dynamic scene sets it to N dt.
    steps
        Load steps (quasi-static scenes).
    resolution
        Mesh resolution: cells along the body's shortest edge (scene-specific meaning).
    degree
        Lagrange degree of the displacement, 1 or 2.
    project
        Tangent (:data:`~dolfinx_invertible.choices.TANGENTS`): ``"auto"``, ``"yes"``
        (SPD-projected) or ``"no"`` (exact).
    inversion_free
        Cap every Newton step so that no point's volume falls below this fraction of its
        current value; ``None``: no cap.
    scheme
        Time integrator (:data:`~dolfinx_invertible.choices.SCHEMES`).
    damping
        Mass-proportional damping as a fraction of critical damping of the body's lowest
        elastic mode (≈ π c / L with c = √(E/ρ)); 0 means none.
    size
        Size scale of the body [m] (its length along its largest extent, scene-specific).
    mesh
        Mesh choice of scenes that offer several (e.g. ``"cube"`` or ``"armadillo-like"``), or
        a mesh file where the scene takes one.
    dimension
        Space dimension of scenes that exist in 2D and 3D.
    elastic
        How the elastic energy is assembled (:data:`~dolfinx_invertible.choices.ELASTIC_ROUTES`).
    linear_solver
        Newton's linear solves (:data:`~dolfinx_invertible.choices.LINEAR_SOLVERS`; see
        :func:`~dolfinx_invertible.solvers.options.linear_solver_options`).
    pc
        Preconditioner of the iterative path (:data:`~dolfinx_invertible.choices.
        PRECONDITIONERS`).
    globalization
        How Newton's steps are kept safe (:data:`~dolfinx_invertible.choices.GLOBALIZATIONS`).
    max_cuts
        Consecutive cuts (halvings) of a failing time or load step before the run stops with
        the step's failure. Each failed attempt costs up to a Newton solve's iteration cap, so
        a larger budget is slower to give up.
    self_contact
        Keep the body's surface from passing through itself (IPC Toolkit's barrier and
        continuous collision detection, :class:`~dolfinx_invertible.contact.BodyContactTerm`),
        in the scenes that offer it.
    count
        Number of bodies, in the scenes of several (``cubes-in-bowl``, ``links``).
    friction
        Coulomb's coefficient μ of every contact of the scene (with obstacles and between
        surfaces), lagged per time step; 0: frictionless.
    friction_velocity
        ε_v [m/s] of the smoothed friction: slip slower than this sticks (elastically). A
        fraction of the scene's sliding speeds: too small a value makes the friction force
        jump between steps, and Newton's iterations run out.
    """

    model: str = _option(
        "neo-hookean", "energy model (default: {default})", choices=MODELS, group="material"
    )
    extension: str = _option(
        "c2",
        "invertible extension (default: c2 for neo-hookean, which is undefined at J <= 0; none "
        "for the other models, which are defined through inversion)",
        choices=EXTENSIONS,
        group="material",
    )
    E: float = _option(1.0e3, "Young's modulus [Pa] (default: {default})", metavar="PA",
                       group="material")  # fmt: skip
    nu: float = _option(0.45, "Poisson ratio, in (-1, 0.5); plane strain in 2D (default: "
                        "{default})", metavar="NU", group="material")  # fmt: skip
    density: float = _option(1.0, "mass density [kg/m^3] (default: {default})", metavar="RHO",
                             group="material", scenes="dynamic")  # fmt: skip
    eps: float | None = _option(
        None,
        "extension threshold, in (0, 1): on J for c2 and ife (default 0.9), on each singular "
        "value for c1 (default 0.4)",
        metavar="EPS",
        group="material",
    )
    k: float | None = _option(None, "c1 penalty stiffness [Pa] (default: 20 E)", metavar="K",
                              group="material")  # fmt: skip
    dt: float = _option(0.01, "largest time step [s] (default: {default})", metavar="DT",
                        group="time stepping", scenes="dynamic")  # fmt: skip
    t_end: float = _option(0.4, "end time [s] (default: {default})", metavar="T",
                           group="time stepping", scenes="dynamic")  # fmt: skip
    t_stop: float | None = None
    steps: int = _option(
        4,
        {
            "quasi-static": "load steps (default: {default})",
            "dynamic": "stop after N steps of dt (at t = N dt, at most --t-end); the scene's "
            "loading keeps its schedule over --t-end",
        },
        metavar="N",
        group={"quasi-static": "load stepping", "dynamic": "time stepping"},
    )
    resolution: int = _option(4, "mesh resolution, cells along the shortest edge (default: "
                              "{default})", metavar="N")  # fmt: skip
    degree: int = _option(1, "Lagrange degree, 1 or 2 (default: {default})", metavar="{1,2}")
    project: str = _option("auto", "tangent (default: {default})", choices=TANGENTS)
    inversion_free: float | None = _option(
        None,
        "cap Newton steps so that no point's volume falls below FRACTION of its current value "
        "(default: {default})",
        metavar="FRACTION",
    )
    scheme: str = _option("backward-euler", "time integrator (default: {default})",
                          choices=SCHEMES, group="time stepping", scenes="dynamic")  # fmt: skip
    damping: float = _option(
        0.0,
        "mass-proportional damping as a fraction of critical damping of the lowest mode "
        "(default: {default})",
        metavar="ZETA",
        group="time stepping",
        scenes="dynamic",
    )
    size: float = _option(1.0, "size of the body [m] (default: {default})", metavar="L")
    mesh: str = _option("cube", "the body: one of the scene's meshes (default: {default})",
                        scenes="scene-choices")  # fmt: skip
    dimension: int = _option(3, "space dimension (default: {default})", scenes="scene-choices")
    elastic: str = _option("kernels", "how the elastic energy is assembled (default: {default})",
                           choices=ELASTIC_ROUTES)  # fmt: skip
    linear_solver: str = _option("auto", "Newton's linear solves (default: {default})",
                                 choices=LINEAR_SOLVERS)  # fmt: skip
    pc: str = _option("gamg", "AMG of the iterative path (default: {default})",
                      choices=PRECONDITIONERS)  # fmt: skip
    globalization: str = _option("auto", "how Newton's steps are kept safe (default: "
                                 "{default})", choices=GLOBALIZATIONS)  # fmt: skip
    max_cuts: int = _option(
        6,
        "consecutive halvings of a failing step before the run stops; a run stopped so goes "
        "on with --resume DIR --max-cuts M (default: {default})",
        metavar="N",
    )
    self_contact: bool = _option(
        False,
        "keep the body's surface from passing through itself: IPC Toolkit's barrier between "
        "surface primitives closer than d̂ and continuous collision detection on every Newton "
        "step (docs/contact.md)",
        scenes="self-contact",
        flag=True,
    )
    count: int = _option(1, "number of bodies (default: {default})", metavar="N",
                         scenes="several-bodies")  # fmt: skip
    friction: float = _option(0.0, "Coulomb's friction coefficient of the contacts, lagged per "
                              "time step (default: {default})", metavar="MU",
                              scenes="contact")  # fmt: skip
    friction_velocity: float = _option(1e-3, "slip speed [m/s] below which friction sticks "
                                       "(elastically) (default: {default})", metavar="EPS_V",
                                       scenes="contact")  # fmt: skip

    def validate(self) -> None:
        """Raise ``ValueError`` with the option name for any value outside its range."""
        for field in dataclasses.fields(self):
            choices = field.metadata.get("choices")
            if choices is not None:
                choices.check(getattr(self, field.name), command_line=True)
        _positive("--E", self.E)
        if not (math.isfinite(self.nu) and -1.0 < self.nu < 0.5):
            raise ValueError(f"--nu must lie in (-1, 0.5), got {self.nu!r}")
        _positive("--density", self.density)
        if self.eps is not None and not (0.0 < self.eps < 1.0):
            raise ValueError(f"--eps must lie in (0, 1), got {self.eps!r}")
        if self.k is not None and not (math.isfinite(self.k) and self.k >= 0.0):
            raise ValueError(f"--k must be a finite number >= 0, got {self.k!r}")
        _positive("--dt", self.dt)
        _positive("--t-end", self.t_end)
        if self.t_stop is not None:
            _positive("t_stop", self.t_stop)
        _whole("--steps", self.steps, 1)
        _whole("--resolution", self.resolution, 1)
        if self.degree not in (1, 2):
            raise ValueError(f"--degree must be 1 or 2, got {self.degree!r}")
        if self.inversion_free is not None and not (0.0 < self.inversion_free < 1.0):
            raise ValueError(f"--inversion-free must lie in (0, 1), got {self.inversion_free!r}")
        if not (math.isfinite(self.damping) and self.damping >= 0.0):
            raise ValueError(f"--damping must be a finite number >= 0, got {self.damping!r}")
        _positive("--size", self.size)
        if self.dimension not in (2, 3):
            raise ValueError(f"--dimension must be 2 or 3, got {self.dimension!r}")
        if self.globalization == "trust-region" and self.linear_solver == "direct":
            raise ValueError(
                "--globalization trust-region runs conjugate gradients: it needs "
                "--linear-solver iterative (or auto above the direct solve's limit), got direct"
            )
        _whole("--max-cuts", self.max_cuts, 0)
        if not (math.isfinite(self.friction) and self.friction >= 0.0):
            raise ValueError(f"--friction must be a finite number >= 0, got {self.friction!r}")
        _positive("--friction-velocity", self.friction_velocity)
        _whole("--count", self.count, 1)
        if not isinstance(self.self_contact, bool):
            raise ValueError(f"--self-contact is a flag (True or False), got {self.self_contact!r}")
        if self.elastic == "ufl" and (self.model != "neo-hookean" or self.extension != "none"):
            raise ValueError(
                "--elastic ufl (DOLFINx's own route) is plain Neo-Hookean only: use --model "
                "neo-hookean --extension none"
            )

    @property
    def stop_time(self) -> float:
        """Where a dynamic run stops: ``t_stop`` if given and before ``t_end``, else ``t_end``."""
        return self.t_end if self.t_stop is None else min(self.t_stop, self.t_end)

    @property
    def wave_speed(self) -> float:
        """C = √(E/ρ) [m/s], the scale of elastic wave speeds."""
        return math.sqrt(self.E / self.density)

    def as_dict(self) -> dict[str, Any]:
        """Return every value, as the summary records them."""
        return dataclasses.asdict(self)


def _positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


def _whole(name: str, value: Any, least: int) -> None:
    if int(value) != value or value < least:
        raise ValueError(f"{name} must be an integer >= {least}, got {value!r}")


def make_material(parameters: Parameters):
    """Return the :class:`~dolfinx_invertible.Material` the parameters describe."""
    from dolfinx_invertible.constitutive import ARAP, C1, Material, lame

    model_class = MODELS.resolve(parameters.model)
    mu, lam = lame(parameters.E, parameters.nu)
    model = model_class(mu=mu) if model_class is ARAP else model_class(mu=mu, lam=lam)
    extension_class = EXTENSIONS.resolve(parameters.extension)
    if extension_class is None:
        return Material(model)
    options: dict[str, Any] = {}
    if parameters.eps is not None:
        options["eps"] = parameters.eps
    if extension_class is C1 and parameters.k is not None:
        options["k"] = parameters.k
    return Material(model, extension_class(**options))


def shown_default(value: Any) -> str:
    """Return a default value as the help texts show it (``none``, ``0.01``, ``1000``)."""
    if value is None:
        return "none"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def option_name(field: dataclasses.Field) -> str:
    """Return the command-line option of a :class:`Parameters` field, e.g. ``--t-end``."""
    return "--" + field.name.replace("_", "-")


def options_of(field: dataclasses.Field, dynamic: bool | None = None) -> dict[str, Any] | None:
    """Return the command-line metadata of a field (None for one without an option).

    ``dynamic`` picks the help and group of a dynamic or a quasi-static scene where they
    differ; ``None`` joins the two helps.
    """
    if not field.metadata:
        return None
    metadata = dict(field.metadata)
    for key in ("help", "group"):
        value = metadata[key]
        if isinstance(value, dict):
            if dynamic is None:
                metadata[key] = "; ".join(f"{kind}: {text}" for kind, text in value.items())
            else:
                metadata[key] = value["dynamic" if dynamic else "quasi-static"]
    return metadata


def option_table() -> str:
    """Return the Markdown table of the scene options (docs/scenes.md), from the metadata."""
    lines = ["| option | scenes | meaning |", "|---|---|---|"]
    for field in dataclasses.fields(Parameters):
        metadata = options_of(field)
        if metadata is None:
            continue
        choices = metadata["choices"]
        if choices is not None:
            shown = f"`{option_name(field)} {{{','.join(choices)}}}`"
        elif metadata["flag"]:
            shown = f"`{option_name(field)}`"
        else:
            shown = f"`{option_name(field)} {metadata['metavar'] or 'VALUE'}`"
        meaning = metadata["help"].replace("{default}", shown_default(field.default))
        if choices is not None:
            meaning += ": " + "; ".join(
                f"`{name}`, {choice.description}" for name, choice in choices.items()
            )
        scenes = SCENE_KINDS[metadata["scenes"]][0]
        lines.append(f"| {shown} | {scenes} | {meaning} |")
    return "\n".join(lines)
