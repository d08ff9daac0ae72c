"""Solver robustness across scales: a body at rest, scaled problems, a failing linear solver.

The at-rest case is the point collapse of the collapse scene with a stiff, light material
(E = 1e7, ρ = 1, dt = 0.01: a wave crosses the cube 30 times per step): once the body has come
to rest, every step starts at its solution, where stopping tests and a line search that are not
scaled to the problem fail. Scale invariance: multiplying E, ρ and the loads by one
factor is the same dimensionless problem (docs/design.md, "Scale"), so the Newton iterations
must not change. The injected failure checks that a linear solver that cannot converge is
retried with cut steps and reported at the stage "linear solve".
"""

from __future__ import annotations

from mpi4py import MPI

import dolfinx
import numpy as np
import pytest
import ufl

from dolfinx_invertible import C2, Material, NeoHookean, _compat, lame
from dolfinx_invertible.scenes import Parameters, RunObserver, get_scene, run_scene
from dolfinx_invertible.solvers import HyperelasticProblem, ImplicitDynamics, SolverError

SCALES = (1.0e-6, 1.0e-3, 1.0, 1.0e3, 1.0e6)
KSP_ITERATION_CAP = ("DIVERGED_ITS", "DIVERGED_MAX_IT")


def test_collapse_at_rest_takes_no_newton_iterations():
    """E = 1e7, ρ = 1, dt = 0.01, 40 steps: completes, and steps at rest cost nothing."""
    scene = get_scene("collapse")
    parameters = Parameters(**{**scene.defaults, "E": 1.0e7, "density": 1.0, "dt": 0.01})
    assert parameters.t_end == pytest.approx(0.4)
    iterations = []
    summary = run_scene(
        scene,
        parameters,
        comm=MPI.COMM_SELF,
        on_step=lambda run: iterations.append(run.result.newton_iterations),
    )
    assert summary["completed"] and summary["outcome"] == "recovered"
    # 40 = t_end / dt = 0.4 / 0.01 steps, none cut. The cuts: regression pin: observed 0 on
    # 2026-12-04 (a5eadce) with pytest tests/solvers/test_robustness.py -k collapse_at_rest
    assert len(iterations) == 40 and summary["stepping"]["cuts"] == 0
    # Recovery takes a few steps; from then on the body is at rest and the state it starts
    # from already solves the step.
    assert max(iterations[:5]) > 0
    # regression pin: observed iterations 3, 2, 2, 1, 1, then 0 from the sixth step on, on
    # 2026-12-04 (a5eadce) with pytest tests/solvers/test_robustness.py -k collapse_at_rest
    assert iterations[-30:] == [0] * 30


def _bar(comm=MPI.COMM_SELF):
    mesh = dolfinx.mesh.create_box(
        comm,
        [np.zeros(3), np.array([1.0, 0.25, 0.25])],
        [4, 1, 1],
        dolfinx.mesh.CellType.tetrahedron,
    )
    space = _compat.vector_function_space(mesh, 1)
    clamped = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 0.0))
    dofs = dolfinx.fem.locate_dofs_topological(space, 2, clamped)
    end = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 1.0))
    tags = dolfinx.mesh.meshtags(mesh, 2, end, np.full(len(end), 1, dtype=np.int32))
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags)
    return mesh, space, dolfinx.fem.dirichletbc(np.zeros(3), dofs, space), ds(1)


def _dynamic_iterations(scale: float) -> list[int]:
    """Newton iterations per step of a clamped bar under gravity and an end traction."""
    mesh, space, bc, end = _bar()
    u = dolfinx.fem.Function(space)
    mu, lam = lame(scale * 1.0e5, 0.45)
    traction = dolfinx.fem.Constant(mesh, np.array([0.0, scale * 2.0e3, scale * 1.0e3]))
    dynamics = ImplicitDynamics(
        u,
        Material(NeoHookean(mu=mu, lam=lam), C2()),
        density=scale * 1.0e3,
        dt=0.01,
        bcs=[bc],
        gravity=(0.0, 0.0, -9.81),  # a body force ρ g: scales with ρ
        external_energy=-ufl.dot(traction, u) * end,
    )
    return [dynamics.step().newton_iterations for _ in range(4)]


