"""Build a scene's run from its declaration: mesh, unknown, terms, problem and stepper.

:func:`build_run` turns a :class:`~dolfinx_invertible.scenes.Scene` subclass and its
:class:`~dolfinx_invertible.scenes.Parameters` into a :class:`~dolfinx_invertible.scenes.run.Run`
whose stepper is ready to advance: an :class:`~dolfinx_invertible.ImplicitDynamics` for a dynamic
scene, a :class:`~dolfinx_invertible.solvers.quasi_static.QuasiStatic` of a
:class:`~dolfinx_invertible.HyperelasticProblem` for a quasi-static one, both under a
:class:`~dolfinx_invertible.StepController` with the scene's nominal step and ``max_cuts``. The
scene's :class:`~dolfinx_invertible.solvers.terms.StatefulTerm` terms are driven from here on:
their time update joins the stepper's, their start-up check runs before anything is solved.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from time import perf_counter
from typing import Any

import dolfinx

from dolfinx_invertible.choices import TANGENTS
from dolfinx_invertible.fem.mesh import reproducible_partitioning
from dolfinx_invertible.fem.spaces import vector_function_space
from dolfinx_invertible.scenes.parameters import Parameters, make_material
from dolfinx_invertible.scenes.run import Run
from dolfinx_invertible.scenes.scene import Scene
from dolfinx_invertible.solvers.dynamics import ImplicitDynamics
from dolfinx_invertible.solvers.hyperelastic import HyperelasticProblem
from dolfinx_invertible.solvers.quasi_static import QuasiStatic
from dolfinx_invertible.solvers.stepping import StepController
from dolfinx_invertible.solvers.terms import stateful_terms

__all__ = ["build_run"]


def build_run(
    scene_class: type[Scene],
    parameters: Parameters,
    comm,
    *,
    petsc_options: dict[str, Any] | None = None,
    problem_options: dict[str, Any] | None = None,
) -> Run:
    """Return the run of a scene, built and checked, at its initial state (collective).

    ``problem_options`` override the scene's and the parameters' options of the problem (see
    :class:`~dolfinx_invertible.HyperelasticProblem`). ``ValueError`` (e.g. surfaces that
    cross at the start) before anything is solved. The mesh is partitioned the same way on
    every run (:func:`~dolfinx_invertible.reproducible_partitioning`).
    """
    started = perf_counter()
    scene = scene_class(parameters, comm)
    material = make_material(parameters)
    reproducible_partitioning()
    mesh = scene.mesh = scene.create_mesh()
    space = vector_function_space(mesh, parameters.degree)
    u = dolfinx.fem.Function(space, name="displacement")
    initial = scene.initial_displacement()
    if initial is not None:
        u.interpolate(initial)
        u.x.scatter_forward()
    bcs, boundary_update = scene.boundary_conditions(space)
    terms, limits = scene.terms(u), scene.step_limits(u)
    stateful = stateful_terms(terms)
    for term in stateful:
        term.check_start()
    options = _problem_options(scene, parameters, petsc_options, terms, limits)
    options.update(problem_options or {})
    if scene.dynamic:
        update = _joined([boundary_update, *(term.start_step for term in stateful)])
        stepper = _dynamics(scene, parameters, material, u, bcs, update, options)
    else:
        update = _joined([scene.set_load, *(term.start_step for term in stateful)])
        problem = HyperelasticProblem(
            u, material, bcs, external_energy=scene.external_energy(u), **options
        )
        controller = StepController(1.0 / parameters.steps, max_cuts=int(parameters.max_cuts))
        stepper = QuasiStatic(problem, update, parameters.steps, controller=controller)
    return Run(
        scene=scene,
        parameters=parameters,
        material=material,
        mesh=mesh,
        u=u,
        stepper=stepper,
        terms=stateful,
        started=started,
    )


def _problem_options(
    scene: Scene, parameters: Parameters, petsc_options, terms: list, limits: list
) -> dict[str, Any]:
    """Return the problem's options: the scene's, then the parameters', its terms and caps."""
    options = dict(scene.problem_options())
    options.setdefault("project", TANGENTS.value(parameters.project))
    options.setdefault("petsc_options", petsc_options)
    if parameters.inversion_free is not None:
        options.setdefault("inversion_free", parameters.inversion_free)
    for name in ("elastic", "linear_solver", "pc", "globalization"):
        options.setdefault(name, getattr(parameters, name))
    if terms:
        options.setdefault("terms", terms)
    if limits:
        options.setdefault("step_limits", limits)
    return options


def _dynamics(scene: Scene, parameters: Parameters, material, u, bcs, update, options):
    """Return the time stepper of a dynamic scene."""
    velocity = None
    initial_velocity = scene.initial_velocity()
    if initial_velocity is not None:
        velocity = dolfinx.fem.Function(u.function_space)
        velocity.interpolate(initial_velocity)
        velocity.x.scatter_forward()
    return ImplicitDynamics(
        u,
        material,
        density=parameters.density,
        dt=parameters.dt,
        bcs=bcs,
        velocity=velocity,
        gravity=scene.gravity(),
        external_energy=scene.external_energy(u),
        boundary_update=update,
        scheme=parameters.scheme,
        damping=_damping_coefficient(parameters),
        controller=StepController(parameters.dt, max_cuts=int(parameters.max_cuts)),
        **options,
    )


def _damping_coefficient(parameters: Parameters) -> float:
    """Return the mass-proportional damping c [1/s] for the requested fraction ζ.

    ζ is relative to critical damping of the lowest elastic mode, ω ≈ π c / L: c = 2 ζ ω.
    """
    if parameters.damping == 0.0:
        return 0.0
    lowest = math.pi * parameters.wave_speed / parameters.size
    return 2.0 * parameters.damping * lowest


def _joined(
    updates: Sequence[Callable[[float], None] | None],
) -> Callable[[float], None] | None:
    """Return one update calling each given one in order (None if none is given)."""
    given = [update for update in updates if update is not None]
    if not given:
        return None
    if len(given) == 1:
        return given[0]

    def update(t: float) -> None:
        for each in given:
            each(t)

    return update
