"""Newton solver and load stepping on a compressible Neo-Hookean cantilever (real DOLFINx/PETSc).

Runs serially and under mpirun: every test is collective, and the MPI test compares the
distributed solution with the same problem solved on MPI.COMM_SELF in the same run.
"""

from __future__ import annotations

import dataclasses

from mpi4py import MPI

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import numpy as np
import pytest
import ufl
from dolfinx_helpers import values_at_points
from petsc4py import PETSc

from dolfinx_invertible import _compat
from dolfinx_invertible.solvers import (
    DEFAULT_PETSC_OPTIONS,
    EnergyMinimizer,
    EnergyProblem,
    NewtonIteration,
    SolverError,
    SolveResult,
    StepController,
    rigid_body_near_nullspace,
    snes_reason_name,
    solve_load_steps,
    take_step,
)
from dolfinx_invertible.solvers.line_search import EnergyLineSearch

pytestmark = pytest.mark.mpi

LENGTH = 3.0
YOUNG, POISSON = 1.0e3, 0.3
SPRING = 5.0  # N/m³ on the loaded end: gives the split jacobian a facet-integral form
# Body force and end traction per unit load factor, pointing down; at load factor 0.5 the tip
# deflects by about a third of the length, enough for Newton to need several iterations.
BODY_FORCE, TRACTION = 10.0, 30.0
PROBE_POINTS = np.array([[2.9, 0.45, 0.55], [1.5, 0.3, 0.7], [0.7, 0.6, 0.2], [2.2, 0.9, 0.1]])


@dataclasses.dataclass
class Cantilever:
    problem: EnergyProblem
    pseudo_time: dolfinx.fem.Constant  # scales body force and traction
    u: dolfinx.fem.Function

    def set_time(self, t: float) -> None:
        self.pseudo_time.value = t

    def reset(self) -> None:
        self.u.x.array[:] = 0.0


def cantilever(
    comm: MPI.Comm = MPI.COMM_WORLD, split: bool = False, energy: bool = True, load: float = 0.5
) -> Cantilever:
    """A 3 x 1 x 1 block of 6x2x2x6 P1 tetrahedra clamped at x = 0, hanging under gravity and an
    end traction, with a weak spring on the end face.

    ``split`` gives Π as [elastic, spring + load potential] and the tangent as [elastic, spring];
    otherwise everything is one form. ``energy=False`` drops the energy forms (stress-only).
    """
    corners = [np.zeros(3), np.array([LENGTH, 1.0, 1.0])]
    mesh = dolfinx.mesh.create_box(comm, corners, [6, 2, 2], dolfinx.mesh.CellType.tetrahedron)
    space = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(space)
    test, trial = ufl.TestFunction(space), ufl.TrialFunction(space)
    pseudo_time = dolfinx.fem.Constant(mesh, 0.0)

    mu = YOUNG / (2.0 * (1.0 + POISSON))
    lam = YOUNG * POISSON / ((1.0 + POISSON) * (1.0 - 2.0 * POISSON))
    gradient = ufl.Identity(3) + ufl.grad(u)
    log_volume = ufl.ln(ufl.det(gradient))
    psi = mu / 2 * (ufl.tr(gradient.T * gradient) - 3) - mu * log_volume + lam / 2 * log_volume**2

    end = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], LENGTH))
    tags = dolfinx.mesh.meshtags(mesh, 2, end, np.ones(len(end), dtype=np.int32))
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags)
    down = ufl.as_vector((0.0, 0.0, -1.0))
    elastic = psi * ufl.dx
    spring = SPRING / 2 * ufl.inner(u, u) * ds(1)
    load_density = BODY_FORCE * ufl.inner(down, u) * ufl.dx + TRACTION * ufl.inner(down, u) * ds(1)
    load_potential = -pseudo_time * load * load_density

    def first(form):
        return ufl.derivative(form, u, test)

    def second(form):
        return ufl.derivative(first(form), u, trial)

    if split:
        energy_parts, tangent_parts = [elastic, spring + load_potential], [elastic, spring]
    else:
        energy_parts = [elastic + spring + load_potential]
        tangent_parts = energy_parts
    clamped = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 0.0))
    bc = dolfinx.fem.dirichletbc(
        np.zeros(3), dolfinx.fem.locate_dofs_topological(space, 2, clamped), space
    )
    problem = EnergyProblem(
        u,
        [dolfinx.fem.form(part) for part in energy_parts] if energy else None,
        [dolfinx.fem.form(first(part)) for part in energy_parts],
        [dolfinx.fem.form(second(part)) for part in tangent_parts],
        [bc],
    )
    return Cantilever(problem, pseudo_time, u)


