"""HyperelasticProblem, implicit dynamics and the inversion-free step, end to end.

Real DOLFINx, PETSc and MPI; runs serially and under mpirun (2 and 3 ranks).
"""

from __future__ import annotations

import itertools
import math

from mpi4py import MPI

import dolfinx
import dolfinx.fem.petsc
import numpy as np
import pytest
import ufl
from dolfinx_helpers import values_at_points

from dolfinx_invertible import C2, IFE, Material, NeoHookean, _compat, lame
from dolfinx_invertible.fem.diagnostics import cell_diagnostics, summary
from dolfinx_invertible.solvers import (
    EnergyMinimizer,
    EnergyProblem,
    HyperelasticProblem,
    ImplicitDynamics,
    InversionFreeStep,
    SolverError,
    external_forms,
    solve_load_steps,
)
from dolfinx_invertible.solvers import directions as directions_module
from dolfinx_invertible.solvers.convergence import STALL_WINDOW, ConvergenceTest

MU, LAM = lame(1.0e3, 0.3)
PROBE_POINTS = np.array([[1.0, 0.1, 0.1], [0.5, 0.25, 0.25], [0.9, 0.2, 0.05]])


def beam(comm=MPI.COMM_WORLD, degree: int = 1):
    mesh = dolfinx.mesh.create_box(
        comm, [np.zeros(3), np.array([1.0, 0.3, 0.3])], [6, 2, 2], dolfinx.mesh.CellType.tetrahedron
    )
    V = _compat.vector_function_space(mesh, degree)
    u = dolfinx.fem.Function(V)
    clamped = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 0.0))
    bc = dolfinx.fem.dirichletbc(np.zeros(3), dolfinx.fem.locate_dofs_topological(V, 2, clamped), V)
    end = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 1.0))
    tags = dolfinx.mesh.meshtags(mesh, 2, end, np.full(len(end), 1, dtype=np.int32))
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags)
    traction = dolfinx.fem.Constant(mesh, np.zeros(3))
    return mesh, u, bc, traction, ds(1)


def neo_hookean_ufl_energy(u):
    F = ufl.Identity(3) + ufl.grad(u)
    J = ufl.det(F)
    return (MU / 2 * (ufl.tr(F.T * F) - 3) - MU * ufl.ln(J) + LAM / 2 * ufl.ln(J) ** 2) * ufl.dx


@pytest.mark.mpi
def test_kernels_plus_ufl_traction_match_pure_ufl_solution():
    """Custom kernels and a UFL traction in one system solve the same problem as pure UFL.

    Plain Neo-Hookean: under C2 the compressed fibres (J < 0.9) rightly differ from UFL's.
    """
    mesh, u, bc, traction, end = beam()
    load = -ufl.dot(traction, u) * end
    problem = HyperelasticProblem(
        u, Material(NeoHookean(mu=MU, lam=LAM)), [bc], external_energy=load,
        quadrature_degree=2, petsc_options={"snes_rtol": 1e-11},
    )  # fmt: skip

    mesh_ufl, u_ufl, bc_ufl, traction_ufl, end_ufl = beam()
    total = neo_hookean_ufl_energy(u_ufl) - ufl.dot(traction_ufl, u_ufl) * end_ufl
    energy, residual, jacobian = external_forms(u_ufl, total)
    reference = EnergyMinimizer(
        EnergyProblem(u_ufl, energy, residual, jacobian, [bc_ufl]),
        petsc_options={"snes_rtol": 1e-11},
    )

    def load(constant):
        def at(t):
            constant.value[:] = (0.0, 0.0, -30.0 * t)

        return at

    solve_load_steps(problem.solver, load(traction), 3)
    solve_load_steps(reference, load(traction_ufl), 3)
    expected = values_at_points(u_ufl, PROBE_POINTS)
    actual = values_at_points(u, PROBE_POINTS)
    assert np.abs(expected).max() > 0.05  # a real deflection
    np.testing.assert_allclose(actual, expected, atol=1e-8 * np.abs(expected).max())


