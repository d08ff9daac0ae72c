"""Stability study: which methods come through which scenes, over E, ν and the time step.

The matrix: the scenes ``collapse``, ``scatter``, ``compress-block`` and ``stretch-bar`` ×
eight methods (:data:`METHODS`) × ν in :data:`POISSON_RATIOS` × E in :data:`YOUNGS_MODULI`
(ρ = :data:`DENSITY`) × dt in :data:`TIME_STEPS`. Every cell is one scene run
(:func:`~dolfinx_invertible.scenes.runner.run_scene` without output, on ``MPI.COMM_SELF``) in a
pool of worker processes started as fresh interpreters (the parent has initialised MPI, so no
fork); the parent writes one CSV row per cell, one heat map per scene and a Markdown summary
that names the cause of every cell that did not come through.

Methodology (see docs/stability.md). A relaxation scene depends only on ν, the extension and
the dimensionless step dt·c/L (c = √(E/ρ), L the body size; docs/design.md, "Scale"), so every
run uses a body of :data:`SIZE` = 0.1 m and an end time in units of L/c
(:data:`SCENE_SETUPS`); the matrix's six (E, dt) pairs are then four dimensionless steps
0.01, 0.1, 1 and 10, two of them twice, which the report uses as a consistency check. The
relaxation scenes get mass-proportional damping of half the critical damping of the lowest
mode (the compress-block scene's own default): every underdamped mode then decays like
exp(−ζπ·t c/L), a factor 10⁻⁴ over the end time, so "recovered" (no inverted cell, rest
distance below 10⁻³ of the diameter) is reachable in every cell of the matrix. The stretch bar
keeps its own (no damping, its end time in units of L/c).

Causes. A cell that does not come through is diagnosed from data: a failed step is retried
once more from the last converged state with the cut step, and the last Newton iterate of that
attempt is examined (singular values of its inverted points against the corotated model's kink
σ₂ + σ₃ = 0, the inversion-free cap, the spectrum of the tangent, the step size against the
controller's floor); a relaxation that ends inverted or away from rest is continued with long
damped steps (each nearly a static minimisation from the state before) to tell a trapped,
inverted equilibrium from an end time that was too short. :func:`diagnose` maps the numbers
to a cause.

Command line: ``python -m dolfinx_invertible report stability [--quick] [--out DIR]``.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import dataclasses
import json
import math
import os
import pathlib
import queue
import re
import select
import subprocess
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from typing import Any

__all__ = [
    "COLUMNS",
    "DENSITY",
    "METHODS",
    "POISSON_RATIOS",
    "SCENES",
    "SCENE_SETUPS",
    "SIZE",
    "TIME_STEPS",
    "YOUNGS_MODULI",
    "Cell",
    "Method",
    "SceneSetup",
    "add_arguments",
    "command",
    "diagnose",
    "matrix",
    "run",
    "run_cells",
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
#: Wall-clock limit of one cell [s]; a cell over it is stopped and reported.
CELL_TIMEOUT = 900.0
#: Newton iterations allowed in the diagnostic retry of a step that hit the iteration cap.
LONG_SOLVE = 1000
#: Largest tangent assembled densely for its spectrum at a failure (unknowns).
SPECTRUM_LIMIT = 3000


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
_METHODS = {method.name: method for method in METHODS}


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
    """One cell of the matrix: a scene, a method and the material and time-step values."""

    scene: str
    method: str
    nu: float
    E: float
    dt: float

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
        method = _METHODS[self.method]
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
            resolution=setup.resolution,
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


# -- one cell (in a worker) ---------------------------------------------------------------------

#: How a failure message names the SNES and KSP reasons (SolveResult.describe).
_REASON_PATTERN = re.compile(r"failed \((?P<snes>[A-Z_]+)(?:, KSP (?P<ksp>[A-Z_0-9]+))?\)")
_CUT_PATTERN = re.compile(r"last dt = (?P<dt>[0-9.eE+-]+)")


class _Recorder:
    """What a cell tracks beyond the runner's summary, through the scene's ``record`` hook.

    At t = 0 it puts a SNES monitor on the step's minimiser, which keeps the latest Newton
    iterate and residual norms of the current solve (after a failed step: of its last attempt),
    and wraps the step limits so that their caps are kept too.
    """

    def __init__(self):
        self.run = None
        self.kinetic_max = 0.0
        self.projected = 0
        self.last_inverted_time = None
        self.iterate = None
        self.norms: list[float] = []
        self.caps: list[float] = []

    def scene(self, scene_class):
        """Return a subclass of ``scene_class`` whose ``record`` hook reports to this recorder."""
        recorder = self

        class Observed(scene_class):
            def record(self, run) -> None:
                recorder.observe(run)
                super().record(run)

        Observed.__name__ = scene_class.__name__
        return Observed

    def observe(self, run) -> None:
        """Record the state after a step (and at t = 0)."""
        if self.run is None and run.dynamics is not None:
            minimizer = run.dynamics.problem.solver
            self.iterate = minimizer.problem.create_vector()
            minimizer.snes.setMonitor(self._monitor)
            minimizer.step_limits = [_CapRecorder(limit, self) for limit in minimizer.step_limits]
        self.run = run
        kinetic = run.kinetic_energy
        if kinetic is not None:
            self.kinetic_max = max(self.kinetic_max, kinetic)
        if run.result is not None:
            self.projected += run.result.projected_iterations
        if run.diagnostics.get("inverted_cells", 0) > 0:
            self.last_inverted_time = run.time

    def _monitor(self, snes, iteration: int, norm: float) -> None:
        if iteration == 0:
            self.norms = []
            self.caps = []
        snes.getSolution().copy(self.iterate)
        self.norms.append(float(norm))


class _CapRecorder:
    """A step limit wrapped so that the caps it returns are kept."""

    def __init__(self, limit, recorder: _Recorder):
        self.limit = limit
        self.recorder = recorder

    def largest_step(self, direction, sign: float = 1.0) -> float:
        """Return the wrapped limit's cap, keeping it."""
        cap = self.limit.largest_step(direction, sign)
        self.recorder.caps.append(float(cap))
        return cap


def _initial_inverted_cells(scene_class, parameters, comm) -> int:
    """Cells with J ≤ 0 at a quadrature point in the scene's initial state."""
    import dolfinx

    from dolfinx_invertible.fem.diagnostics import cell_diagnostics, summary
    from dolfinx_invertible.fem.spaces import vector_function_space
    from dolfinx_invertible.scenes.parameters import make_material

    scene = scene_class(parameters, comm)
    scene.mesh = scene.create_mesh()
    u = dolfinx.fem.Function(vector_function_space(scene.mesh, parameters.degree))
    initial = scene.initial_displacement()
    if initial is not None:
        u.interpolate(initial)
        u.x.scatter_forward()
    return int(summary(cell_diagnostics(u, make_material(parameters)), comm)["inverted_cells"])


def _point_singular_values(u, quadrature_degree: int | None = None):
    """Return (J, σ) at every quadrature point of every owned cell: shapes (n,), (n, d)."""
    import basix
    import dolfinx
    import numpy as np
    import ufl

    from dolfinx_invertible import _compat
    from dolfinx_invertible.constitutive.svd import polar_svd
    from dolfinx_invertible.fem.forms import default_quadrature_degree

    mesh = u.function_space.mesh
    d = mesh.topology.dim
    cell_type = _compat.basix_element(u.function_space).cell_type
    if quadrature_degree is None:
        quadrature_degree = default_quadrature_degree(
            _compat.element_degree(u.function_space), cell_type
        )
    points, _ = basix.make_quadrature(cell_type, quadrature_degree)
    expression = dolfinx.fem.Expression(ufl.Identity(d) + ufl.grad(u), points)
    cells = np.arange(mesh.topology.index_map(d).size_local, dtype=np.int32)
    values = _compat.evaluate_expression(expression, mesh, cells)
    F = np.ascontiguousarray(values.reshape(-1, d, d))
    _, sigma, _ = polar_svd(F)
    return np.linalg.det(F), sigma