def global_norm(function: dolfinx.fem.Function) -> float:
    return _compat.petsc_vector(function).norm()


def relative_difference(a: dolfinx.fem.Function, b: dolfinx.fem.Function) -> float:
    difference = _compat.petsc_vector(a).copy()
    difference.axpy(-1.0, _compat.petsc_vector(b))
    return difference.norm() / global_norm(b)


def solve_at(case: Cantilever, solver: EnergyMinimizer, t: float) -> SolveResult:
    case.set_time(t)
    result = solver.solve()
    assert result.converged, result
    return result


def test_neo_hookean_load_steps_converge_with_energy_decrease():
    case = cantilever()
    # Small enough for the default to factorise; the iterative solver is what large problems get.
    assert EnergyMinimizer(case.problem).linear_solver == "direct"
    solver = EnergyMinimizer(case.problem, linear_solver="iterative")
    assert solver.line_search == "energy"
    assert solver.linear_solver == "iterative"
    assert solver.krylov_solver.getType() == "cg"
    assert solver.krylov_solver.getPC().getType() == "gamg"

    energies: list[float] = []

    def record_energy(iteration: NewtonIteration) -> None:
        energies.append(case.problem.objective(None, iteration.iterate))

    solver.add_monitor(on_iteration=record_energy)
    per_step: list[tuple[float, list[float], SolveResult]] = []

    def on_step(t: float, result: SolveResult) -> None:
        per_step.append((t, list(energies), result))
        energies.clear()

    results = solve_load_steps(solver, case.set_time, 3, on_step=on_step)

    assert [t for t, _, _ in per_step] == pytest.approx([1 / 3, 2 / 3, 1.0])
    assert len(results) == 3 and all(result.converged for result in results)
    residual = case.problem.create_vector()
    for _, step_energies, result in per_step:
        # regression pin: observed 4 Newton iterations in each step on 2026-12-04 (a5eadce) with
        # pytest tests/solvers/test_minimizer.py -k load_steps_converge_with_energy_decrease
        assert result.newton_iterations >= 2 and result.linear_iterations > 0
        # Monotone descent of Π over the Newton iterates, up to rounding.
        scale = max(abs(value) for value in step_energies)
        assert all(b <= a + 1e-12 * scale for a, b in zip(step_energies, step_energies[1:]))
        assert step_energies[-1] < step_energies[0]
        assert result.energy == pytest.approx(step_energies[-1], rel=1e-12)
        assert result.residual_norm < 1e-8 * result.residual_history[0]
    # Independent check of the final residual: assemble it afresh at the solution.
    case.problem.F(None, _compat.petsc_vector(case.u), residual)
    assert residual.norm() < 1e-8 * per_step[-1][2].residual_history[0]
    tip = values_at_points(case.u, PROBE_POINTS[:1])[0]
    assert tip[2] < -0.5  # hangs down by a visible fraction of its length


@pytest.mark.mpi
def test_every_iterate_of_petsc_cg_keeps_the_dirichlet_values_exactly():
    """Every Newton iterate holds the clamped dofs at their values, to the last bit, on the
    iterative path with PETSc's own CG, whose solution is exact only to its tolerance (the
    trust region's truncated CG: tests/solvers/test_hyperelastic.py)."""
    case = cantilever()
    solver = EnergyMinimizer(case.problem, linear_solver="iterative")
    assert solver.krylov_solver.getType() == "cg" and solver.directions.truncated is None
    problem = case.problem
    fixed = problem.constrained_dofs[problem.constrained_dofs < problem.free_owned.size]
    drift: list[float] = []

    def record(iteration: NewtonIteration) -> None:
        values = iteration.iterate.getArray(readonly=True)[fixed]
        drift.append(float(np.abs(values).max(initial=0.0)))

    solver.add_monitor(on_iteration=record)
    result = solve_at(case, solver, 1.0)
    comm = problem.comm
    assert result.newton_iterations >= 3 and result.linear_iterations > result.newton_iterations
    assert comm.allreduce(len(fixed), op=MPI.SUM) > 0
    assert comm.allreduce(max(drift), op=MPI.MAX) == 0.0