def _collapse_iterations(scale: float) -> list[int]:
    """Newton iterations per step of a small cube released from F = 0.05 I."""
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_SELF, 2, 2, 2)
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))
    u.interpolate(lambda x: -0.95 * (x - 0.5))
    mu, lam = lame(scale * 1.0e3, 0.45)
    dynamics = ImplicitDynamics(
        u, Material(NeoHookean(mu=mu, lam=lam), C2()), density=scale * 1.0, dt=0.02
    )
    return [dynamics.step().newton_iterations for _ in range(6)]


def _static_iterations(scale: float) -> list[int]:
    """Newton iterations per load step of the bar bent by an end traction, no inertia."""
    mesh, space, bc, end = _bar()
    u = dolfinx.fem.Function(space)
    mu, lam = lame(scale * 1.0e5, 0.3)
    traction = dolfinx.fem.Constant(mesh, np.zeros(3))
    problem = HyperelasticProblem(
        u,
        Material(NeoHookean(mu=mu, lam=lam), C2()),
        [bc],
        external_energy=-ufl.dot(traction, u) * end,
    )
    iterations = []
    for step in range(1, 4):
        traction.value = np.array([0.0, 0.0, scale * 4.0e3 * step])
        result = problem.solve()
        assert result.converged
        iterations.append(result.newton_iterations)
    return iterations


@pytest.mark.parametrize(
    "iterations", [_dynamic_iterations, _collapse_iterations, _static_iterations]
)
def test_scaling_stiffness_density_and_loads_leaves_iterations_unchanged(iterations):
    reference = iterations(1.0)
    assert all(count > 0 for count in reference)
    for scale in SCALES:
        assert iterations(scale) == reference, f"scale {scale:g}"


@pytest.mark.parametrize(
    ("globalization", "cuts", "escalations"), [("line-search", 8, 1), ("trust-region", 4, 0)]
)
def test_injected_linear_solver_failure_is_cut_and_reported_as_linear_solve(
    globalization, cuts, escalations
):
    mesh, space, bc, end = _bar()
    u = dolfinx.fem.Function(space)
    mu, lam = lame(1.0e5, 0.45)
    dynamics = ImplicitDynamics(
        u,
        Material(NeoHookean(mu=mu, lam=lam), C2()),
        density=1.0e3,
        dt=0.01,
        bcs=[bc],
        gravity=(0.0, 0.0, -9.81),
        max_cuts=3,
        linear_solver="iterative",
        globalization=globalization,
        petsc_options={"ksp_max_it": 1},
    )
    with pytest.raises(SolverError) as caught:
        dynamics.step()
    error = caught.value
    assert error.stage == "linear solve"
    assert error.reason_name == "DIVERGED_LINEAR_SOLVE"
    # KSP's -3 has two names in petsc4py (DIVERGED_ITS, DIVERGED_MAX_IT).
    assert error.result.linear_reason_name in KSP_ITERATION_CAP
    assert "linear solve failed" in str(error)
    assert f"KSP {error.result.linear_reason_name}" in str(error)
    # Retried: the first attempt and one per cut, each a smaller step. Every attempt fails (one
    # Krylov iteration cannot converge): the cuts run out after max_cuts + 1 = 4 failed
    # attempts. The line search then escalates to blended tangents once (the truncated CG's
    # curvature test) with a fresh budget, and those 4 attempts fail too; a trust region, whose
    # steps use the negative curvature already, has nothing to escalate to.
    assert dynamics.controller.cuts == cuts and dynamics.controller.escalations == escalations
    assert ("blended tangents" in str(error)) == (escalations > 0)
    assert dynamics.time == 0.0 and np.all(u.x.array == 0.0)