@pytest.mark.mpi
def test_unprojected_tangent_converges_quadratically():
    mesh, u, bc, traction, end = beam()
    problem = HyperelasticProblem(
        u,
        Material(NeoHookean(mu=MU, lam=LAM), C2()),
        [bc],
        external_energy=-ufl.dot(traction, u) * end,
        project=False,
        petsc_options={"snes_rtol": 1e-12, "snes_atol": 1e-13},
    )
    traction.value[:] = (0.0, 0.0, -20.0)
    result = problem.solve()
    assert result.converged
    history = np.asarray(result.residual_history)
    history = history[history > 1e-14 * history[0]]
    assert len(history) >= 4
    # The observed order from the last three residuals: log(r₊/r) / log(r/r₋) → 2.
    rates = np.log(history[2:] / history[1:-1]) / np.log(history[1:-1] / history[:-2])
    print("Newton residuals", history, "orders", rates)
    assert rates[-1] >= 1.8


def _pulled_beam(linear_solver: str):
    """Solve the beam pulled along its axis; return the solution, the directions and the
    arguments of every tangent switch."""
    mesh, u, bc, traction, end = beam()
    problem = HyperelasticProblem(
        u,
        Material(NeoHookean(mu=MU, lam=LAM), C2()),
        [bc],
        external_energy=-ufl.dot(traction, u) * end,
        linear_solver=linear_solver,
        petsc_options={"snes_rtol": 1e-10},
    )
    directions = problem.solver.directions
    switched = []
    switch = directions.tangent_switch

    def counted_switch(projected: bool) -> None:
        switched.append(projected)
        switch(projected)

    directions.tangent_switch = counted_switch
    traction.value[:] = (30.0, 0.0, 0.0)
    assert problem.solve().converged
    return values_at_points(u, PROBE_POINTS), directions, switched


@pytest.mark.mpi
def test_iterative_path_preconditions_with_the_exact_tangent_while_it_is_definite():
    """Pulled, the beam's exact tangent has no negative curvature: AMG is built on it and the
    projected tangent is never assembled; the solution is the direct solver's."""
    direct, _, _ = _pulled_beam("direct")
    iterative, directions, switched = _pulled_beam("iterative")
    assert directions.exact_preconditioner
    assert True not in switched  # never projected
    assert np.allclose(iterative, direct, rtol=1e-7, atol=1e-10)


def _collapsed_cube(**options):
    """A 3³ × 6 cube collapsed to 5 % of its size (C2), in implicit dynamics on the iterative
    path; return the mesh, the displacement, the material and the dynamics."""
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 3, 3, 3)
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))
    u.interpolate(lambda x: -0.95 * (x - 0.5))
    material = Material(NeoHookean(mu=MU, lam=LAM), C2(0.9))
    dynamics = ImplicitDynamics(
        u, material, density=1.0, dt=0.02, linear_solver="iterative", **options
    )
    return mesh, u, material, dynamics


@pytest.mark.mpi
def test_iterative_path_falls_back_to_the_projected_preconditioner_and_back():
    """Collapsed, the exact tangent has negative curvature: the first exact iteration's AMG on
    K fails, the direction is solved again with AMG on K₊, and K₊ preconditions the exact
    iterations until one meets no negative curvature; then AMG is built on K again."""
    mesh, u, material, dynamics = _collapsed_cube()
    directions = dynamics.problem.solver.directions
    states = []
    dynamics.problem.add_monitor(
        on_iteration=lambda iteration: (
            iteration.iteration > 0
            and states.append((iteration.direction, directions.preconditioned_by))
        )
    )
    dynamics.advance(0.4)
    assert states[0] == ("projected", "exact failed")  # AMG on K met negative curvature
    assert states[1][1] == "projected"  # so K₊ preconditions the next iteration
    assert states[-1] == ("exact", "exact")  # at rest K preconditions itself again
    final = summary(cell_diagnostics(u, material), mesh.comm)
    assert final["inverted_cells"] == 0 and final["min_J"] > 0.95


