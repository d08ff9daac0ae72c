"""The solvers' observation API: Newton iterations, step caps and step attempts.

Every record is checked against what the solver reports independently (the solve result's
residual history and counts) or against a quantity computed afresh (the energy at the iterate).
"""

from __future__ import annotations

from mpi4py import MPI

import dolfinx
import numpy as np
import pytest
import ufl

from dolfinx_invertible import C2, Material, NeoHookean, _compat, lame, vector_function_space
from dolfinx_invertible.solvers import (
    DIRECTION_KINDS,
    HyperelasticProblem,
    ImplicitDynamics,
    InversionFreeStep,
    NewtonIteration,
    StepAttempt,
    StepCap,
    solve_load_steps,
)

MU, LAM = lame(1.0e3, 0.3)


def _beam(comm=MPI.COMM_WORLD, **options):
    """A clamped 1 × 0.3 × 0.3 beam of plain Neo-Hookean under a downward end traction."""
    mesh = dolfinx.mesh.create_box(
        comm, [np.zeros(3), np.array([1.0, 0.3, 0.3])], [6, 2, 2], dolfinx.mesh.CellType.tetrahedron
    )
    V = vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(V)
    clamped = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 0.0))
    bc = dolfinx.fem.dirichletbc(np.zeros(3), dolfinx.fem.locate_dofs_topological(V, 2, clamped), V)
    end = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[0], 1.0))
    tags = dolfinx.mesh.meshtags(mesh, 2, end, np.full(len(end), 1, dtype=np.int32))
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags)
    traction = dolfinx.fem.Constant(mesh, np.zeros(3))
    problem = HyperelasticProblem(
        u,
        Material(NeoHookean(mu=MU, lam=LAM)),
        [bc],
        external_energy=-ufl.dot(traction, u) * ds(1),
        **options,
    )

    def load(t: float) -> None:
        traction.value[:] = (0.0, 0.0, -40.0 * t)

    return problem, load


@pytest.mark.mpi
def test_iteration_records_match_the_solve_and_the_state():
    problem, load = _beam()
    records: list[NewtonIteration] = []
    states: list[tuple[float, float | None, bool]] = []

    def on_iteration(record: NewtonIteration) -> None:
        records.append(record)
        # u holds the iterate during the call: the energy at u is the energy at the iterate.
        u_vector = _compat.petsc_vector(problem.u)
        difference = record.iterate.copy()
        difference.axpy(-1.0, u_vector)
        states.append((problem.energy_problem.total_energy(), record.energy, difference.norm()))

    remove = problem.add_monitor(on_iteration=on_iteration)
    load(1.0)
    result = problem.solve()
    assert result.converged and result.newton_iterations >= 3

    assert [record.iteration for record in records] == list(range(result.newton_iterations + 1))
    assert {record.solve for record in records} == {records[0].solve}
    norms = [record.residual_norm for record in records]
    assert norms == pytest.approx(list(result.residual_history), rel=1e-14)
    assert sum(record.linear_iterations for record in records) == result.linear_iterations
    first, later = records[0], records[1:]
    assert first.direction is None and first.step_length is None and first.step_cap is None
    for record in later:
        assert record.direction in DIRECTION_KINDS
        assert 0.0 < record.step_length <= 1.0 and record.step_cap == 1.0
        assert record.linear_reason.startswith("CONVERGED")
    assert all(distance == 0.0 for _, _, distance in states)
    for energy, reported, _ in states:
        if reported is not None:
            assert reported == pytest.approx(energy, rel=1e-13)
    assert any(reported is not None for _, reported, _ in states)

    # A second solve is numbered as such; a removed monitor hears nothing more.
    count = len(records)
    load(1.2)
    assert problem.solve().converged
    assert records[-1].solve == records[0].solve + 1
    remove()
    count = len(records)
    load(1.4)
    assert problem.solve().converged
    assert len(records) == count


@pytest.mark.mpi
def test_step_caps_are_reported_per_limit_and_iteration():
    """The inversion-free cap on a large load step: every cap is seen, the smallest recorded."""
    problem, load = _beam(inversion_free=0.98)
    caps: list[StepCap] = []
    records: list[NewtonIteration] = []
    problem.add_monitor(on_iteration=records.append, on_step_cap=caps.append)
    load(3.0)
    result = problem.solve()
    assert result.converged
    limits = {id(cap.limit) for cap in caps}
    assert len(limits) == 1 and isinstance(caps[0].limit, InversionFreeStep)
    assert all(0.0 <= cap.cap <= 1.0 for cap in caps)
    assert any(cap.cap < 1.0 for cap in caps)  # the load is large enough to be capped
    for record in records[1:]:
        seen = [cap.cap for cap in caps if cap.iteration == record.iteration - 1]
        assert record.step_cap == min(seen, default=1.0)
        assert record.step_length <= record.step_cap


@pytest.mark.mpi
def test_attempts_report_the_cut_and_the_accepted_step():
    """A one-iteration cap fails the full load; the cut steps are reported, failed ones first."""
    problem, load = _beam(petsc_options={"snes_max_it": 4})
    attempts: list[StepAttempt] = []
    solve_load_steps(problem, load, 1, on_attempt=attempts.append, max_cuts=8)
    assert not attempts[0].accepted and attempts[0].result.stage == "iteration cap"
    assert attempts[0].start == 0.0 and attempts[0].end == 1.0
    assert attempts[-1].accepted and attempts[-1].end == pytest.approx(1.0)
    for earlier, later in zip(attempts, attempts[1:]):
        if not earlier.accepted:  # retried from the same start, a quarter after the cap
            cut = 0.25 if earlier.result.stage == "iteration cap" else 0.5
            assert later.start == earlier.start
            assert later.end - later.start == pytest.approx(cut * (earlier.end - earlier.start))
        else:
            assert later.start == pytest.approx(earlier.end)


def test_replaced_directions_are_named_and_counted():
    """Out of a collapse the exact tangent is indefinite: blended directions replace it.

    The step of tests/solvers/test_robustness.py's blended-tangent test.
    """
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_SELF, 4, 4, 4, dolfinx.mesh.CellType.tetrahedron)
    u = dolfinx.fem.Function(vector_function_space(mesh, 1))
    u.interpolate(lambda x: -0.95 * (x - 0.5))
    mu, lam = lame(1.0e3, 0.49)
    dynamics = ImplicitDynamics(
        u, Material(NeoHookean(mu=mu, lam=lam), C2()), density=1.0e3, dt=1.5625e-3, blend_after=0
    )
    records: list[NewtonIteration] = []
    attempts: list[StepAttempt] = []
    dynamics.add_monitor(on_iteration=records.append, on_attempt=attempts.append)
    result = dynamics.step()
    assert result.converged and len(attempts) == 1 and attempts[0].accepted
    kinds = [record.direction for record in records[1:]]
    assert kinds.count("blended") == result.blended_iterations > 0
    assert kinds.count("projected") + kinds.count("blended") == result.projected_iterations