def _state_diagnostics(u, material, minimizer) -> dict[str, Any]:
    """Numbers about a state that tell failure causes apart (see :func:`diagnose`).

    - ``inverted_points``: quadrature points with J ≤ 0;
    - ``kink_gap``: the smallest |σ₂ + σ₃| / σ₁ over the inverted points (canonical signed
      singular values, σ₃ < 0): 0 on the corotated models' kink, where the two smallest |σ|
      swap and the stress jumps;
    - ``tangent_min``, ``tangent_max``, ``tangent_negative``: the extreme eigenvalues and the
      number of negative ones of the tangent at the state (free dofs only, dense, small
      problems only), and ``tangent_condition`` = max |λ| / min |λ|.
    """
    import numpy as np

    J, sigma = _point_singular_values(u)
    inverted = J <= 0.0
    data: dict[str, Any] = {"inverted_points": int(np.count_nonzero(inverted))}
    if inverted.any():
        s = sigma[inverted]
        data["kink_gap"] = float(np.min(np.abs(s[:, -2] + s[:, -1]) / s[:, 0]))
    problem = minimizer.problem
    free = problem.free_owned
    if 0 < len(free) <= SPECTRUM_LIMIT:
        from dolfinx_invertible import _compat

        vector = problem.create_vector()
        _compat.petsc_vector(u).copy(vector)
        tangent = problem.create_matrix()
        problem.J(None, vector, tangent, tangent)
        dense = tangent.convert("dense").getDenseArray()
        eigenvalues = np.linalg.eigvalsh(dense[np.ix_(free, free)])
        magnitude = np.abs(eigenvalues)
        data.update(
            tangent_min=float(eigenvalues[0]),
            tangent_max=float(eigenvalues[-1]),
            tangent_negative=int(np.count_nonzero(eigenvalues < 0.0)),
            tangent_condition=float(magnitude.max() / max(magnitude.min(), 1e-300)),
        )
    return data