def _collapse_out_of(lifetime: int, monkeypatch):
    """Take the first time step of a collapsed cube on the iterative path with projected
    preconditioners kept for at most ``lifetime`` iterations; return its displacement at the
    probe points, the preconditioner's age at every iteration, the projected tangents
    assembled and the Newton iterations."""
    monkeypatch.setattr(directions_module, "PRECONDITIONER_LIFETIME", lifetime)
    _, u, _, dynamics = _collapsed_cube(petsc_options={"snes_rtol": 1e-11})
    directions = dynamics.problem.solver.directions
    switch = directions.tangent_switch
    projected = []
    directions.tangent_switch = lambda on: (projected.append(on), switch(on))
    ages = []
    dynamics.problem.add_monitor(
        on_iteration=lambda iteration: (
            iteration.iteration > 0 and ages.append(directions.preconditioner_age)
        )
    )
    # The first step: from the collapse to a cube most of the way back (at rest, later, every
    # displacement is zero and would compare equal whatever the solver did).
    iterations = dynamics.step().newton_iterations
    return values_at_points(u, PROBE_POINTS), ages, projected.count(True), iterations


@pytest.mark.mpi
def test_iterative_path_keeps_the_projected_preconditioner_for_the_same_solutions(monkeypatch):
    """Out of a collapse the projected preconditioner (K₊ and its AMG) is kept from one
    iteration to the next while the Krylov iterations do not grow: fewer projected tangents
    assembled, and the same converged step as when it is built at every iteration."""
    kept, kept_ages, kept_assembled, kept_iterations = _collapse_out_of(8, monkeypatch)
    built, built_ages, built_assembled, built_iterations = _collapse_out_of(1, monkeypatch)
    print("ages kept", kept_ages, "built", built_ages)
    print("projected tangents", kept_assembled, built_assembled)
    print("Newton iterations", kept_iterations, built_iterations)
    assert max(age for age in built_ages if age is not None) == 0
    assert max(age for age in kept_ages if age is not None) >= 1
    assert kept_assembled < built_assembled
    assert np.abs(built + 0.95 * (PROBE_POINTS - 0.5)).max() > 0.1  # the step moved the cube
    np.testing.assert_allclose(kept, built, atol=1e-8 * np.abs(built).max())


@pytest.mark.mpi
def test_inverted_scene_same_solution_on_any_number_of_ranks():
    """Start with inverted elements (C2): the equilibrium is independent of the partition."""

    def solve(comm):
        mesh, u, bc, traction, end = beam(comm)
        # A fold through the middle of the beam inverts the elements there.
        u.interpolate(lambda x: np.stack([-0.8 * np.sin(np.pi * x[0]), 0 * x[1], 0 * x[2]]))
        u.x.scatter_forward()
        material = Material(NeoHookean(mu=MU, lam=LAM), C2())
        start = summary(cell_diagnostics(u, material), comm)
        problem = HyperelasticProblem(
            u, material, [bc], external_energy=-ufl.dot(traction, u) * end,
            petsc_options={"snes_rtol": 1e-11, "snes_max_it": 200},
        )  # fmt: skip
        traction.value[:] = (0.0, 0.0, -10.0)
        result = problem.solve()
        assert result.converged, result
        return u, start

    distributed, start = solve(MPI.COMM_WORLD)
    serial, _ = solve(MPI.COMM_SELF)
    assert start["inverted_cells"] > 0
    expected = values_at_points(serial, PROBE_POINTS)
    actual = values_at_points(distributed, PROBE_POINTS)
    np.testing.assert_allclose(actual, expected, atol=1e-8 * np.abs(expected).max())


@pytest.mark.mpi
def test_inversion_free_step_on_affine_motion():
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2)
    V = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(V)
    direction = dolfinx.fem.Function(V)
    direction.interpolate(lambda x: 2.0 * x)  # δF = 2 I (sign −1 below: shrinking)
    limiter = InversionFreeStep(u, fraction=0.1)
    step = limiter.largest_step(_compat.petsc_vector(direction), sign=-1.0)
    # det((1 − 2α) I) = 0.1  ⇒  α = (1 − 0.1^(1/3)) / 2
    assert step == pytest.approx((1.0 - 0.1 ** (1.0 / 3.0)) / 2.0, rel=1e-12)
    assert limiter.largest_step(_compat.petsc_vector(direction), sign=1.0) == 1.0