def test_injected_linear_solver_failure_reaches_the_scene_summary():
    scene = get_scene("collapse")
    parameters = Parameters(**{**scene.defaults, "resolution": 2, "t_end": 0.02})
    summary = run_scene(
        scene,
        parameters,
        comm=MPI.COMM_SELF,
        petsc_options={"ksp_type": "cg", "pc_type": "jacobi", "ksp_max_it": 1},
    )
    assert not summary["completed"] and summary["outcome"] == "failed"
    assert summary["failed_stage"] == "linear solve"
    assert any(f"KSP {name}" in summary["reason"] for name in KSP_ITERATION_CAP)
    # Every attempt fails and CG offers no escalation: max_cuts + 1 failed attempts, with the
    # scenes' StepController default of max_cuts = 6.
    assert summary["stepping"]["cuts"] == 7  # the first attempt, then 6 cuts


@pytest.mark.parametrize("pc_type", ["jacobi", "gamg"])
def test_krylov_solver_chosen_in_petsc_options_replaces_the_direct_default(pc_type):
    """The inertia test of the exact tangent asks the preconditioner in effect for a factor.

    The default solve of a small problem is a MUMPS factorisation; a KSP and PC given in
    ``petsc_options`` replace it, and a PC without a factor must not be asked for one.
    """
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_SELF, 2, 2, 2)
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))
    u.interpolate(lambda x: -0.95 * (x - 0.5))
    mu, lam = lame(1.0e3, 0.45)
    dynamics = ImplicitDynamics(
        u,
        Material(NeoHookean(mu=mu, lam=lam), C2()),
        density=1.0,
        dt=0.02,
        petsc_options={"ksp_type": "cg", "pc_type": pc_type, "ksp_rtol": 1.0e-12},
    )
    assert dynamics.problem.solver.linear_solver == "direct"  # what the default chose
    for _ in range(3):
        result = dynamics.step()
        assert result.converged and result.linear_iterations > result.newton_iterations
    assert dynamics.problem.solver.krylov_solver.getPC().getType() == pc_type


def _collapse_step(blend: bool, nu: float):
    """One backward Euler step out of the point collapse (F = 0.05 I) of a unit cube."""
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_SELF, 4, 4, 4, dolfinx.mesh.CellType.tetrahedron)
    space = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(space)
    u.interpolate(lambda x: -0.95 * (x - 0.5))
    mu, lam = lame(1.0e3, nu)
    # ρ = 1000: the wave speed is 1 m/s and dt·c/L = 1.5625e-3, where the exact tangent of the
    # collapsed state is indefinite but only just: the mass outweighs most of its negative
    # curvature.
    dynamics = ImplicitDynamics(
        u,
        Material(NeoHookean(mu=mu, lam=lam), C2()),
        density=1.0e3,
        dt=1.5625e-3,
        blend_after=0 if blend else None,
        petsc_options={"snes_max_it": 200},
    )
    return dynamics.step()


def test_blended_tangent_restores_fast_convergence_out_of_a_collapse():
    """The projected tangent alone converges linearly there; the blend keeps the convergence.

    (At ν = 0.499 the same step is no example: the blend, from its first iteration, wanders to
    another minimum of lower energy in 145 iterations, the projected tangent takes 28.)
    """
    projected = _collapse_step(False, 0.49)
    blended = _collapse_step(True, 0.49)
    assert projected.converged and blended.converged
    assert projected.blended_iterations == 0 and blended.blended_iterations > 0
    # regression pins: observed blended 16 and projected 86 iterations on 2026-12-04 (a5eadce)
    # with pytest tests/solvers/test_robustness.py -k blended_tangent_restores
    assert blended.newton_iterations <= 20
    assert projected.newton_iterations >= 1.5 * blended.newton_iterations
    # The same solution: the blend changes the path, not the minimiser it converges to.
    assert blended.energy == pytest.approx(projected.energy, rel=1e-9)


def _collapsed_cube_dynamics(dt: float, **petsc_options) -> ImplicitDynamics:
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_SELF, 4, 4, 4, dolfinx.mesh.CellType.tetrahedron)
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))
    u.interpolate(lambda x: -0.95 * (x - 0.5))
    mu, lam = lame(1.0e3, 0.49)
    return ImplicitDynamics(
        u, Material(NeoHookean(mu=mu, lam=lam), C2()), density=1.0e3, dt=dt,
        petsc_options=petsc_options,
    )  # fmt: skip