def _first_newton_direction(load: float):
    """The cantilever at rest under ``load``, its minimiser, Newton direction, state, residual."""
    case = cantilever()
    solver = EnergyMinimizer(case.problem)
    case.set_time(load)
    direction = case.problem.create_vector()
    solver.newton_direction(direction)
    x = _compat.petsc_vector(case.u).copy()
    residual = case.problem.create_vector()
    case.problem.F(None, x, residual)
    return case, solver, direction, x, residual


def test_line_search_starts_from_the_energy_of_the_point_it_accepted(monkeypatch):
    """The energy at the point a search accepted is not assembled again when the next starts.

    The line search on its own, on the cantilever at load 0.5: a first backtracking step from
    the initial guess along its Newton direction, then the energy at the accepted point, which
    must cost no assembly, while any other point costs one.
    """
    case, solver, direction, x, residual = _first_newton_direction(0.5)
    search = EnergyLineSearch(case.problem, rounding=solver.tolerances.energy_rounding)
    assemblies = []
    terms = case.problem.energy_terms
    monkeypatch.setattr(case.problem, "energy_terms", lambda: assemblies.append(1) or terms())
    assert search.backtrack(x, direction, residual) is None
    trials = len(assemblies)
    assert trials >= 2  # the start and at least one trial point
    accepted = x.copy()
    accepted.axpy(-1.0, direction)
    energy, _ = search.energy_at(accepted)
    assert len(assemblies) == trials  # reused
    assert search.known_energy(accepted) == energy
    assert energy < search.energy_at(x)[0]  # the start: assembled again, and higher
    assert len(assemblies) == trials + 1
    assert energy == pytest.approx(case.problem.objective(None, accepted), rel=1e-14)


def test_a_direction_that_raises_the_energy_is_not_taken_at_the_rounding_floor(monkeypatch):
    """After a resolvable rise of Π along a direction, the residual test takes no shorter step.

    The cantilever at load 0.05 from rest and its Newton direction y, with Π given a kink at the
    start along y, 2 (rᵀy / |y|²) |yᵀ(u − u₀)|, which the residual does not see: Π then rises
    along −y at every length. The search must fail (halving down to where Π's change is lost in
    its rounding must not count as progress), although the residual falls along y. Without the
    kink the full step is taken.
    """
    case, solver, newton, x, residual = _first_newton_direction(0.05)
    slope = residual.dot(newton)
    assert slope > 0.0

    search = EnergyLineSearch(case.problem, rounding=solver.tolerances.energy_rounding)
    direction = newton.copy()
    assert search.backtrack(x, direction, residual) is None and search.fraction == 1.0

    terms = case.problem.energy_terms
    weight = 2.0 * slope / newton.dot(newton)
    offset = case.problem.create_vector()

    def with_a_kink():
        _compat.petsc_vector(case.u).copy(offset)
        offset.axpy(-1.0, x)
        return np.append(terms(), weight * abs(newton.dot(offset)))

    monkeypatch.setattr(case.problem, "energy_terms", with_a_kink)
    # The premise: the residual falls along y at the shortest step the search tries, where the
    # change of Π is below its rounding error.
    shortest = x.copy()
    shortest.axpy(-(0.5**search.max_backtracks), newton)
    after = case.problem.create_vector()
    case.problem.F(None, shortest, after)
    assert after.norm() < residual.norm()
    # Without the watchdog, as the trust region searches (a watch would take the full step).
    search = EnergyLineSearch(
        case.problem, rounding=solver.tolerances.energy_rounding, watchdog_steps=0
    )
    energy, rounding = search.energy_at(x)[0], search.rounding(search.energy_at(x)[1])
    assert search.energy_at(shortest)[0] - energy <= rounding

    direction = newton.copy()
    stop = search.backtrack(x, direction, residual)
    assert stop is not None and not stop.converged and "decreases the energy" in stop.detail
    assert search.fraction == 0.0 and direction.norm() == 0.0