@pytest.mark.mpi
def test_plain_neo_hookean_with_inversion_free_steps_stays_uninverted():
    mesh, u, bc, traction, end = beam()
    material = Material(NeoHookean(mu=MU, lam=LAM))
    problem = HyperelasticProblem(
        u, material, [bc], external_energy=-ufl.dot(traction, u) * end, inversion_free=0.1
    )
    worst = []

    def monitor(record):
        # u holds the iterate during the call.
        worst.append(summary(cell_diagnostics(u, material), mesh.comm)["min_J"])

    problem.add_monitor(on_iteration=monitor)

    def load(t):
        traction.value[2] = -60.0 * t

    solve_load_steps(problem.solver, load, 4)
    assert min(worst) > 0.0
    assert values_at_points(u, PROBE_POINTS)[0, 2] < -0.1


@pytest.mark.mpi
def test_free_fall_matches_discrete_backward_euler():
    """No supports, gravity only: every node follows uₙ = h² g n(n+1)/2 exactly."""
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2)
    V = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(V)
    g = np.array([0.0, 0.0, -9.81])
    for lumped in (False, True):
        u.x.array[:] = 0.0
        dynamics = ImplicitDynamics(
            u, Material(NeoHookean(mu=MU, lam=LAM), C2()), density=2.0, dt=0.05,
            gravity=g, lumped_mass=lumped,
        )  # fmt: skip
        for _ in range(3):
            dynamics.step()
        expected = 0.05**2 * g * 3 * 4 / 2
        values = u.x.array.reshape(-1, 3)
        np.testing.assert_allclose(values, np.broadcast_to(expected, values.shape), atol=1e-9)
        assert dynamics.time == pytest.approx(0.15)


@pytest.mark.mpi
@pytest.mark.parametrize("extension", [C2(0.9), IFE(0.9)])
def test_collapsed_cube_recovers(extension):
    """Paper Fig. 5 (left), small: every vertex pulled to the centre (F = 0.05 I)."""
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 3, 3, 3)
    V = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(V)
    u.interpolate(lambda x: -0.95 * (x - 0.5))
    material = Material(NeoHookean(mu=MU, lam=LAM), extension)
    dynamics = ImplicitDynamics(
        u, material, density=1.0, dt=0.02, petsc_options={"snes_rtol": 1e-6, "snes_max_it": 200}
    )
    dynamics.advance(0.4)
    final = summary(cell_diagnostics(u, material), mesh.comm)
    assert final["inverted_cells"] == 0
    assert final["min_J"] > 0.95


@pytest.mark.mpi
def test_bad_input_is_refused_before_solving():
    mesh, u, bc, traction, end = beam()
    material = Material(NeoHookean(mu=MU, lam=LAM), C2())
    V = u.function_space
    nowhere = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 5.0))
    empty = dolfinx.fem.dirichletbc(
        np.zeros(3), dolfinx.fem.locate_dofs_topological(V, 2, nowhere), V
    )
    with pytest.raises(ValueError, match="constrains no degree of freedom"):
        HyperelasticProblem(u, material, [empty])
    with pytest.raises(ValueError, match="dt must be"):
        ImplicitDynamics(u, material, density=1.0, dt=0.0)
    with pytest.raises(ValueError, match="dt must be"):
        ImplicitDynamics(u, material, density=1.0, dt=-1.0)
    u.x.array[0] = math.nan
    with pytest.raises(ValueError, match="NaN or Inf"):
        HyperelasticProblem(u, material, [bc])


def test_degenerate_reference_cells_are_named():
    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_SELF, 2, 2)
    # Squash the top row of vertices onto the middle row: the top cells lose all their area.
    x = mesh.geometry.x
    x[np.isclose(x[:, 1], 1.0), 1] = 0.5
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))
    with pytest.raises(ValueError, match=r"4 degenerate \(zero-volume\) cells"):
        HyperelasticProblem(u, Material(NeoHookean(mu=MU, lam=LAM), C2()))


@pytest.mark.mpi
def test_failed_time_step_raises_with_time_and_reason():
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2)
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))
    u.interpolate(lambda x: -0.9 * (x - 0.5))
    dynamics = ImplicitDynamics(
        u, Material(NeoHookean(mu=MU, lam=LAM), C2()), density=1.0, dt=0.1, max_cuts=1,
        petsc_options={"snes_max_it": 1},
    )  # fmt: skip
    before = u.x.array.copy()
    # Twice (dt, then one cut: a budget of one cut leaves no room for a quarter), then twice
    # more after escalating to blended tangents.
    with pytest.raises(SolverError, match=r"step 1 from t = 0 failed 4 times.*DIVERGED.*blended"):
        dynamics.step()
    np.testing.assert_array_equal(u.x.array, before)
    assert dynamics.time == 0.0