def _failure_diagnostics(recorder: _Recorder, material) -> dict[str, Any]:
    """Examine the last Newton iterate of the failed step, then retry the step once.

    The numbers of the iterate: :func:`_state_diagnostics`, the residual norms of the attempt
    (``attempt_iterations``, ``residual_drop`` = last over first, ``residual_drop_last10``
    over the last ten iterations) and the caps of the step limits (``cap_last``, ``cap_min``,
    ``cap_median``). The retry, from the restored last converged state with the step the
    controller cut to (below its floor or past its cuts), tells whether one more cut would
    have converged (``retry``).
    """
    import dolfinx

    from dolfinx_invertible import _compat
    from dolfinx_invertible.solvers.results import SolverError

    run = recorder.run
    dynamics = run.dynamics
    minimizer = dynamics.problem.solver
    data: dict[str, Any] = {"attempt_iterations": max(len(recorder.norms) - 1, 0)}
    norms = recorder.norms
    if len(norms) > 1 and norms[0] > 0.0:
        data["residual_drop"] = norms[-1] / norms[0]
        recent = norms[-11:]
        data["residual_drop_last10"] = recent[-1] / recent[0] if recent[0] > 0.0 else None
    caps = recorder.caps
    if caps:
        data.update(
            cap_last=caps[-1], cap_min=min(caps), cap_median=float(sorted(caps)[len(caps) // 2])
        )
    state = dolfinx.fem.Function(run.u.function_space)
    recorder.iterate.copy(_compat.petsc_vector(state))
    state.x.scatter_forward()
    data.update(_state_diagnostics(state, material, minimizer))
    step = dynamics.controller.step
    data.update(retry_step=step, step_floor=dynamics.controller.minimum)
    remaining = run.parameters.t_end - dynamics.time
    try:
        dynamics.step(remaining)
        data["retry"] = "converged"
    except SolverError as error:
        data["retry"] = error.stage
    if data["retry"] == "iteration cap":
        # Would Newton get there with more iterations? Same step, a larger cap.
        _, _, _, cap = minimizer.snes.getTolerances()
        minimizer.snes.setTolerances(max_it=LONG_SOLVE)
        dynamics.controller.step = step
        try:
            data["long_retry_iterations"] = dynamics.step(remaining).newton_iterations
            data["long_retry"] = "converged"
        except SolverError as error:
            data["long_retry"] = error.stage
        finally:
            minimizer.snes.setTolerances(max_it=cap)
    return data


def overlapping_cells(u) -> int:
    """Count the cells whose deformed centroid lies inside another deformed cell (P1 simplices).

    Cells that share a vertex are not compared. A positive count means the body has passed
    through itself: an uninverted, locally injective configuration can still be tangled
    globally, and the elastic energy has no term against it.
    """
    import numpy as np

    from dolfinx_invertible import _compat

    space = u.function_space
    d = space.mesh.geometry.dim
    cells = _compat.cell_dofs(space)[:, : d + 1]
    positions = space.tabulate_dof_coordinates()[:, :d] + u.x.array.reshape(-1, d)
    simplices = positions[cells]
    centroids = simplices.mean(axis=1)
    edges = np.transpose(simplices[:, 1:] - simplices[:, :1], (0, 2, 1))
    determinant = np.linalg.det(edges)
    usable = np.abs(determinant) > 1e-14 * np.abs(edges).max() ** d
    inverse = np.zeros_like(edges)
    inverse[usable] = np.linalg.inv(edges[usable])
    offsets = centroids[None, :, :] - simplices[:, None, 0, :]
    barycentric = np.einsum("nij,nmj->nmi", inverse, offsets)
    tolerance = 1e-9
    inside = (barycentric > tolerance).all(axis=2) & (barycentric.sum(axis=2) < 1 - tolerance)
    inside &= usable[:, None]
    shared = (cells[:, None, :, None] == cells[None, :, None, :]).any(axis=(2, 3))
    inside &= ~shared
    return int(np.count_nonzero(inside.any(axis=0)))


def inverted_energy_minimum(parameters) -> float | None:
    """Return min (Ψ(F) − Ψ(I))/μ over the inverted stretches F = diag(s, s, −s), s ≤ 100.

    A negative value means inverted states lie below the rest state, so a released body can
    fall into them and keep going. ``None`` for a material without energy (IFE) or one that
    is undefined there (plain Neo-Hookean).
    """
    import numpy as np

    from dolfinx_invertible.constitutive.material import NoEnergyError
    from dolfinx_invertible.scenes.parameters import make_material

    material = make_material(parameters)
    if material.positive_only:
        return None
    stretches = np.geomspace(0.05, 100.0, 41)
    F = np.zeros((len(stretches) + 1, 3, 3))
    F[:-1, 0, 0] = F[:-1, 1, 1] = stretches
    F[:-1, 2, 2] = -stretches
    F[-1] = np.eye(3)
    try:
        energy = material.energy(F)
    except NoEnergyError:
        return None
    return float(np.min(energy[:-1] - energy[-1]) / material.model.mu)


def _continue(run, cell: Cell) -> dict[str, Any]:
    """Continue a relaxation with long damped steps: is its end state trapped or just slow."""
    import numpy as np

    from dolfinx_invertible.fem.diagnostics import cell_diagnostics, summary
    from dolfinx_invertible.scenes.outcome import body_diameter, rest_distance
    from dolfinx_invertible.solvers.results import SolverError
    from dolfinx_invertible.solvers.stepping import StepController

    dynamics = run.dynamics
    dynamics.controller = StepController(CONTINUATION_STEP * cell.time_unit)
    data: dict[str, Any] = {}
    previous = run.u.x.array.copy()
    diameter = body_diameter(run.u)

    def step_done(t: float, result) -> None:
        # How far the last step moved any node, and what it cost: an equilibrium moves by
        # nothing and takes no Newton iteration.
        motion = np.abs(run.u.x.array - previous).reshape(-1, run.mesh.geometry.dim)
        data["continued_last_motion"] = float(np.linalg.norm(motion, axis=1).max() / diameter)
        data["continued_last_newton"] = result.newton_iterations
        previous[:] = run.u.x.array

    try:
        dynamics.advance(dynamics.time + CONTINUATION_TIME * cell.time_unit, on_step=step_done)
        data["continued"] = "completed"
    except SolverError as error:
        data["continued"] = f"failed ({error.stage})"
    state = summary(cell_diagnostics(run.u, run.material), run.mesh.comm)
    # A minimum or a saddle: the exact tangent's curvature at the end state (the projected one
    # would hide a negative direction); the mass term of a 10 L/c step adds < 1e-3 of it.
    forms = getattr(dynamics.problem, "forms", None)
    if data["continued"] == "completed" and hasattr(forms, "set_projection"):
        forms.set_projection(False)
        curvature = _state_diagnostics(run.u, run.material, dynamics.problem.solver)
        data.update(
            continued_tangent_min=curvature.get("tangent_min"),
            continued_tangent_max=curvature.get("tangent_max"),
            continued_tangent_negative=curvature.get("tangent_negative"),
        )
    data.update(
        continued_inverted=state["inverted_cells"],
        continued_rest_distance=rest_distance(run.u),
        continued_time=dynamics.time / cell.time_unit,
        continued_overlap=overlapping_cells(run.u),
    )
    return data


def _parse_reason(message: str | None) -> tuple[str | None, str | None, float | None]:
    if not message:
        return None, None, None
    found = _REASON_PATTERN.search(message)
    step = _CUT_PATTERN.search(message)
    return (
        found.group("snes") if found else None,
        found.group("ksp") if found and found.group("ksp") else None,
        float(step.group("dt")) if step else None,
    )


def run_cell(cell: Cell) -> dict[str, Any]:
    """Run one cell here (``MPI.COMM_SELF``) and return its record (CSV columns and more)."""
    from mpi4py import MPI

    from dolfinx_invertible.scenes import get_scene, run_scene
    from dolfinx_invertible.scenes.parameters import Parameters, make_material

    start = time.perf_counter()
    scene_class = get_scene(cell.scene)
    parameters = Parameters(**cell.parameters())
    method = _METHODS[cell.method]
    record: dict[str, Any] = {
        **cell.identity(),
        "t_end_star": parameters.t_end / cell.time_unit,
        "resolution": parameters.resolution,
        "damping": parameters.damping,
        "size": parameters.size,
        "density": parameters.density,
        "parameters": cell.parameters(),
    }
    comm = MPI.COMM_SELF
    if method.needs_positive_volume:
        inverted = _initial_inverted_cells(scene_class, parameters, comm)
        if inverted:
            record.update(
                outcome="does_not_apply",
                reason=f"starts with {inverted} inverted cells, where plain Neo-Hookean's "
                "energy is undefined (J <= 0)",
                initial_inverted=inverted,
                wall_time_s=time.perf_counter() - start,
            )
            record["cause"], record["cause_detail"] = diagnose(record)
            return record
    recorder = _Recorder()
    summary = run_scene(recorder.scene(scene_class), parameters, output=None, comm=comm)
    snes, ksp, failed_step = _parse_reason(summary.get("reason"))
    stepping = summary.get("stepping", {})
    kinetic = summary.get("kinetic_energy_final")
    energy_scale = cell.E * SIZE**3
    record.update(
        outcome=summary["outcome"],
        failed_stage=summary.get("failed_stage"),
        snes_reason=snes,
        ksp_reason=ksp,
        failed_time_star=(
            summary["failed_time"] / cell.time_unit if summary.get("failed_time") else None
        ),
        failed_step_star=failed_step / cell.time_unit if failed_step else None,
        reason=summary.get("reason"),
        steps=summary["steps"],
        cuts=stepping.get("cuts"),
        step_min_star=(stepping["step_min"] / cell.time_unit if stepping.get("step_min") else None),
        newton_total=summary["newton_iterations"]["total"],
        newton_max=summary["newton_iterations"]["max"],
        linear_total=summary["linear_iterations"],
        projected_total=recorder.projected,
        min_J_reached=summary.get("min_J_reached"),
        final_min_J=summary.get("final_min_J"),
        final_inverted=summary.get("final_inverted"),
        max_inverted=summary.get("max_inverted"),
        rest_distance=summary.get("rest_distance"),
        kinetic_final=kinetic / energy_scale if kinetic is not None else None,
        kinetic_max=recorder.kinetic_max / energy_scale,
        last_inverted_star=(
            recorder.last_inverted_time / cell.time_unit
            if recorder.last_inverted_time is not None
            else None
        ),
        nan=bool(summary.get("nan_encountered")),
        run_time_s=summary["wall_time_s"],
    )
    run = recorder.run
    record["inverted_energy_min"] = inverted_energy_minimum(parameters)
    if run is not None and run.dynamics is not None:
        if record["outcome"] in ("stalled_inverted", "not_at_rest", "failed"):
            record["overlap_cells"] = overlapping_cells(run.u)
            record["largest_singular_value"] = float(_point_singular_values(run.u)[1].max())
        if record["outcome"] == "failed":
            record.update(_failure_diagnostics(recorder, make_material(parameters)))
        elif record["outcome"] in ("stalled_inverted", "not_at_rest"):
            record.update(_continue(run, cell))
    record["wall_time_s"] = time.perf_counter() - start
    record["cause"], record["cause_detail"] = diagnose(record)
    return record


# -- causes -------------------------------------------------------------------------------------


def diagnose(record: dict[str, Any]) -> tuple[str, str]:
    """Return (cause class, one sentence with the numbers) of a cell's outcome.

    Classes of cells that came through: ``recovered``, ``completed``; of the others, see the
    module description and docs/stability.md.
    """
    outcome = record.get("outcome")
    if outcome in ("recovered", "completed"):
        return outcome, ""
    if outcome == "does_not_apply":
        return "does not apply", record.get("reason", "")
    if outcome == "timeout":
        return "timeout", record.get("reason", "")
    if outcome == "crashed":
        return "crashed", record.get("reason", "")
    if outcome == "nan":
        return "NaN", record.get("reason", "")
    if outcome in ("stalled_inverted", "not_at_rest"):
        runaway = _runaway(record)
        if runaway:
            return "energy below rest when inverted", runaway
        continued = record.get("continued")
        inverted = record.get("continued_inverted")
        distance = record.get("continued_rest_distance")
        overlap = record.get("continued_overlap")
        state = (
            f"{record.get('final_inverted')} inverted cells, rest distance "
            f"{_number(record.get('rest_distance'))} at t = {_number(record.get('t_end_star'))} "
            f"L/c (kinetic energy {_number(record.get('kinetic_final'))} E L³)"
        )
        largest = record.get("largest_singular_value")
        if continued == "completed" and largest is not None and largest < COLLAPSED:
            return (
                "collapsed equilibrium",
                f"{state}; every singular value is below {_number(largest)}: the body sits "
                "collapsed at F ≈ 0 and stays there when continued. For an energy of I_C and J "
                "such as stable Neo-Hookean, P = μF·I_C/(I_C + 1) + λ(J − α) cof F vanishes at "
                "F = 0 in 3D: the fully collapsed state is an equilibrium with no restoring force",
            )
        if continued == "completed" and inverted == 0 and distance is not None and distance < REST:
            return (
                "end time too short",
                f"{state}; continued with damped steps of {CONTINUATION_STEP:g} L/c it "
                f"recovers by t = {_number(record.get('continued_time'))} L/c",
            )
        settled = (
            f"the last continued step moved no node by more than "
            f"{_number(record.get('continued_last_motion'))} of the diameter in "
            f"{record.get('continued_last_newton')} Newton iterations"
        )
        negative = record.get("continued_tangent_negative")
        if continued == "completed" and inverted and negative:
            return (
                "inverted saddle",
                f"{state}; continued with damped steps of {CONTINUATION_STEP:g} L/c it stays at "
                f"{inverted} inverted cells ({settled}), but the exact tangent there has "
                f"{negative} negative eigenvalues (smallest "
                f"{_number(record.get('continued_tangent_min'))}, largest "
                f"{_number(record.get('continued_tangent_max'))}): a stationary point that is "
                "not a minimum, which Newton on the projected tangent does not leave",
            )
        if continued == "completed" and inverted:
            curvature = (
                f"; the exact tangent there is positive definite (smallest eigenvalue "
                f"{_number(record.get('continued_tangent_min'))})"
                if negative == 0
                else ""
            )
            return (
                "inverted equilibrium",
                f"{state}; continued with damped steps of {CONTINUATION_STEP:g} L/c (each a "
                f"near-static minimisation) it stays at {inverted} inverted cells (rest distance "
                f"{_number(distance)}, {overlap} cells inside others; {settled}){curvature}: a "
                "local minimum of the discrete energy with inverted elements",
            )
        if continued == "completed" and overlap:
            return (
                "self-overlapping equilibrium",
                f"{state}; continued it stays uninverted at rest distance {_number(distance)} "
                f"with {overlap} cells whose centroid lies inside another cell ({settled}): the "
                "body has passed through itself, a locally injective but tangled state that is "
                "a local minimum of the elastic energy (nothing in the model keeps a body from "
                "penetrating itself)",
            )
        if continued == "completed":
            return (
                "distorted equilibrium",
                f"{state}; continued it stays uninverted but at rest distance "
                f"{_number(distance)}, without self-overlap: an equilibrium away from the rest "
                "shape",
            )
        return "continuation failed", f"{state}; the continuation {continued}"
    if outcome == "failed":
        return _diagnose_failure(record)
    return str(outcome), record.get("reason", "")


#: |σ₂ + σ₃| / σ₁ below which an inverted point counts as on the kink.
KINK = 1.0e-3
#: Inversion-free cap below which a Newton step counts as pinned.
PINNED = 1.0e-3
#: Largest singular value below which a body counts as collapsed to a point.
COLLAPSED = 0.05
#: Residual reduction over the last ten iterations below which a capped solve was converging.
CONVERGING = 0.5


def _runaway(record: dict[str, Any]) -> str:
    """Describe a body that fell into inverted states below its rest energy, or return ''."""
    lowest = record.get("inverted_energy_min")
    if lowest is None or lowest >= 0.0:
        return ""
    distance = record.get("rest_distance")
    lowest_J = record.get("final_min_J")
    expanded = (distance is not None and distance > 1.0) or (
        lowest_J is not None and lowest_J < -1.0
    )
    if not expanded:
        return ""
    return (
        f"the material's energy is below its rest energy in inverted states (min (Ψ − Ψ(I))/μ "
        f"= {_number(lowest)} along F = diag(s, s, −s)), and the body fell into them: smallest "
        f"J {_number(lowest_J)}, rest distance {_number(distance)}, kinetic energy up to "
        f"{_number(record.get('kinetic_max'))} E L³"
        + (f"; then {record.get('failed_stage')} failed" if record.get("failed_stage") else "")
    )


def _diagnose_failure(record: dict[str, Any]) -> tuple[str, str]:
    runaway = _runaway(record)
    if runaway:
        return "energy below rest when inverted", runaway
    stage = record.get("failed_stage")
    where = (
        f"at t = {_number(record.get('failed_time_star'))} L/c, stage {stage} "
        f"({record.get('snes_reason')}"
        + (f", KSP {record.get('ksp_reason')}" if record.get("ksp_reason") else "")
        + ")"
    )
    gap = record.get("kink_gap")
    cap = record.get("cap_last")
    retry = record.get("retry")
    floor = record.get("step_floor")
    below_floor = (
        record.get("retry_step") is not None and floor is not None and record["retry_step"] < floor
    )
    ending = (
        "the controller then stopped at its step floor"
        if below_floor
        else "the controller then stopped after its 6 consecutive cuts"
    )
    if retry == "converged":
        ending += ", and one more cut converges"
    tangent = (
        f"the exact tangent at the last iterate has {record.get('tangent_negative')} negative "
        f"eigenvalues, condition {_number(record.get('tangent_condition'))}"
        if record.get("tangent_negative") is not None
        else ""
    )
    if gap is not None and gap < KINK:
        return (
            "kink σ₂+σ₃=0",
            f"{where}; the last Newton iterate has inverted points with |σ₂ + σ₃|/σ₁ = "
            f"{_number(gap)}: on the kink of the energy, where the stress jumps, so Newton "
            f"cannot converge to a solution there; {ending}",
        )
    if cap is not None and cap < PINNED:
        return (
            "inversion-free cap stalls",
            f"{where}; the inversion-free cap limits the last Newton step to {_number(cap)} "
            f"(median {_number(record.get('cap_median'))}): the iterate is pinned against the "
            f"volume barrier; {ending}",
        )
    condition = record.get("tangent_condition")
    if stage == "linear solve" and condition is not None and condition > 1.0e12:
        return (
            "nearly singular tangent",
            f"{where}; the tangent at the last iterate has condition number "
            f"{_number(condition)}; {ending}",
        )
    drop = record.get("residual_drop_last10")
    if stage == "iteration cap" and drop is not None and drop < CONVERGING:
        return (
            "iteration cap while converging",
            f"{where}; Newton was converging linearly (residual × {_number(drop)} over the "
            f"last 10 iterations, × {_number(record.get('residual_drop'))} over the attempt) "
            f"but not within 50 iterations; {tangent}; {ending}",
        )
    if retry == "converged":
        return ("step-size floor" if below_floor else "cut budget", f"{where}; {ending}")
    return (
        f"solver ({stage})",
        f"{where}; residual × {_number(drop)} over the last 10 iterations; {tangent}; "
        f"inverted points {record.get('inverted_points')}; {ending}",
    )


def _number(value) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        if value == 0.0 or 1.0e-3 <= abs(value) < 1.0e4:
            return f"{value:.3g}"
        return f"{value:.2e}"
    return str(value)


# -- the pool -----------------------------------------------------------------------------------

_RESULT = "STABILITY-CELL "


def _worker_command() -> list[str]:
    return [sys.executable, "-m", "dolfinx_invertible.reports.stability", "--worker"]


class _Worker:
    """A child interpreter that runs cells sent on its stdin, one JSON line each."""

    def __init__(self, log: pathlib.Path):
        self.log_path = log
        self.log = open(log, "ab")  # noqa: SIM115 (closed in close())
        environment = dict(os.environ)
        # One thread per process: the pool is the parallelism.
        environment.setdefault("OMP_NUM_THREADS", "1")
        environment.setdefault("OPENBLAS_NUM_THREADS", "1")
        environment.setdefault("NUMBA_NUM_THREADS", "1")
        package_root = str(pathlib.Path(__file__).resolve().parents[2])
        environment["PYTHONPATH"] = os.pathsep.join(
            [package_root, *filter(None, [environment.get("PYTHONPATH")])]
        )
        self.process = subprocess.Popen(
            _worker_command(),
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self.log,
            env=environment,
        )
        self._buffer = b""

    def send(self, cell: Cell) -> None:
        self.process.stdin.write((json.dumps(dataclasses.asdict(cell)) + "\n").encode())
        self.process.stdin.flush()

    def receive(self, timeout: float) -> dict[str, Any] | None:
        """Return the next result, or ``None`` on timeout or when the worker died."""
        deadline = time.monotonic() + timeout
        stream = self.process.stdout.fileno()
        while True:
            while b"\n" in self._buffer:
                line, self._buffer = self._buffer.split(b"\n", 1)
                text = line.decode(errors="replace")
                if text.startswith(_RESULT):
                    return json.loads(text[len(_RESULT) :])
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            ready, _, _ = select.select([stream], [], [], min(remaining, 5.0))
            if ready:
                chunk = os.read(stream, 1 << 16)
                if not chunk:
                    return None
                self._buffer += chunk

    def tail(self) -> str:
        self.log.flush()
        with contextlib.suppress(OSError):
            return self.log_path.read_bytes()[-2000:].decode(errors="replace").strip()
        return ""

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.process.stdin.close()
        try:
            self.process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self.log.close()

    def kill(self) -> None:
        self.process.kill()
        self.process.wait()
        self.log.close()


def _expected_cost(cell: Cell) -> float:
    """Relative cost of a cell (steps × cells of the mesh), to start the longest first."""
    parameters = cell.parameters()
    steps = parameters["t_end"] / cell.dt
    cells = {"collapse": 1.0, "scatter": 1.0, "compress-block": 4.0, "stretch-bar": 5.0}
    resolution = parameters["resolution"] / 4.0
    return steps * cells[cell.scene] * resolution**3


def run_cells(
    cells: Sequence[Cell],
    *,
    workers: int = 2,
    timeout: float = CELL_TIMEOUT,
    log_directory: pathlib.Path,
    on_result: Callable[[dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """Run cells in a pool of worker processes; return their records in the cells' order.

    A worker that dies or exceeds ``timeout`` on a cell is replaced, and the cell is recorded
    with the outcome ``crashed`` or ``timeout``.
    """
    order = sorted(range(len(cells)), key=lambda index: -_expected_cost(cells[index]))
    tasks: queue.Queue[int] = queue.Queue()
    for index in order:
        tasks.put(index)
    results: list[dict[str, Any] | None] = [None] * len(cells)
    lock = threading.Lock()
    errors: list[BaseException] = []
    live: set[_Worker] = set()
    stopping = threading.Event()

    def serve(number: int) -> None:
        log = log_directory / f"worker-{number}.log"
        worker = None
        try:
            while not stopping.is_set():
                try:
                    index = tasks.get_nowait()
                except queue.Empty:
                    break
                cell = cells[index]
                if worker is None:
                    worker = _Worker(log)
                    with lock:
                        live.add(worker)
                worker.send(cell)
                result = worker.receive(timeout)
                if stopping.is_set():
                    break
                if result is None:
                    alive = worker.process.poll() is None
                    tail = worker.tail()
                    with lock:
                        live.discard(worker)
                    worker.kill()
                    worker = None
                    result = _lost_cell(cell, "timeout" if alive else "crashed", timeout, tail)
                with lock:
                    results[index] = result
                    if on_result is not None:
                        on_result(result)
        except BaseException as error:  # reported by the caller's thread
            errors.append(error)
        finally:
            if worker is not None and not stopping.is_set():
                with lock:
                    live.discard(worker)
                worker.close()

    threads = [
        threading.Thread(target=serve, args=(number,), daemon=True)
        for number in range(max(1, min(workers, len(cells))))
    ]
    for thread in threads:
        thread.start()
    try:
        for thread in threads:
            while thread.is_alive():
                thread.join(timeout=1.0)
    except BaseException:
        # Interrupted: stop the workers rather than leave them running their cells.
        stopping.set()
        with lock:
            for worker in list(live):
                with contextlib.suppress(OSError, ValueError):
                    worker.kill()
            live.clear()
        raise
    if errors:
        raise errors[0]
    return [result for result in results if result is not None]


def _lost_cell(cell: Cell, outcome: str, timeout: float, tail: str) -> dict[str, Any]:
    reason = (
        f"the cell ran longer than {timeout:.0f} s and was stopped"
        if outcome == "timeout"
        else "the worker process died: " + (tail.splitlines()[-1] if tail else "no output")
    )
    record = {**cell.identity(), "outcome": outcome, "reason": reason}
    record["cause"], record["cause_detail"] = diagnose(record)
    return record


def _worker() -> int:
    """Run cells read from stdin (one JSON line each); write each record as one line."""
    import logging
    import warnings

    from mpi4py import MPI  # noqa: F401 (initialised before DOLFINx)

    from dolfinx_invertible.io.step_log import json_ready
    from dolfinx_invertible.scenes.runner import RunInterrupted

    for name in ("ffcx", "UFL", "dolfinx", "numba"):
        logging.getLogger(name).setLevel(logging.WARNING)
    warnings.simplefilter("ignore")
    output = sys.stdout
    # Anything the libraries print goes to the log, not into the results.
    sys.stdout = sys.stderr
    for line in sys.stdin:
        if not line.strip():
            continue
        cell = Cell(**json.loads(line))
        try:
            record = run_cell(cell)
        except RunInterrupted:
            return 1
        except Exception as error:  # a defect: reported as the cell's outcome, not hidden
            import traceback

            traceback.print_exc()
            record = _lost_cell(cell, "crashed", 0.0, f"{type(error).__name__}: {error}")
        output.write(_RESULT + json.dumps(json_ready(record)) + "\n")
        output.flush()
    return 0


# -- outputs ------------------------------------------------------------------------------------

#: CSV columns, in order (see docs/stability.md for their meaning).
COLUMNS = (
    "scene",
    "method",
    "nu",
    "E",
    "dt",
    "dt_star",
    "t_end_star",
    "resolution",
    "damping",
    "outcome",
    "cause",
    "failed_stage",
    "snes_reason",
    "ksp_reason",
    "failed_time_star",
    "failed_step_star",
    "steps",
    "cuts",
    "step_min_star",
    "newton_total",
    "newton_max",
    "linear_total",
    "projected_total",
    "min_J_reached",
    "final_min_J",
    "final_inverted",
    "max_inverted",
    "rest_distance",
    "kinetic_final",
    "kinetic_max",
    "last_inverted_star",
    "continued_inverted",
    "continued_rest_distance",
    "attempt_iterations",
    "residual_drop",
    "residual_drop_last10",
    "inverted_points",
    "kink_gap",
    "cap_last",
    "cap_median",
    "tangent_min",
    "tangent_max",
    "tangent_negative",
    "tangent_condition",
    "retry",
    "nan",
    "wall_time_s",
    "cause_detail",
    "reason",
)

#: Outcome shown in the heat maps -> (label, colour, legend text).
_DISPLAY = {
    "recovered": ("R", "#1a9850", "recovered"),
    "completed": ("C", "#1a9850", "completed (stretch bar)"),
    "completed_inverted": ("C·inv", "#a6d96a", "completed, cells inverted at the end"),
    "not_at_rest": ("N", "#fee08b", "not at rest (uninverted)"),
    "stalled_inverted": ("S", "#fc8d59", "stalled inverted"),
    "failed": ("F", "#d73027", "failed at: ls line search, lin linear solve, cap iteration cap"),
    "nan": ("NaN", "#542788", "NaN"),
    "does_not_apply": ("n/a", "#d9d9d9", "does not apply (starts inverted)"),
    "timeout": ("T", "#525252", "timeout"),
    "crashed": ("X", "#000000", "worker crashed"),
}
_STAGES = {
    "line search": "ls",
    "linear solve": "lin",
    "iteration cap": "cap",
    "step check": "chk",
    "NaN": "nan",
}


def display_outcome(record: dict[str, Any]) -> str:
    """Return the heat-map category of a record (completed runs split by inverted cells)."""
    outcome = record.get("outcome", "crashed")
    if outcome == "completed" and (record.get("final_inverted") or 0) > 0:
        return "completed_inverted"
    return outcome


def write_csv(records: Sequence[dict[str, Any]], path: pathlib.Path) -> None:
    """Write one row per record with :data:`COLUMNS`."""
    with path.open("w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=COLUMNS, extrasaction="ignore")
        writer.writeheader()
        for record in records:
            writer.writerow({name: _csv_value(record.get(name)) for name in COLUMNS})


def _csv_value(value):
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.6g}"
    return value


def _points(records: Iterable[dict[str, Any]]) -> list[tuple[float, float, float]]:
    return sorted({(record["nu"], record["E"], record["dt"]) for record in records})


def _exponent(value: float) -> str:
    exponent = math.log10(value)
    if abs(exponent - round(exponent)) < 1e-9:
        return f"1e{int(round(exponent))}"
    return f"{value:g}"


def plot_heat_map(records: Sequence[dict[str, Any]], scene: str, path: pathlib.Path) -> None:
    """Draw the outcomes of one scene: methods × (ν, E, dt), one coloured cell each."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import to_rgb
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    rows = [record for record in records if record["scene"] == scene]
    methods = [method for method in METHODS if any(r["method"] == method.name for r in rows)]
    points = _points(rows)
    by_key = {(r["method"], r["nu"], r["E"], r["dt"]): r for r in rows}
    width = max(6.0, 0.62 * len(points) + 3.2)
    figure = Figure(figsize=(width, 0.5 * len(methods) + 2.6))
    FigureCanvasAgg(figure)
    axes = figure.add_axes([2.9 / width, 0.3, 1.0 - 3.1 / width, 0.5])
    for row, method in enumerate(methods):
        for column, (nu, E, dt) in enumerate(points):
            record = by_key.get((method.name, nu, E, dt))
            if record is None:
                continue
            category = display_outcome(record)
            label, colour, _ = _DISPLAY.get(category, ("?", "#ffffff", category))
            if category == "failed":
                label += "\n" + _STAGES.get(record.get("failed_stage") or "", "?")
            axes.add_patch(
                _rectangle(column, row, colour),
            )
            red, green, blue = to_rgb(colour)
            dark = 0.299 * red + 0.587 * green + 0.114 * blue < 0.5
            axes.text(
                column + 0.5,
                row + 0.5,
                label,
                ha="center",
                va="center",
                fontsize=7,
                color="white" if dark else "black",
            )
    axes.set_xlim(0, len(points))
    axes.set_ylim(len(methods), 0)
    axes.set_yticks([row + 0.5 for row in range(len(methods))])
    axes.set_yticklabels([method.label for method in methods], fontsize=8)
    axes.set_xticks([column + 0.5 for column in range(len(points))])
    axes.set_xticklabels(
        [
            f"{_exponent(E)}\n{_exponent(dt)}\n{dt / (SIZE / math.sqrt(E / DENSITY)):g}"
            for _, E, dt in points
        ],
        fontsize=7,
    )
    axes.tick_params(length=0)
    axes.text(
        -0.01, -0.085, "E [Pa]\ndt [s]\ndt·c/L", transform=axes.transAxes, ha="right",
        va="top", fontsize=7,
    )  # fmt: skip
    for column, (nu, _, _) in enumerate(points):
        if column == 0 or points[column - 1][0] != nu:
            if column:
                axes.axvline(column, color="black", linewidth=1.5)
            span = sum(1 for point in points if point[0] == nu)
            ratio = 2.0 * nu / (1.0 - 2.0 * nu)
            axes.text(
                column + span / 2,
                -0.25,
                f"ν = {nu:g} (λ/μ = {ratio:.3g})",
                ha="center",
                va="bottom",
                fontsize=8,
            )
    for spine in axes.spines.values():
        spine.set_visible(False)
    present = []
    for record in rows:
        category = display_outcome(record)
        if category not in present:
            present.append(category)
    handles = [
        Patch(facecolor=_DISPLAY[category][1], edgecolor="black", label=_DISPLAY[category][2])
        for category in _DISPLAY
        if category in present
    ]
    figure.legend(
        handles=handles, loc="lower center", ncol=min(4, max(1, len(handles))), fontsize=7,
        frameon=False,
    )  # fmt: skip
    figure.suptitle(
        f"{scene}: outcome per method, ν, E and dt\n(ρ = {DENSITY:g} kg/m³, L = {SIZE:g} m, "
        "c = √(E/ρ))",
        fontsize=9,
    )
    figure.savefig(path, dpi=110)


def _rectangle(column: int, row: int, colour: str):
    from matplotlib.patches import Rectangle

    return Rectangle((column, row), 1.0, 1.0, facecolor=colour, edgecolor="white", linewidth=1.0)


def _table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return lines


def _label(method: str) -> str:
    return _METHODS[method].label if method in _METHODS else method


def _came_through(record: dict[str, Any]) -> bool:
    return record.get("outcome") in ("recovered", "completed")


def summary_lines(
    records: Sequence[dict[str, Any]],
    *,
    quick: bool,
    wall_time: float,
    load: tuple[float, float] | None,
    command_line: str,
) -> list[str]:
    """Return the Markdown summary of the study (see docs/stability.md)."""
    lines = [
        "# Stability study" + (" (quick subset)" if quick else ""),
        "",
        f"{len(records)} cells; wall time {wall_time / 60:.1f} min with {_workers_used(records)} "
        "worker processes"
        + (f", load average {load[0]:.2f} before and {load[1]:.2f} after" if load else "")
        + ".",
        "",
        f"Regenerate: `{command_line}`",
        "",
        "## Method",
        "",
        f"Scenes {', '.join(SCENES)}; body size L = {SIZE:g} m, ρ = {DENSITY:g} kg/m³, "
        "c = √(E/ρ); every run ends at max(end time, "
        f"{MINIMUM_STEPS} dt). End times in L/c and damping (fraction of critical damping of "
        "the lowest mode π c/L):",
        "",
    ]
    setup_rows = []
    for scene in SCENES:
        cell = Cell(scene, METHODS[0].name, POISSON_RATIOS[0], YOUNGS_MODULI[1], TIME_STEPS[0])
        parameters = cell.parameters()
        setup_rows.append(
            (
                scene,
                parameters["resolution"],
                f"{parameters['t_end'] / cell.time_unit:g}",
                f"{parameters['damping']:g}",
            )
        )
    lines += _table(("scene", "resolution", "end time [L/c]", "damping ζ"), setup_rows)
    lines += [
        "",
        "Outcomes: *recovered* (every step converged, no inverted cell, rest distance < "
        f"{REST:g} of the diameter at the end), *stalled inverted* (converged, cells still "
        "inverted), *not at rest* (converged, uninverted, rest distance above the tolerance), "
        "*completed* (stretch bar), *failed* (a step failed after all cuts; the stage and "
        "PETSc reasons are given), *NaN*, *does not apply* (plain Neo-Hookean from an "
        "inverted start). A cell that did not come through is diagnosed from data: a "
        "relaxation is continued with damped steps of "
        f"{CONTINUATION_STEP:g} L/c for {CONTINUATION_TIME:g} L/c (each a near-static "
        "minimisation from the state before): if it then recovers, the end time was too short; "
        "if it stays inverted, it sits in an inverted local minimum. A failed step's last "
        "Newton iterate is examined (inverted points' singular values against the kink "
        "σ₂ + σ₃ = 0, inversion-free caps, the tangent's spectrum) and the step is retried once "
        "with the cut step.",
        "",
        "## Headline",
        "",
    ]
    counts = Counter(display_outcome(record) for record in records)
    lines += _table(
        ("outcome", "cells"),
        [(_DISPLAY[name][2], counts[name]) for name in _DISPLAY if counts[name]],
    )
    lines += ["", "Per method (all scenes):", ""]
    categories = [name for name in _DISPLAY if counts[name]]
    method_rows = []
    for method in METHODS:
        mine = [record for record in records if record["method"] == method.name]
        if not mine:
            continue
        tally = Counter(display_outcome(record) for record in mine)
        method_rows.append((method.label, *(tally[name] or "" for name in categories)))
    lines += _table(("method", *(_DISPLAY[name][0] for name in categories)), method_rows)
    legend = ", ".join(f"{_DISPLAY[name][0]} {_DISPLAY[name][2]}" for name in categories)
    lines += ["", f"Legend: {legend}."]
    lines += ["", "## The study's goals", ""]
    nan_cells = [r for r in records if r.get("outcome") == "nan" or r.get("nan")]
    lines.append(f"- NaN anywhere: {len(nan_cells)} cells.")
    c2_small = [r for r in records if r["method"] == "nh-c2" and r["dt"] == TIME_STEPS[0]]
    c2_missed = [record for record in c2_small if not _came_through(record)]
    lines.append(
        f"- Neo-Hookean + C2 with dt = {TIME_STEPS[0]:g} s: {len(c2_small) - len(c2_missed)} of "
        f"{len(c2_small)} cells recovered or completed"
        + (
            "; the others: "
            + "; ".join(
                f"{r['scene']} ν = {r['nu']:g}, E = {r['E']:g}: {r['outcome']} ({r.get('cause')})"
                for r in c2_missed
            )
            if c2_missed
            else ""
        )
        + "."
    )
    lines += ["", "### C2 against IFE on the paper's relaxations (collapse, scatter)", ""]
    paper_rows = []
    for scene in ("collapse", "scatter"):
        for nu in sorted({record["nu"] for record in records}):
            row = [scene, f"{nu:g} ({2 * nu / (1 - 2 * nu):.3g})"]
            for method in ("nh-c2", "nh-ife"):
                mine = [
                    r for r in records if r["scene"] == scene and r["method"] == method
                    and r["nu"] == nu
                ]  # fmt: skip
                good = sum(1 for r in mine if _came_through(r))
                row.append(f"{good}/{len(mine)}" if mine else "–")
            paper_rows.append(row)
    lines += _table(("scene", "ν (λ/μ)", "C2 recovered", "IFE recovered"), paper_rows)
    lines += ["", "## Scale invariance", ""]
    lines += _invariance_lines(records)
    lines += ["", "## Every cell that did not come through, with its cause", ""]
    missed = [record for record in records if not _came_through(record)]
    by_cause: dict[str, list[dict[str, Any]]] = {}
    for record in missed:
        by_cause.setdefault(record.get("cause") or "unknown", []).append(record)
    lines += _table(
        ("cause", "cells", "methods"),
        [
            (
                cause,
                len(group),
                ", ".join(sorted({_label(r["method"]) for r in group})),
            )
            for cause, group in sorted(by_cause.items(), key=lambda item: -len(item[1]))
        ],
    )
    lines += ["", *_CAUSE_TEXT_LINES(by_cause)]
    lines += [""]
    lines += _table(
        ("scene", "method", "ν", "E", "dt", "outcome", "cause: data"),
        [
            (
                r["scene"],
                _label(r["method"]),
                f"{r['nu']:g}",
                f"{r['E']:g}",
                f"{r['dt']:g}",
                r.get("outcome"),
                f"**{r.get('cause')}**: {r.get('cause_detail') or r.get('reason') or ''}".replace(
                    "|", "/"
                ),
            )
            for r in missed
        ],
    )
    return lines + [""]


def _workers_used(records: Sequence[dict[str, Any]]) -> str:
    return str(records[0].get("workers", "")) if records and records[0].get("workers") else "the"


#: What each cause class means, for the Markdown.
CAUSES = {
    "end time too short": "the relaxation was still untangling or still moving at the end "
    "time; continued with damped steps it recovers (methodological: the end time).",
    "inverted equilibrium": "continued with near-static damped steps the body stays with "
    "inverted cells: a local minimum of the discrete energy with inverted elements (physical "
    "for the discrete model).",
    "inverted saddle": "continued with near-static damped steps the body stays with inverted "
    "cells at a stationary point where the exact tangent has negative eigenvalues: not a "
    "minimum; Newton on the projected tangent converges to any stationary point (a solver "
    "limitation, not the energy's).",
    "distorted equilibrium": "continued, the body stays uninverted but away from its rest "
    "shape, without self-overlap: an equilibrium of the method that is not the rest state.",
    "collapsed equilibrium": "the body stays collapsed at F ≈ 0, a stationary point of the "
    "energy where the stress vanishes (stable Neo-Hookean in 3D): a property of the energy.",
    "self-overlapping equilibrium": "continued, the body stays uninverted but part of it lies "
    "inside another part: it passed through itself (no contact in the model), a tangled local "
    "minimum of the elastic energy.",
    "energy below rest when inverted": "the material's energy is lower in inverted states than "
    "at rest (Neo-Hookean + C1 at large λ/μ), so the released body falls into ever more "
    "expanded inverted states: a property of the energy, not of the solver.",
    "kink σ₂+σ₃=0": "the last Newton iterate has inverted points on σ₂ + σ₃ = 0, where an "
    "energy of the signed singular values that is not even in each pair of them (corotated, "
    "fixed corotated) has a kink and its stress jumps: Newton cannot converge to a solution "
    "with a point there, and the controller cuts until it gives up.",
    "iteration cap while converging": "Newton was still converging (linearly, on the "
    "projected tangent) when it reached its 50 iterations, at every step the controller tried.",
    "cut budget": "the controller gave up after 6 consecutive cuts; one more cut converges.",
    "inversion-free cap stalls": "the inversion-free cap limits every Newton step to nearly "
    "zero: the iterate is pinned against the volume barrier.",
    "step-size floor": "the controller cut the step to its floor (dt/4096) and one more cut "
    "converges: the solution moves through a region Newton resolves only with tiny steps.",
    "nearly singular tangent": "the tangent at the last iterate is numerically singular.",
    "does not apply": "plain Neo-Hookean cannot start from inverted cells.",
}


def _CAUSE_TEXT_LINES(by_cause: dict[str, list[dict[str, Any]]]) -> list[str]:  # noqa: N802
    return [f"- **{cause}**: {CAUSES[cause]}" for cause in by_cause if cause in CAUSES]


def _invariance_lines(records: Sequence[dict[str, Any]]) -> list[str]:
    """Compare cells with the same dt·c/L (the same dimensionless problem)."""
    groups: dict[tuple, list[dict[str, Any]]] = {}
    for record in records:
        star = round(math.log10(record["dt_star"]), 6)
        groups.setdefault((record["scene"], record["method"], record["nu"], star), []).append(
            record
        )
    pairs = [group for group in groups.values() if len(group) > 1]
    if not pairs:
        return ["No two cells share a dimensionless step."]
    same_outcome = sum(1 for group in pairs if len({r.get("outcome") for r in group}) == 1)
    same_newton = sum(1 for group in pairs if len({r.get("newton_total") for r in group}) == 1)
    spreads = [
        (max(totals) - min(totals)) / max(max(totals), 1)
        for totals in (
            [r["newton_total"] for r in group if r.get("newton_total") is not None]
            for group in pairs
        )
        if totals
    ]
    lines = [
        f"Cells with the same dt·c/L (different E and dt) are the same dimensionless problem: "
        f"{len(pairs)} such pairs, {same_outcome} with the same outcome, {same_newton} with the "
        f"same total of Newton iterations; the largest difference in that total is "
        f"{100 * max(spreads, default=0.0):.1f} % (E and dt differ by factors that are not "
        "powers of two, so the twins round differently).",
    ]
    differing = [group for group in pairs if len({r.get("outcome") for r in group}) > 1]
    for group in differing:
        first = group[0]
        lines.append(
            f"- differs: {first['scene']}, {_label(first['method'])}, ν = {first['nu']:g}, "
            f"dt·c/L = {first['dt_star']:g}: "
            + ", ".join(f"E = {r['E']:g}: {r.get('outcome')}" for r in group)
        )
    return lines


def run(
    output_directory,
    *,
    quick: bool = False,
    workers: int = 2,
    resume: bool = False,
    scenes: Sequence[str] | None = None,
    methods: Sequence[str] | None = None,
    progress: bool = False,
    command_line: str | None = None,
) -> dict[str, Any]:
    """Run the study (or its quick subset) and write the CSV, the heat maps and the summary.

    Parameters
    ----------
    output_directory
        Where ``stability.csv``, ``stability.md``, ``stability_SCENE.png`` and ``cells.jsonl``
        (every record in full) go.
    quick
        The quick subset (:func:`matrix`).
    workers
        Worker processes.
    resume
        Reuse the records in ``cells.jsonl`` of cells of this matrix that ran with the same
        parameters.
    scenes, methods
        Restrict the matrix (for development); ``None``: all.
    progress
        Print one line per finished cell.
    command_line
        The command to state in the summary; by default the one that regenerates this run.

    Returns
    -------
    dict
        ``files``, ``cells``, ``outcomes`` (counts), ``causes`` (counts), ``wall_time_s``.
    """
    directory = pathlib.Path(output_directory)
    directory.mkdir(parents=True, exist_ok=True)
    unknown = [name for name in scenes or () if name not in SCENES]
    unknown += [name for name in methods or () if name not in _METHODS]
    if unknown:
        raise ValueError(
            f"unknown scene or method {', '.join(unknown)}; scenes: {', '.join(SCENES)}; "
            f"methods: {', '.join(_METHODS)}"
        )
    cells = [
        cell
        for cell in matrix(quick)
        if (not scenes or cell.scene in scenes) and (not methods or cell.method in methods)
    ]
    records_path = directory / "cells.jsonl"
    done: dict[tuple, dict[str, Any]] = {}
    if resume and records_path.exists():
        from dolfinx_invertible.io.step_log import json_ready

        wanted = {cell.key: cell for cell in cells}
        for line in records_path.read_text().splitlines():
            with contextlib.suppress(ValueError, KeyError):
                record = json.loads(line)
                key = (record["scene"], record["method"], record["nu"], record["E"], record["dt"])
                cell = wanted.get(key)
                if cell is not None and record.get("parameters") == json_ready(cell.parameters()):
                    # The causes are read from the data again: the diagnosis may have changed.
                    record["cause"], record["cause_detail"] = diagnose(record)
                    done[key] = record
    todo = [cell for cell in cells if cell.key not in done]
    load_before = _load_average()
    begin = time.perf_counter()
    logs = directory / "logs"
    logs.mkdir(exist_ok=True)
    with records_path.open("a" if resume else "w") as stream:
        for record in done.values():
            if not resume:
                stream.write(json.dumps(record) + "\n")

        def finished(record: dict[str, Any]) -> None:
            record["workers"] = workers
            stream.write(json.dumps(record) + "\n")
            stream.flush()
            if progress:
                print(
                    f"{record['scene']:>14} {_label(record['method']):>34} ν={record['nu']:<5g} "
                    f"E={record['E']:<7g} dt={record['dt']:<6g} {record.get('outcome'):>17} "
                    f"{record.get('cause') or '':<26} {record.get('wall_time_s') or 0:6.1f} s",
                    flush=True,
                )

        new = run_cells(todo, workers=workers, log_directory=logs, on_result=finished)
    wall_time = time.perf_counter() - begin
    by_key = {**done, **{tuple(_key(record)): record for record in new}}
    records = [by_key[cell.key] for cell in cells if cell.key in by_key]
    if not any(record.get("outcome") == "crashed" for record in records):
        for log in logs.glob("worker-*.log"):
            log.unlink()
        with contextlib.suppress(OSError):
            logs.rmdir()
    files = {"csv": "stability.csv", "summary": "stability.md"}
    write_csv(records, directory / files["csv"])
    for scene in SCENES:
        if any(record["scene"] == scene for record in records):
            name = f"stability_{scene.replace('-', '_')}.png"
            plot_heat_map(records, scene, directory / name)
            files[f"heat_map_{scene}"] = name
    if command_line is None:
        command_line = (
            "python -m dolfinx_invertible report stability"
            + (" --quick" if quick else "")
            + f" --out {directory}"
        )
    lines = summary_lines(
        records,
        quick=quick,
        wall_time=wall_time,
        load=(load_before, _load_average()) if load_before is not None else None,
        command_line=command_line,
    )
    (directory / files["summary"]).write_text("\n".join(lines))
    return {
        "files": files,
        "cells": len(records),
        "outcomes": dict(Counter(display_outcome(record) for record in records)),
        "causes": dict(Counter(record.get("cause") for record in records)),
        "wall_time_s": wall_time,
    }


def _key(record: dict[str, Any]) -> tuple:
    return (record["scene"], record["method"], record["nu"], record["E"], record["dt"])


def _load_average() -> float | None:
    try:
        return os.getloadavg()[0]
    except OSError:
        return None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``report stability``."""
    from dolfinx_invertible.reports import add_output_arguments

    add_output_arguments(
        parser,
        "results/reports/stability",
        "the quick subset: every scene and method at nu = 0.45, E = 1e5, dt = 1e-2, and C2 and "
        "corotated also at E = 1e7, dt = 1e-3 (the same dt c/L)",
    )
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument(
        "--resume", action="store_true", help="reuse finished cells of cells.jsonl in --out"
    )
    parser.add_argument(
        "--scene", action="append", choices=SCENES, help="only this scene (repeatable)"
    )
    parser.add_argument(
        "--method",
        action="append",
        choices=[method.name for method in METHODS],
        help="only this method (repeatable)",
    )
    parser.add_argument("--quiet", action="store_true", help="no line per finished cell")


def command(arguments: argparse.Namespace) -> int:
    """Run ``report stability``; exit code 1 if a worker crashed or a cell timed out."""
    import signal

    if arguments.workers < 1:
        raise SystemExit("--workers must be at least 1")

    def interrupt(number, frame):
        raise KeyboardInterrupt(f"stopped by {signal.Signals(number).name}")

    signal.signal(signal.SIGTERM, interrupt)
    words = ["python -m dolfinx_invertible report stability"]
    if arguments.quick:
        words.append("--quick")
    words.append(f"--out {arguments.out}")
    for scene in arguments.scene or ():
        words.append(f"--scene {scene}")
    for method in arguments.method or ():
        words.append(f"--method {method}")
    result = run(
        arguments.out,
        quick=arguments.quick,
        workers=arguments.workers,
        resume=arguments.resume,
        scenes=arguments.scene,
        methods=arguments.method,
        progress=not arguments.quiet,
        command_line=" ".join(words),
    )
    outcomes = ", ".join(f"{name} {count}" for name, count in sorted(result["outcomes"].items()))
    print(
        f"{result['cells']} cells in {result['wall_time_s'] / 60:.1f} min: {outcomes}; "
        f"written to {arguments.out}"
    )
    lost = result["outcomes"].get("crashed", 0) + result["outcomes"].get("timeout", 0)
    return 1 if lost else 0


if __name__ == "__main__":
    if sys.argv[1:] == ["--worker"]:
        sys.exit(_worker())
