"""The study matrix: scenes × methods × ν × E × dt, and the scene setup of every cell."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

__all__ = [
    "CONTINUATION_STEP",
    "CONTINUATION_TIME",
    "Cell",
    "DENSITY",
    "METHODS",
    "METHODS_BY_NAME",
    "MINIMUM_STEPS",
    "Method",
    "POISSON_RATIOS",
    "QUICK_PAIR",
    "QUICK_POINT",
    "RELAXATION_DAMPING",
    "REST",
    "SCENES",
    "SCENE_SETUPS",
    "SIZE",
    "SceneSetup",
    "TIME_STEPS",
    "YOUNGS_MODULI",
    "matrix",
    "method_label",
]

#: Scenes of the study.
SCENES = ("collapse", "scatter", "compress-block", "stretch-bar")
#: Poisson ratios (λ/μ = 1.5, 9, 49, 499).
POISSON_RATIOS = (0.3, 0.45, 0.49, 0.499)
#: Young's moduli [Pa].
YOUNGS_MODULI = (1.0e3, 1.0e5, 1.0e7)
#: Time steps [s] (the largest step the controller takes).
TIME_STEPS = (1.0e-3, 1.0e-2)
#: Mass density [kg/m³].
DENSITY = 1000.0
#: Body size L [m]: the cube's edge, the block's width, the bar's length.
SIZE = 0.1
#: Fraction of critical damping of the lowest mode for the relaxation scenes.
RELAXATION_DAMPING = 0.5
#: Rest distance (relative to the diameter) below which a relaxed body is at rest.
REST = 1.0e-3
#: Continuation of a relaxation that did not recover: steps of this many L/c ...
CONTINUATION_STEP = 10.0
#: ... up to this much further time, in L/c.
CONTINUATION_TIME = 200.0
#: Fewest nominal steps of a run: the end time is at least this many time steps, so that a
#: large step still resolves the loading of a driven scene and leaves a relaxation steps to
#: come to rest in.
MINIMUM_STEPS = 40


@dataclasses.dataclass(frozen=True)
class Method:
    """A column of methods: a material, and how it is assembled and stepped.

    Attributes
    ----------
    name
        Identifier in the CSV.
    label
        Name in the figures and tables.
    model, extension
        Command-line names of the material model and the extension.
    elastic
        ``"kernels"`` or ``"ufl"`` (DOLFINx's own route).
    inversion_free
        Fraction of the inversion-free step cap, or ``None``.
    """

    name: str
    label: str
    model: str
    extension: str
    elastic: str = "kernels"
    inversion_free: float | None = None

    @property
    def needs_positive_volume(self) -> bool:
        """Plain Neo-Hookean: its energy is undefined at J ≤ 0, so it cannot start inverted."""
        return self.model == "neo-hookean" and self.extension == "none"


#: The methods, in the order of the figures' rows.
METHODS = (
    Method("nh-c1", "Neo-Hookean + C1", "neo-hookean", "c1"),
    Method("nh-c2", "Neo-Hookean + C2", "neo-hookean", "c2"),
    Method("nh-ife", "Neo-Hookean + IFE", "neo-hookean", "ife"),
    Method("corotated", "corotated", "corotated", "none"),
    Method("fixed-corotated", "fixed corotated", "fixed-corotated", "none"),
    Method("stable-neo-hookean", "stable Neo-Hookean", "stable-neo-hookean", "none"),
    Method(
        "nh-inversion-free",
        "Neo-Hookean, inversion-free steps",
        "neo-hookean",
        "none",
        inversion_free=0.1,
    ),
    Method("nh-ufl", "Neo-Hookean in UFL (DOLFINx)", "neo-hookean", "none", elastic="ufl"),
)
#: The methods by name.
METHODS_BY_NAME = {method.name: method for method in METHODS}


def method_label(method: str) -> str:
    """Return the display label of a method's name (the name itself if unknown)."""
    return METHODS_BY_NAME[method].label if method in METHODS_BY_NAME else method


@dataclasses.dataclass(frozen=True)
class SceneSetup:
    """How a scene runs in the study.

    Attributes
    ----------
    resolution
        The scene's mesh resolution.
    end_time
        End time in units of L/c; ``None``: the scene's own, converted to L/c.
    damping
        Fraction of critical damping of the lowest mode; ``None``: the scene's own.
    """

    resolution: int
    end_time: float | None = None
    damping: float | None = None


#: Per scene: the collapse and the scatter (the paper's relaxations) relax over 6 L/c with
#: damping; the compress block keeps its own end time (10 L/c) and damping (0.5), the stretch
#: bar its end time (12 L/c, no damping). Resolution 4 is the scenes' default; the compress
#: block and the stretch bar, 4 and 5 times as many cells at one resolution, run at 2 (192 and
#: 240 cells), which keeps the full matrix within 45 minutes on two cores. Every
#: run takes at least :data:`MINIMUM_STEPS` steps (see :meth:`Cell.parameters`).
SCENE_SETUPS = {
    "collapse": SceneSetup(4, 6.0, RELAXATION_DAMPING),
    "scatter": SceneSetup(4, 6.0, RELAXATION_DAMPING),
    "compress-block": SceneSetup(2),
    "stretch-bar": SceneSetup(2),
}


@dataclasses.dataclass(frozen=True)
class Cell:
    """One cell of the matrix: a scene, a method and the material and time-step values.

    ``resolution`` is the scene's mesh resolution; ``None`` takes :data:`SCENE_SETUPS`'s.
    """

    scene: str
    method: str
    nu: float
    E: float
    dt: float
    resolution: int | None = None

    @property
    def key(self) -> tuple[str, str, float, float, float]:
        """The cell's identity (scene, method, ν, E, dt)."""
        return (self.scene, self.method, self.nu, self.E, self.dt)

    def identity(self) -> dict[str, Any]:
        """Return the first columns of the cell's record: its axes and dt·c/L."""
        return {
            "scene": self.scene,
            "method": self.method,
            "nu": self.nu,
            "E": self.E,
            "dt": self.dt,
            "dt_star": self.dimensionless_step,
        }

    @property
    def wave_speed(self) -> float:
        """The wave speed c = √(E/ρ) [m/s]."""
        return math.sqrt(self.E / DENSITY)

    @property
    def time_unit(self) -> float:
        """L/c [s]: the time a wave takes to cross the body."""
        return SIZE / self.wave_speed

    @property
    def dimensionless_step(self) -> float:
        """dt·c/L."""
        return self.dt / self.time_unit

    def parameters(self) -> dict[str, Any]:
        """Return the scene parameters of this cell (the scene's defaults filled in)."""
        from dolfinx_invertible.scenes import get_scene
        from dolfinx_invertible.scenes.parameters import Parameters

        scene_class = get_scene(self.scene)
        setup = SCENE_SETUPS[self.scene]
        values = dataclasses.asdict(Parameters())
        values.update(scene_class.defaults)
        own = Parameters(**values)
        method = METHODS_BY_NAME[self.method]
        end_time = setup.end_time
        if end_time is None:
            end_time = own.t_end * own.wave_speed / own.size
        end_time = max(end_time, MINIMUM_STEPS * self.dimensionless_step)
        values.update(
            model=method.model,
            extension=method.extension,
            elastic=method.elastic,
            inversion_free=method.inversion_free,
            E=self.E,
            nu=self.nu,
            density=DENSITY,
            dt=self.dt,
            t_end=end_time * self.time_unit,
            size=SIZE,
            resolution=setup.resolution if self.resolution is None else self.resolution,
            damping=own.damping if setup.damping is None else setup.damping,
        )
        return values


#: The quick subset's (ν, E, dt) for every scene and method: dt·c/L = 1 ...
QUICK_POINT = (0.45, 1.0e5, 1.0e-2)
#: ... and the same dimensionless step with E and dt scaled (10⁷ Pa, 10⁻³ s) for these methods,
#: a check of scale invariance.
QUICK_PAIR = ((0.45, 1.0e7, 1.0e-3), ("nh-c2", "corotated"))


def matrix(quick: bool = False) -> list[Cell]:
    """Return the cells of the full matrix or of the quick subset.

    The quick subset: every scene and method at ν = 0.45, E = 10⁵ Pa, dt = 10⁻² s
    (dt·c/L = 1), and Neo-Hookean + C2 and corotated also at E = 10⁷ Pa, dt = 10⁻³ s, the
    same dimensionless problem (40 cells of 40 steps each).
    """
    if quick:
        point, (pair, pair_methods) = QUICK_POINT, QUICK_PAIR
        return [
            Cell(scene, method.name, *values)
            for scene in SCENES
            for method in METHODS
            for values in (point, pair)
            if values == point or method.name in pair_methods
        ]
    points = [(nu, E, dt) for nu in POISSON_RATIOS for E in YOUNGS_MODULI for dt in TIME_STEPS]
    return [
        Cell(scene, method.name, nu, E, dt)
        for scene in SCENES
        for method in METHODS
        for nu, E, dt in points
    ]
