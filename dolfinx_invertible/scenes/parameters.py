"""The parameters every scene takes, their units, their validation and the material they make."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from dolfinx_invertible.constitutive import (
    ARAP,
    C1,
    C2,
    IFE,
    Corotated,
    FixedCorotated,
    Material,
    NeoHookean,
    StableNeoHookean,
    StVK,
    lame,
)

__all__ = [
    "EXTENSION_NAMES",
    "MODEL_NAMES",
    "OUTPUT_FORMATS",
    "PROJECT_CHOICES",
    "Parameters",
    "make_material",
]

#: Command-line model names and the classes they stand for.
MODEL_NAMES = {
    "neo-hookean": NeoHookean,
    "corotated": Corotated,
    "fixed-corotated": FixedCorotated,
    "stable-neo-hookean": StableNeoHookean,
    "arap": ARAP,
    "stvk": StVK,
}
#: Command-line extension names.
EXTENSION_NAMES = {"none": None, "c1": C1, "c2": C2, "ife": IFE}
#: ``--linear-solver`` choices (the solvers' ``LINEAR_SOLVERS``; kept here so that the command
#: line's parser does not load PETSc).
LINEAR_SOLVERS = ("auto", "direct", "iterative")
#: ``--globalization`` choices (the solvers' ``GLOBALIZATIONS``, kept here for the same reason).
GLOBALIZATIONS = ("auto", "line-search", "trust-region")
#: ``--pc`` choices: the preconditioners of the iterative path.
PRECONDITIONERS = ("gamg", "hypre")
#: ``--format`` choices: XDMF, ADIOS2 VTX, or both (see :func:`~.runner.run_scene`).
OUTPUT_FORMATS = ("xdmf", "vtx", "both")

#: ``--project`` choices and the value HyperelasticProblem takes.
PROJECT_CHOICES = {"auto": "auto", "yes": True, "no": False}


@dataclasses.dataclass
class Parameters:
    """Every value a scene run uses; a scene's defaults fill what the user leaves out.

    Attributes
    ----------
    model, extension
        Material model and invertible extension (command-line names).
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
        ``None`` (default) or a time past ``t_end``: at ``t_end``.
    steps
        Load steps (quasi-static scenes).
    resolution
        Mesh resolution: cells along the body's shortest edge (scene-specific meaning).
    degree
        Lagrange degree of the displacement, 1 or 2.
    project
        Tangent: ``"auto"``, ``"yes"`` (SPD-projected) or ``"no"`` (exact).
    inversion_free
        Cap every Newton step so that no point's volume falls below this fraction of its
        current value; ``None``: no cap.
    scheme
        Time integrator: ``"backward-euler"`` or ``"bdf2"``.
    damping
        Mass-proportional damping as a fraction of critical damping of the body's lowest
        elastic mode (≈ π c / L with c = √(E/ρ)); 0 means none.
    size
        Size scale of the body [m] (its length along its largest extent, scene-specific).
    mesh
        Mesh choice of scenes that offer several (e.g. ``"cube"`` or ``"armadillo-like"``).
    dimension
        Space dimension of scenes that exist in 2D and 3D.
    elastic
        How the elastic energy is assembled: ``"kernels"`` (this package) or ``"ufl"``
        (DOLFINx's own route: plain Neo-Hookean in UFL, compiled by FFCx).
    linear_solver
        ``"auto"``, ``"direct"`` or ``"iterative"`` (see
        :func:`~dolfinx_invertible.solvers.options.linear_solver_options`).
    pc
        Preconditioner of the iterative path: ``"gamg"`` or ``"hypre"``.
    globalization
        ``"auto"`` (the trust region on the iterative path, the line search on the direct one),
        ``"line-search"`` or ``"trust-region"`` (the iterative path only; see
        :mod:`~dolfinx_invertible.solvers.trust_region`).
    max_cuts
        Consecutive cuts (halvings) of a failing time or load step before the run stops with
        the step's failure. Each failed attempt costs up to a Newton solve's iteration cap, so
        a larger budget is slower to give up; a run whose first step has to resolve motion
        finer than the mesh's (the scatter on fine meshes, docs/performance.md) needs more.
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

    model: str = "neo-hookean"
    extension: str = "c2"
    E: float = 1.0e3
    nu: float = 0.45
    density: float = 1.0
    eps: float | None = None
    k: float | None = None
    dt: float = 0.01
    t_end: float = 0.4
    t_stop: float | None = None
    steps: int = 4
    resolution: int = 4
    degree: int = 1
    project: str = "auto"
    inversion_free: float | None = None
    scheme: str = "backward-euler"
    damping: float = 0.0
    size: float = 1.0
    mesh: str = "cube"
    dimension: int = 3
    elastic: str = "kernels"
    linear_solver: str = "auto"
    pc: str = "gamg"
    globalization: str = "auto"
    max_cuts: int = 6
    self_contact: bool = False
    count: int = 1
    friction: float = 0.0
    friction_velocity: float = 1e-3

    def validate(self) -> None:
        """Raise ``ValueError`` with the option name for any value outside its range."""
        if self.model not in MODEL_NAMES:
            raise ValueError(f"--model must be one of {', '.join(MODEL_NAMES)}, got {self.model!r}")
        if self.extension not in EXTENSION_NAMES:
            raise ValueError(
                f"--extension must be one of {', '.join(EXTENSION_NAMES)}, got {self.extension!r}"
            )
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
        if int(self.steps) != self.steps or self.steps < 1:
            raise ValueError(f"--steps must be an integer >= 1, got {self.steps!r}")
        if int(self.resolution) != self.resolution or self.resolution < 1:
            raise ValueError(f"--resolution must be an integer >= 1, got {self.resolution!r}")
        if self.degree not in (1, 2):
            raise ValueError(f"--degree must be 1 or 2, got {self.degree!r}")
        if self.project not in PROJECT_CHOICES:
            raise ValueError(f"--project must be one of auto, yes, no, got {self.project!r}")
        if self.inversion_free is not None and not (0.0 < self.inversion_free < 1.0):
            raise ValueError(f"--inversion-free must lie in (0, 1), got {self.inversion_free!r}")
        if self.scheme not in ("backward-euler", "bdf2"):
            raise ValueError(f"--scheme must be backward-euler or bdf2, got {self.scheme!r}")
        if not (math.isfinite(self.damping) and self.damping >= 0.0):
            raise ValueError(f"--damping must be a finite number >= 0, got {self.damping!r}")
        _positive("--size", self.size)
        if self.dimension not in (2, 3):
            raise ValueError(f"--dimension must be 2 or 3, got {self.dimension!r}")
        if self.elastic not in ("kernels", "ufl"):
            raise ValueError(f"--elastic must be kernels or ufl, got {self.elastic!r}")
        if self.linear_solver not in LINEAR_SOLVERS:
            raise ValueError(
                f"--linear-solver must be one of {', '.join(LINEAR_SOLVERS)}, "
                f"got {self.linear_solver!r}"
            )
        if self.globalization not in GLOBALIZATIONS:
            raise ValueError(
                f"--globalization must be one of {', '.join(GLOBALIZATIONS)}, "
                f"got {self.globalization!r}"
            )
        if self.globalization == "trust-region" and self.linear_solver == "direct":
            raise ValueError(
                "--globalization trust-region runs conjugate gradients: it needs "
                "--linear-solver iterative (or auto above the direct solve's limit), got direct"
            )
        if int(self.max_cuts) != self.max_cuts or self.max_cuts < 0:
            raise ValueError(f"--max-cuts must be an integer >= 0, got {self.max_cuts!r}")
        if not (math.isfinite(self.friction) and self.friction >= 0.0):
            raise ValueError(f"--friction must be a finite number >= 0, got {self.friction!r}")
        _positive("--friction-velocity", self.friction_velocity)
        if int(self.count) != self.count or self.count < 1:
            raise ValueError(f"--count must be an integer >= 1, got {self.count!r}")
        if not isinstance(self.self_contact, bool):
            raise ValueError(f"--self-contact is a flag (True or False), got {self.self_contact!r}")
        if self.pc not in PRECONDITIONERS:
            raise ValueError(f"--pc must be one of {', '.join(PRECONDITIONERS)}, got {self.pc!r}")
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


def make_material(parameters: Parameters) -> Material:
    """Return the material the parameters describe."""
    model_class = MODEL_NAMES[parameters.model]
    mu, lam = lame(parameters.E, parameters.nu)
    model = model_class(mu=mu) if model_class is ARAP else model_class(mu=mu, lam=lam)
    extension_class = EXTENSION_NAMES[parameters.extension]
    if extension_class is None:
        return Material(model)
    options: dict[str, Any] = {}
    if parameters.eps is not None:
        options["eps"] = parameters.eps
    if extension_class is C1 and parameters.k is not None:
        options["k"] = parameters.k
    return Material(model, extension_class(**options))