@pytest.mark.mpi
def test_time_dependent_dirichlet_data_drive_the_motion():
    """A face moved with prescribed velocity 0.5: its dofs follow exactly, the rest follows."""
    mesh, u, _, _, _ = beam()
    V = u.function_space
    face = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 0.0))
    dofs = dolfinx.fem.locate_dofs_topological(V, 2, face)
    prescribed = dolfinx.fem.Function(V)
    bc = dolfinx.fem.dirichletbc(prescribed, dofs)

    def move(t):
        prescribed.interpolate(lambda x: np.stack([0.5 * t + 0 * x[0], 0 * x[1], 0 * x[2]]))

    dynamics = ImplicitDynamics(
        u, Material(NeoHookean(mu=MU, lam=LAM), C2()), density=10.0, dt=0.02, bcs=[bc],
        boundary_update=move,
    )  # fmt: skip
    dynamics.advance(0.1)
    moved = u.x.array.reshape(-1, 3)[dofs]
    np.testing.assert_allclose(moved[:, 0], 0.5 * dynamics.time, rtol=1e-12)
    np.testing.assert_allclose(dynamics.velocity.x.array.reshape(-1, 3)[dofs, 0], 0.5, rtol=1e-9)
    # The far end has started to follow, but lags behind the driven face.
    far = values_at_points(u, np.array([[1.0, 0.15, 0.15]]))[0, 0]
    assert 0.0 < far < 0.5 * dynamics.time


@pytest.mark.mpi
def test_a_form_that_does_not_read_u_is_assembled_once_per_change_of_its_data(monkeypatch):
    """The inertia term's matrix is reused: the sum equals assembling every form, every time."""
    mesh, u, bc, _, _ = beam()
    u.interpolate(lambda x: np.stack([0.02 * x[1], -0.03 * x[0], 0.01 * x[0] * x[2]]))
    dynamics = ImplicitDynamics(u, Material(NeoHookean(mu=MU, lam=LAM), C2(0.9)), density=1.0,
                                dt=0.01, bcs=[bc])  # fmt: skip
    problem = dynamics.problem.energy_problem
    elastic, inertia = problem.jacobian_forms
    assembled = []
    assemble = _compat.assemble_matrix_into

    def counting(matrix, form, bcs, diagonal):
        assembled.append(form)
        assemble(matrix, form, bcs, diagonal)

    monkeypatch.setattr(_compat, "assemble_matrix_into", counting)
    matrix = problem.create_matrix()
    reference = problem.create_matrix()
    x = _compat.petsc_vector(u).copy()
    for weight in (1e4, 1e4, 1e4, 2.5e5, 2.5e5):
        dynamics._weight.value = weight
        problem.J(None, x, matrix, matrix)
        reference.zeroEntries()
        assemble(reference, elastic, [bc], 0.0)
        assemble(reference, inertia, [bc], 1.0)
        reference.assemble()
        difference = matrix.copy()
        difference.axpy(-1.0, reference)
        assert difference.norm() <= 1e-13 * reference.norm()
        # The moving iterate reaches the elastic form: it is assembled every time.
        x.array[:] += 1e-3
    assert sum(form is elastic for form in assembled) == 5
    assert sum(form is inertia for form in assembled) == 2  # once per weight


class _Wall:
    """A step limit that allows no motion at all (a contact's CCD with nowhere to go)."""

    def largest_step(self, direction, sign=1.0):
        return 1e-30