def test_split_forms_match_single_form():
    single, split = cantilever(), cantilever(split=True)
    results = []
    for case in (single, split):
        solver = EnergyMinimizer(case.problem)
        results.append(solve_at(case, solver, 1.0))
    assert relative_difference(split.u, single.u) < 1e-10
    assert results[1].energy == pytest.approx(results[0].energy, rel=1e-10)

    # Tangent and residual at the same (non-trivial) state: the split sums must equal the single
    # forms, with each Dirichlet row and column zero but for a 1 on the diagonal.
    state = _compat.petsc_vector(single.u)
    matrices, residuals = [], []
    for case in (single, split):
        matrix, residual = case.problem.create_matrix(), case.problem.create_vector()
        case.problem.J(None, state, matrix, matrix)
        case.problem.F(None, state, residual)
        assert matrix.getInfo()["mallocs"] == 0  # the spring's facet integral fits the pattern
        matrices.append(matrix)
        residuals.append(residual)
    difference = matrices[1].copy()
    difference.axpy(-1.0, matrices[0])
    assert difference.norm() < 1e-12 * matrices[0].norm()
    residuals[1].axpy(-1.0, residuals[0])
    assert residuals[1].norm() < 1e-12 * results[0].residual_history[0]

    bc_dofs = split.problem.bcs[0].dof_indices()[0]
    block_size = split.u.function_space.dofmap.index_map_bs
    owned = split.u.function_space.dofmap.index_map.size_local * block_size
    bc_dofs = bc_dofs[bc_dofs < owned]
    start = matrices[1].getOwnershipRange()[0]
    diagonal = matrices[1].getDiagonal()
    assert np.all(diagonal.array[bc_dofs] == 1.0)
    for dof in bc_dofs[:5]:
        columns, values = matrices[1].getRow(start + dof)
        assert np.all(values[columns != start + dof] == 0.0)