def test_a_step_whose_cuts_run_out_escalates_to_blended_tangents():
    """dt·c/L = 0.1 out of the collapse, 50 Newton iterations an attempt: projected Newton fails
    at every cut, the blend does not.

    Without the escalation the step fails at every size down to dt/64 (each attempt at the cap
    of 50, so cut to a quarter: dt, dt/4, dt/16, dt/64); with it, dt/64 is tried again with
    blended tangents and converges. (At the default budget projected Newton gets through a cut
    on its own: below.)
    """
    refused = _collapsed_cube_dynamics(0.1, snes_max_it=50)
    refused.problem.escalate = lambda: False
    # 4 = the first attempt and three cuts to a quarter, the default max_cuts = 6 halvings.
    with pytest.raises(SolverError, match="failed 4 times"):
        refused.step()
    assert refused.controller.escalations == 0  # refused above

    escalated = _collapsed_cube_dynamics(0.1, snes_max_it=50)
    result = escalated.step()
    assert result.converged and result.blended_iterations > 0
    # regression pin: observed 16 on 2026-12-04 (a5eadce) with
    # pytest tests/solvers/test_robustness.py -k cuts_run_out_escalates
    assert result.newton_iterations <= 25
    # The cuts run out as in the refused run, so at least one escalation; the mode stays, so
    # there is nothing to escalate to a second time.
    assert escalated.controller.escalations == 1
    # 0.1 / 2⁶: the six halvings of the cuts (three quarters), then that size again with
    # blended tangents.
    assert escalated.controller.statistics()["step_min"] == pytest.approx(0.1 / 64)
    assert escalated.problem.solver.blend_after == 0  # the mode stays for the later steps


def test_the_default_budget_takes_the_step_the_cap_of_fifty_could_not():
    """The same step with Newton's default budget (progress, not 50 iterations): a cut
    converges with projected tangents, without running out of cuts or escalating."""
    dynamics = _collapsed_cube_dynamics(0.1)
    dynamics.problem.escalate = lambda: False
    result = dynamics.step()
    assert result.converged and result.newton_iterations > 50
    assert dynamics.controller.escalations == 0
    assert dynamics.controller.statistics()["cuts"] < 6


class _ExactPastCurvature(RunObserver):
    """Counts iterations whose direction is the exact one although CG met negative curvature."""

    def __init__(self):
        self.count = 0

    def iteration(self, run, iteration) -> None:
        truncated = run.minimizer.directions.truncated
        if iteration.iteration > 0 and truncated is not None:
            met = truncated.curvature_iteration is not None
            self.count += int(met and iteration.direction == "exact")


def test_newtons_local_phase_keeps_the_exact_direction_past_negative_curvature():
    """The collapse's first step at 10³ × 6 cells on the iterative path (trust region): with
    ``indefinite_newton`` an iteration past negative curvature takes the exact (MINRES)
    direction, and the step reaches the same state in fewer iterations than with the trust
    region's boundary step there."""
    scene = get_scene("collapse")
    parameters = Parameters(
        **{**scene.defaults, "resolution": 10, "linear_solver": "iterative", "t_stop": 0.01}
    )
    runs = {}
    for indefinite in (True, False):
        observer = _ExactPastCurvature()
        states = []
        summary = run_scene(
            scene,
            parameters,
            comm=MPI.COMM_SELF,
            observers=[observer],
            problem_options={"indefinite_newton": indefinite},
            on_step=lambda run, states=states: states.append(run.u.x.array.copy()),
        )
        assert summary["steps"] == 1 and summary["stepping"]["cuts"] == 0
        runs[indefinite] = (observer.count, summary["newton_iterations"]["total"], states[-1])
    (exact_with, newton_with, state_with), (exact_without, newton_without, state_without) = (
        runs[True],
        runs[False],
    )
    assert exact_with >= 1 and exact_without == 0
    assert newton_with < newton_without
    scale = np.abs(state_without).max()
    np.testing.assert_allclose(state_with, state_without, atol=1e-6 * scale)