@pytest.mark.mpi
def test_a_step_cap_below_the_line_search_floor_fails_the_step_by_name():
    """A cap no line search can take is a reported failure that cuts the step, not a stall."""
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2)
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))
    dynamics = ImplicitDynamics(
        u, Material(NeoHookean(mu=MU, lam=LAM), C2()), density=1.0, dt=0.1, max_cuts=1,
        gravity=(0.0, 0.0, -9.81), step_limits=[_Wall()],
    )  # fmt: skip
    with pytest.raises(
        SolverError, match=r"failed .*_Wall allows 1\.0e-30 of the Newton step"
    ) as error:
        dynamics.step()
    assert dynamics.controller.statistics()["cuts"] >= 1
    # Each attempt stops at its first direction, capped by the wall.
    assert (
        "step limits capped 1 of 1 Newton steps (the smallest cap 1e-30 of the step, by _Wall)"
        in str(error.value)
    )


@pytest.mark.mpi
def test_a_failed_solve_says_where_its_last_iterate_is_worst():
    """One node of a cube at rest is moved: the residual is largest there. A solve allowed no
    iteration fails at that state and names the node, where it is now and the largest entry
    (computed again here); a converged solve names nothing."""
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 4, 4, 4)
    space = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(space)
    centre = np.flatnonzero(np.all(np.isclose(space.tabulate_dof_coordinates(), 0.5), axis=1))
    u.x.array.reshape(-1, 3)[centre] = [0.02, 0.0, 0.0]
    problem = HyperelasticProblem(
        u, Material(NeoHookean(mu=MU, lam=LAM), C2()), petsc_options={"snes_max_it": 0}
    )
    energy_problem = problem.energy_problem
    residual = energy_problem.create_vector()
    energy_problem.F(None, _compat.petsc_vector(u), residual)
    local = np.abs(residual.getArray(readonly=True))[energy_problem.free_owned]
    largest = mesh.comm.allreduce(float(local.max(initial=0.0)), op=MPI.MAX)
    assert largest > 0.0
    expected = (
        f"the largest residual entry, {largest:.3g}, at the node X = (0.5, 0.5, 0.5) "
        "(now at (0.52, 0.5, 0.5))"
    )
    assert energy_problem.locate(_compat.petsc_vector(u)) == expected
    result = problem.solve()
    assert not result.converged and result.where.startswith(expected)
    assert f"; where: {expected}" in result.describe()
    # (0, 3) on a rank the centre node is not on, owned or ghost.
    assert u.x.array.reshape(-1, 3)[centre] == pytest.approx(
        np.tile([0.02, 0.0, 0.0], (len(centre), 1))
    )
    problem.solver.snes.setTolerances(max_it=50)
    converged = problem.solve()
    assert converged.converged and converged.where == "" and "where" not in converged.describe()


@pytest.mark.mpi
def test_trust_region_steps_keep_the_dirichlet_values_exactly():
    """Bent far by an end load, the beam's trust region bounds its steps, where CG stops after
    a few iterations: every iterate still holds the clamped dofs at their values, to the last
    bit. (AMG's coarse corrections reach the clamped nodes; a direction that moves them changes
    Π by their reaction's work, which the residual's Dirichlet rows do not show, and the energy
    and the model then disagree along it.)"""
    mesh, u, bc, traction, end = beam()
    problem = HyperelasticProblem(
        u,
        Material(NeoHookean(mu=MU, lam=LAM), C2()),
        [bc],
        external_energy=-ufl.dot(traction, u) * end,
        linear_solver="iterative",
        globalization="trust-region",
    )
    energy_problem = problem.energy_problem
    fixed = energy_problem.constrained_dofs
    fixed = fixed[fixed < energy_problem.free_owned.size]
    drift, kinds = [], []

    def record(iteration) -> None:
        values = iteration.iterate.getArray(readonly=True)[fixed]
        drift.append(float(np.abs(values).max(initial=0.0)))
        kinds.append(iteration.direction)

    problem.add_monitor(on_iteration=record)
    traction.value[:] = (0.0, 0.0, -40.0)
    assert problem.solve().converged
    comm = mesh.comm
    assert comm.allreduce("bounded" in kinds, op=MPI.LOR)
    assert comm.allreduce(len(fixed), op=MPI.SUM) > 0
    assert comm.allreduce(max(drift), op=MPI.MAX) == 0.0