def test_interior_facet_jacobian_beyond_first_pattern_is_allocated_and_reported():
    mesh = dolfinx.mesh.create_box(MPI.COMM_WORLD, [np.zeros(3), np.ones(3)], [3, 2, 2])
    space = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(space)
    test, trial = ufl.TestFunction(space), ufl.TrialFunction(space)
    mass = ufl.inner(trial, test) * ufl.dx
    # Couples the dofs of the two cells of a facet, which the mass pattern does not contain.
    jumps = ufl.inner(ufl.jump(ufl.grad(trial)), ufl.jump(ufl.grad(test))) * ufl.dS
    facets = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 0.0))
    bc = dolfinx.fem.dirichletbc(
        np.zeros(3), dolfinx.fem.locate_dofs_topological(space, 2, facets), space
    )
    residual = dolfinx.fem.form(ufl.inner(u, test) * ufl.dx)
    problem = EnergyProblem(
        u, None, residual, [dolfinx.fem.form(mass), dolfinx.fem.form(jumps)], [bc]
    )
    matrix = problem.create_matrix()
    with pytest.warns(RuntimeWarning, match="beyond the sparsity pattern"):
        problem.J(None, _compat.petsc_vector(u), matrix, matrix)
    expected = dolfinx.fem.petsc.assemble_matrix(dolfinx.fem.form(mass + jumps), bcs=[bc])
    expected.assemble()
    difference = matrix.copy()
    difference.axpy(-1.0, expected, PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    assert difference.norm() < 1e-12 * expected.norm()


def test_quadratic_convergence_near_solution():
    case = cantilever(load=0.3)
    solver = EnergyMinimizer(case.problem)
    result = solve_at(case, solver, 1.0)
    history = np.array(result.residual_history)
    # Enough residuals for a pair inside the convergence region: regression pin: observed 5 on
    # 2026-12-04 (a5eadce) with pytest tests/solvers/test_minimizer.py -k quadratic_convergence
    assert result.newton_iterations >= 3
    relative = history / history[0]
    # Pairs inside the convergence region and above the rounding floor of the residual.
    pairs = [(a, b) for a, b in zip(relative, relative[1:]) if a < 1e-2 and b > 1e-14]
    assert len(pairs) >= 1, relative
    for a, b in pairs[-2:]:
        assert np.log(b) / np.log(a) >= 1.8, relative


def test_boomeramg_gives_same_solution():
    # A property of the PETSc build, not of DOLFINx: the PyPI DOLFINx wheel's PETSc has no hypre.
    if not PETSc.Sys.hasExternalPackage("hypre"):
        pytest.skip("this PETSc was built without hypre (BoomerAMG)")
    reference, case = cantilever(), cantilever()
    solve_at(reference, EnergyMinimizer(reference.problem), 1.0)
    solver = EnergyMinimizer(case.problem, linear_solver="iterative", pc="hypre")
    assert solver.krylov_solver.getPC().getType() == "hypre"
    solve_at(case, solver, 1.0)
    assert relative_difference(case.u, reference.u) < 1e-8


def test_stress_only_problem_uses_l2_line_search():
    reference, case = cantilever(), cantilever(energy=False)
    solve_at(reference, EnergyMinimizer(reference.problem), 0.5)
    solver = EnergyMinimizer(case.problem)
    assert solver.line_search == "l2"
    result = solve_at(case, solver, 0.5)
    assert result.energy is None
    assert relative_difference(case.u, reference.u) < 1e-8
    with pytest.raises(ValueError, match="no energy"):
        case.problem.objective(None, _compat.petsc_vector(case.u))


def test_option_override_makes_solve_fail_and_keeps_u():
    case = cantilever()
    solve_at(case, EnergyMinimizer(case.problem), 0.5)
    before = case.u.x.array.copy()

    solver = EnergyMinimizer(case.problem, petsc_options={"snes_max_it": 1})
    case.set_time(1.0)
    result = solver.solve()
    assert not result.converged
    assert result.reason < 0 and result.reason_name == "DIVERGED_MAX_IT"
    assert result.newton_iterations == 1 and result.energy is None  # snes_max_it = 1
    assert np.array_equal(case.u.x.array, before)  # ghosts included

    # Our options leave the database with the solve, so a later solver gets the defaults back...
    assert solver.max_iterations == 1
    assert EnergyMinimizer(case.problem).max_iterations == DEFAULT_PETSC_OPTIONS["snes_max_it"]
    assert not PETSc.Options().hasName("dolfinx_invertible_snes_max_it")
    # ...while options the caller put there (as on the command line) win over ours.
    PETSc.Options()["dolfinx_invertible_snes_max_it"] = 2
    try:
        assert EnergyMinimizer(case.problem, petsc_options={"snes_max_it": 7}).max_iterations == 2
    finally:
        PETSc.Options().delValue("dolfinx_invertible_snes_max_it")


def test_reason_names():
    reasons = PETSc.SNES.ConvergedReason
    assert snes_reason_name(reasons.DIVERGED_LINE_SEARCH) == "DIVERGED_LINE_SEARCH"
    assert snes_reason_name(reasons.CONVERGED_FNORM_ABS) == "CONVERGED_FNORM_ABS"
    assert snes_reason_name(-1234) == "UNKNOWN_REASON_-1234"


def test_load_steps_cut_after_failure_then_succeed():
    case = cantilever()
    # Calibrate: Newton iterations for one full step and for two half steps.
    solver = EnergyMinimizer(case.problem)
    full = solve_at(case, solver, 1.0).newton_iterations
    reference = case.u.x.array.copy()
    case.reset()
    halves = [solve_at(case, solver, t).newton_iterations for t in (0.5, 1.0)]
    max_iterations = max(halves)
    assert full > max_iterations, (full, halves)  # the premise: halves are easier than one step
    case.reset()
    case.set_time(0.0)

    limited = EnergyMinimizer(case.problem, petsc_options={"snes_max_it": max_iterations})
    loads: list[float] = []
    steps: list[float] = []

    def update_load(t: float) -> None:
        loads.append(t)
        case.set_time(t)

    results = solve_load_steps(limited, update_load, 1, on_step=lambda t, r: steps.append(t))
    # Try, restore, a retry at a quarter (the attempt ran to the cap: cut twice over), a step
    # grown back to a half, the rest of the way.
    assert loads == [1.0, 0.0, 0.25, 0.75, 1.0]
    assert steps == [0.25, 0.75, 1.0]
    assert len(results) == 3 and all(result.converged for result in results)
    tolerance = 1e-8 * np.abs(reference).max()
    np.testing.assert_allclose(case.u.x.array, reference, rtol=0, atol=tolerance)


def test_load_steps_raise_when_cuts_exhausted():
    case = cantilever()
    solver = EnergyMinimizer(case.problem, petsc_options={"snes_max_it": 1})
    loads: list[float] = []

    def update_load(t: float) -> None:
        loads.append(t)
        case.set_time(t)

    with pytest.raises(SolverError) as raised:
        solve_load_steps(solver, update_load, [0.5, 1.0], max_cuts=2)
    error = raised.value
    message = str(error)
    assert "DIVERGED_MAX_IT" in message
    assert "load step 1 of 2" in message
    assert "failed 2 times" in message  # 0.5, then a quarter of it: both cuts spent
    assert "pseudo-time 0.125" in message
    assert "last converged pseudo-time 0" in message
    assert (error.reason_name, error.step_index) == ("DIVERGED_MAX_IT", 1)
    assert (error.time_reached, error.time_tried) == (0.0, 0.125)
    assert isinstance(error, RuntimeError)
    assert loads == [0.5, 0.0, 0.125, 0.0]
    assert not case.u.x.array.any()  # the state of pseudo-time 0


@pytest.mark.parametrize(
    "steps", [0, -2, True, [], [0.5], [0.0, 1.0], [0.5, 0.5, 1.0], [0.6, 0.4, 1.0], [1.5], "1"]
)
def test_load_steps_validate_steps(steps):
    case = cantilever()
    solver = EnergyMinimizer(case.problem)
    with pytest.raises(ValueError, match="steps"):
        solve_load_steps(solver, case.set_time, steps)
    with pytest.raises(ValueError, match="max_cuts"):
        solve_load_steps(solver, case.set_time, 2, max_cuts=-1)


@pytest.mark.parametrize("dimension", [2, 3])
def test_rigid_body_modes_span_the_kernel_of_elasticity(dimension):
    comm = MPI.COMM_WORLD
    # Away from the origin, so that rotations are not orthogonal to translations from the start.
    corners = [np.full(dimension, 5.0), np.array([7.0, 6.0, 6.0][:dimension])]
    if dimension == 2:
        mesh = dolfinx.mesh.create_rectangle(comm, corners, [4, 2])
    else:
        mesh = dolfinx.mesh.create_box(comm, corners, [4, 2, 2])
    space = _compat.vector_function_space(mesh, 1)
    u, v = ufl.TrialFunction(space), ufl.TestFunction(space)
    strain = ufl.sym(ufl.grad(u))
    form = dolfinx.fem.form(
        ufl.inner(2.0 * strain + ufl.tr(strain) * ufl.Identity(dimension), ufl.grad(v)) * ufl.dx
    )
    matrix = dolfinx.fem.petsc.assemble_matrix(form)
    matrix.assemble()
    nullspace = rigid_body_near_nullspace(space)
    vectors = nullspace.getVecs()
    assert len(vectors) == {2: 3, 3: 6}[dimension]
    gram = np.array([[a.dot(b) for b in vectors] for a in vectors])
    np.testing.assert_allclose(gram, np.eye(len(vectors)), atol=1e-12)
    image = matrix.createVecLeft()
    for vector in vectors:
        matrix.mult(vector, image)
        assert image.norm() < 1e-12 * matrix.norm()


def test_distributed_solution_matches_serial_solution():
    distributed, serial = cantilever(MPI.COMM_WORLD), cantilever(MPI.COMM_SELF)
    assert serial.u.function_space.mesh.comm.size == 1
    for case in (distributed, serial):
        solver = EnergyMinimizer(
            case.problem, petsc_options={"snes_rtol": 1e-11, "snes_atol": 1e-12}
        )
        solve_load_steps(solver, case.set_time, 2)
    expected = values_at_points(serial.u, PROBE_POINTS)
    actual = values_at_points(distributed.u, PROBE_POINTS)
    np.testing.assert_allclose(actual, expected, rtol=0, atol=1e-8 * np.abs(expected).max())
    assert np.abs(expected).max() > 0.1
    # Every rank compared against its own serial solve; make sure they all saw the same thing.
    assert all(np.array_equal(actual, other) for other in MPI.COMM_WORLD.allgather(actual))


def test_a_restored_controller_takes_a_changed_budget_of_cuts():
    def failed_twice(max_cuts):
        controller = StepController(0.1, max_cuts=max_cuts)
        size = controller.size()
        for _ in range(2):
            usable = controller.failed(size)
            size = controller.size()
        return controller, usable, size

    saved, usable, size = failed_twice(2)
    assert usable and size == pytest.approx(0.025)
    state = saved.state()
    assert not saved.failed(size)  # the third cut is past a budget of two
    for max_cuts, next_cut_usable in ((2, False), (3, True)):
        controller = StepController(0.1, max_cuts=max_cuts)
        controller.restore(state)
        assert controller.size() == pytest.approx(0.025) and controller.consecutive_cuts == 2
        assert controller.failed(0.025) is next_cut_usable
    # A checkpoint written before the budget was saved restores the budget as it was.
    older = {name: value for name, value in state.items() if name != "max_cuts"}
    controller = StepController(0.1, max_cuts=3)
    controller.restore(older)
    assert not controller.failed(0.025)


def _converged(newton_iterations: int) -> SolveResult:
    return SolveResult(True, 2, "CONVERGED_FNORM_RELATIVE", newton_iterations, 0, 0.0, None, 0.0)


def test_a_size_that_keeps_failing_is_retried_after_exponentially_more_steps():
    # Every step above 0.025 fails, every step at or below it is easy: the controller grows
    # back to the failed size after 1, 2, 4, ... accepted steps, not after every one.
    controller = StepController(0.1, max_cuts=6)
    attempts = []
    while len(controller.accepted) < 40:
        size = controller.size()
        attempts.append(size)
        if size > 0.025 * (1 + 1e-12):
            assert controller.failed(size)
        else:
            controller.succeeded(size, _converged(3))
    retries = [i for i, size in enumerate(attempts) if size == pytest.approx(0.05)]
    accepted_between = [
        sum(1 for size in attempts[a + 1 : b] if size <= 0.025 * (1 + 1e-12))
        for a, b in zip(retries, retries[1:])
    ]
    assert accepted_between[:4] == [1, 2, 4, 8]
    assert controller.cuts == len(retries) + 1  # the first attempt at 0.1, then each retry
    # Without the backoff the failed size would have been retried after every accepted step.
    assert controller.cuts < len(controller.accepted) / 4


def _failed(stage: str) -> SolveResult:
    return SolveResult(False, -5, "DIVERGED_MAX_IT", 200, 0, 0.0, None, 0.0, stage=stage)


@pytest.mark.parametrize(
    ("stage", "sizes"),
    [("iteration cap", [0.1, 0.025, 0.00625]), ("stalled", [0.1, 0.05, 0.025, 0.0125, 0.00625])],
)
def test_an_attempt_that_ran_to_the_iteration_cap_is_cut_twice_over(stage, sizes):
    # Every step above 0.01 fails: after attempts at the cap the stepping gets there in two
    # cuts, after attempts stopped sooner (stalled) in four.
    controller = StepController(0.1, max_cuts=6)
    tried = []

    def attempt(start: float, end: float) -> SolveResult:
        tried.append(end - start)
        return _converged(3) if end - start <= 0.01 else _failed(stage)

    size, result = take_step(controller, 0.0, 1.0, attempt, lambda t: None, lambda *a: "")
    assert tried == pytest.approx(sizes) and size == pytest.approx(0.00625)
    assert result.converged and controller.cuts == len(sizes) - 1


def test_a_cut_twice_over_spends_two_of_the_budget():
    # Three cuts: a quarter (two), then a half (the one left), then none.
    controller = StepController(0.1, max_cuts=3)
    assert controller.failed(0.1, exhausted=True) and controller.size() == pytest.approx(0.025)
    assert controller.failed(0.025, exhausted=True) and controller.size() == pytest.approx(0.0125)
    assert not controller.failed(0.0125, exhausted=True)
    assert controller.consecutive_cuts == 3  # failed attempts, as the messages count them


def test_the_ceiling_lifts_once_a_step_of_its_size_is_accepted():
    controller = StepController(0.1, max_cuts=6)
    assert controller.failed(0.1) and controller.failed(0.05)  # two cuts: at 0.025 now
    controller.succeeded(controller.size(), _converged(3))
    assert controller.size() == pytest.approx(0.05)  # the first retry after one step
    assert controller.failed(0.05)
    controller.succeeded(controller.size(), _converged(3))
    assert controller.size() == pytest.approx(0.025)  # the second waits for two
    state = controller.state()
    controller.succeeded(controller.size(), _converged(3))
    assert controller.size() == pytest.approx(0.05)
    controller.succeeded(0.05, _converged(3))  # the retry goes through: growth as before
    assert controller.size() == pytest.approx(0.1)
    # The hold survives a checkpoint.
    restored = StepController(0.1, max_cuts=6)
    restored.restore(state)
    restored.succeeded(restored.size(), _converged(3))
    assert restored.size() == pytest.approx(0.05)
    # A checkpoint written before the ceiling was saved restores none (growth as it was).
    memory = ("ceiling", "hold", "held")
    older = {name: value for name, value in state.items() if name not in memory}
    restored = StepController(0.1, max_cuts=6)
    restored.restore(older)
    restored.succeeded(restored.size(), _converged(3))
    assert restored.size() == pytest.approx(0.05)