def _collapse_with(globalization: str):
    """A cube pressed through itself to 1 % of its size and sheared, one time step; the state
    at four points and the kinds of the Newton directions."""
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 3, 3, 3)
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))
    u.interpolate(lambda x: -0.99 * (x - 0.5) + 0.1 * np.sin(7.0 * x[[1, 2, 0]]))
    material = Material(NeoHookean(mu=MU, lam=LAM), C2())
    dynamics = ImplicitDynamics(
        u,
        material,
        density=1.0,
        dt=0.02,
        linear_solver="iterative",
        globalization=globalization,
        petsc_options={"snes_rtol": 1e-11},
    )
    kinds = []
    dynamics.problem.add_monitor(
        on_iteration=lambda iteration: iteration.iteration > 0 and kinds.append(iteration.direction)
    )
    dynamics.advance(0.02)
    points = np.array([[0.5, 0.5, 0.5], [0.1, 0.2, 0.9], [0.8, 0.7, 0.3], [0.95, 0.05, 0.5]])
    return values_at_points(u, points), kinds, dynamics


@pytest.mark.mpi
def test_trust_region_follows_negative_curvature_to_the_line_search_solution():
    """Out of the collapse, the trust region's steps use the exact tangent's negative curvature
    (directions cut at the boundary) and reach the state the line search's projected steps
    reach: the same minimiser of the step's energy."""
    searched, searched_kinds, _ = _collapse_with("line-search")
    bounded, kinds, dynamics = _collapse_with("trust-region")
    # Only a solve's first direction, before any radius is known, may be the projected one.
    assert "bounded" in kinds and "projected" not in kinds[1:]
    assert searched_kinds.count("projected") > 1
    assert len(kinds) < len(searched_kinds)
    assert np.allclose(bounded, searched, rtol=1e-6, atol=1e-8)
    assert dynamics.problem.solver.trust_region.radius < np.inf


@pytest.mark.parametrize("globalization", ["line-search", "trust-region"])
def test_the_progress_test_sees_the_energy_of_the_accepted_iterates(globalization, monkeypatch):
    """The convergence test is given Π at the accepted iterates of both globalizations (the
    progress test judges by it), falling up to its rounding error (as the solver measures it:
    at convergence two iterates may differ by a few ulps either way), and ending at the solve's
    reported energy."""
    seen: list[tuple[int, float | None, float]] = []
    check = ConvergenceTest.check

    def record(test, iteration, norm, snes, reject, energy=None, rounding=0.0):
        seen.append((iteration, energy, rounding))
        return check(test, iteration, norm, snes, reject, energy=energy, rounding=rounding)

    monkeypatch.setattr(ConvergenceTest, "check", record)
    results = []
    monkeypatch.setattr(
        HyperelasticProblem, "solve", _recording(HyperelasticProblem.solve, results)
    )
    _, kinds, dynamics = _collapse_with(globalization)
    assert dynamics.problem.solver.stall_window == STALL_WINDOW
    accepted = [(energy, rounding) for iteration, energy, rounding in seen
                if iteration > 0 and energy is not None]  # fmt: skip
    energies = [energy for energy, _ in accepted]
    assert len(energies) >= len(kinds) // 2 >= 2
    assert all(0.0 <= rounding <= 1e-10 * abs(energy) for energy, rounding in accepted)
    assert all(b <= a + rounding for (a, _), (b, rounding) in itertools.pairwise(accepted))
    # Falling by far more than rounding over the solve: a run that did nothing cannot pass.
    assert energies[-1] < energies[0] - 1e-3 * abs(energies[0])
    assert results and results[-1].energy == pytest.approx(energies[-1], rel=1e-12)


def _recording(solve, results):
    def recorded(self, *args, **kwargs):
        result = solve(self, *args, **kwargs)
        results.append(result)
        return result

    return recorded


def test_trust_region_needs_the_iterative_path():
    mesh, u, bc, traction, end = beam(MPI.COMM_SELF)
    with pytest.raises(ValueError, match="trust-region.*iterative path"):
        HyperelasticProblem(
            u, Material(NeoHookean(mu=MU, lam=LAM), C2()), [bc], linear_solver="direct",
            globalization="trust-region",
        )  # fmt: skip
    with pytest.raises(ValueError, match="globalization must be one of"):
        HyperelasticProblem(
            u, Material(NeoHookean(mu=MU, lam=LAM), C2()), [bc], globalization="dogleg"
        )
