"""Truncated CG against dense linear algebra on small symmetric matrices (serial PETSc)."""

from __future__ import annotations

import numpy as np
import pytest
from petsc4py import PETSc

from dolfinx_invertible import _compat
from dolfinx_invertible.solvers import truncated_cg as truncated_cg_module
from dolfinx_invertible.solvers.truncated_cg import DEFINITE_FLOOR, MINRES_BUDGET, truncated_cg

REASONS = PETSc.KSP.ConvergedReason


def _matrix(operator: np.ndarray) -> PETSc.Mat:
    """A dense matrix, or a diagonal one (sparse) from a vector of its entries."""
    if operator.ndim == 1:
        matrix = PETSc.Mat().createAIJ((operator.size, operator.size), nnz=1, comm=PETSc.COMM_SELF)
        for row, entry in enumerate(operator):
            matrix.setValue(row, row, entry)
    else:
        matrix = PETSc.Mat().createDense(
            operator.shape, array=operator.copy(), comm=PETSc.COMM_SELF
        )
    matrix.assemble()
    return matrix


def _solve(
    operator: np.ndarray,
    preconditioner: np.ndarray,
    rhs: np.ndarray,
    pc: str,
    *,
    restart: bool = True,
    radius: float = np.inf,
    indefinite: bool = False,
    max_it: int = 500,
    definite_iterations: int | None = None,
    preconditioning: np.ndarray | None = None,
    fixed: np.ndarray | None = None,
):
    """``preconditioning``: the matrix the preconditioner is built on, if not ``preconditioner``
    (the projected tangent, which AMG only approximates); ``fixed``: the context's fixed rows."""
    A, P = _matrix(operator), _matrix(preconditioner)
    M = P if preconditioning is None else _matrix(preconditioning)
    b = PETSc.Vec().createWithArray(rhs.copy(), comm=PETSc.COMM_SELF)
    x = b.duplicate()
    ksp = PETSc.KSP().create(comm=PETSc.COMM_SELF)
    context = truncated_cg(ksp)
    if fixed is not None:
        context.fixed = fixed.astype(np.int32)
    ksp.setOperators(P, M)  # the preconditioner sees only an SPD matrix
    context.operator = A
    context.restart = restart
    context.radius = radius
    context.indefinite = indefinite
    context.definite_iterations = definite_iterations
    ksp.getPC().setType(pc)
    ksp.setTolerances(rtol=1e-12, atol=0.0, max_it=max_it)
    ksp.solve(b, x)
    result = (ksp.getConvergedReason(), ksp.getIterationNumber(), x.getArray().copy(), context)
    ksp.destroy()
    return result


def _spd(rng, n: int, smallest: float) -> np.ndarray:
    basis, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return basis @ np.diag(np.linspace(smallest, 10.0, n)) @ basis.T


@pytest.mark.parametrize("pc", ["none", "jacobi"])
def test_definite_operator_gives_the_exact_solution(pc):
    rng = np.random.default_rng(3)
    operator = _spd(rng, 40, 0.5)
    rhs = rng.standard_normal(40)
    reason, iterations, x, context = _solve(operator, operator, rhs, pc)
    assert reason > 0 and reason != _compat.KSP_CONVERGED_NEGATIVE_CURVATURE
    assert context.outcome == "exact" and context.curvature_iteration is None
    np.testing.assert_allclose(x, np.linalg.solve(operator, rhs), rtol=1e-9, atol=1e-12)
    assert 0 < iterations <= 40 + 1  # CG on n unknowns, in exact arithmetic at most n steps


def test_negative_curvature_switches_to_the_preconditioning_matrix():
    """An operator with a negative eigenvalue: CG meets it, and the SPD matrix's solution comes
    back (preconditioned by its exact inverse, that solve takes one iteration)."""
    rng = np.random.default_rng(5)
    basis, _ = np.linalg.qr(rng.standard_normal((30, 30)))
    eigenvalues = np.linspace(1.0, 10.0, 30)
    eigenvalues[0] = -3.0
    operator = basis @ np.diag(eigenvalues) @ basis.T
    projected = basis @ np.diag(np.abs(eigenvalues)) @ basis.T  # the clamped-at-|λ| tangent
    rhs = rng.standard_normal(30)
    reason, iterations, x, context = _solve(operator, projected, rhs, "lu")
    assert reason == _compat.KSP_CONVERGED_NEGATIVE_CURVATURE
    assert context.outcome == "projected" and context.curvature_iteration is not None
    np.testing.assert_allclose(x, np.linalg.solve(projected, rhs), rtol=1e-10, atol=1e-12)
    assert rhs @ x > 0.0  # a descent direction for the step x ↦ −x of SNES
    assert iterations == context.curvature_iteration + 1


def test_without_restart_negative_curvature_fails_the_solve():
    """Without restarts (the iterative path's AMG built on the exact tangent, which cannot
    precondition the projected one), the solve stops where CG meets negative curvature."""
    operator = np.diag([1.0, 2.0, -5.0])
    rhs = np.array([0.1, 0.1, 1.0])
    reason, iterations, _, context = _solve(operator, np.eye(3), rhs, "none", restart=False)
    assert reason == REASONS.DIVERGED_INDEFINITE_MAT
    assert context.outcome == "failed" and context.curvature_iteration == iterations == 0


def test_curvature_is_detected_where_cg_meets_it():
    """Diagonal operator, identity preconditioner: the first search direction is b itself, so
    bᵀAb ≤ 0 stops CG before any iteration."""
    operator = np.diag([1.0, 2.0, -5.0])
    rhs = np.array([0.1, 0.1, 1.0])  # bᵀAb = 0.01 + 0.02 − 5 < 0
    reason, iterations, x, context = _solve(operator, np.eye(3), rhs, "none")
    assert reason == _compat.KSP_CONVERGED_NEGATIVE_CURVATURE and context.curvature_iteration == 0
    np.testing.assert_allclose(x, rhs, rtol=1e-14)  # the identity's solution


def test_an_indefinite_preconditioner_fails():
    operator = np.eye(3)
    preconditioner = np.diag([1.0, -1.0, 1.0])
    reason, _, _, context = _solve(operator, preconditioner, np.array([0.0, 1.0, 0.0]), "lu")
    assert reason == REASONS.DIVERGED_INDEFINITE_PC and context.outcome == "failed"


def _indefinite(rng, n: int, negative: float) -> tuple[np.ndarray, np.ndarray]:
    """A symmetric operator with one negative eigenvalue, and its clamped-at-|λ| tangent."""
    basis, _ = np.linalg.qr(rng.standard_normal((n, n)))
    eigenvalues = np.linspace(1.0, 10.0, n)
    eigenvalues[0] = negative
    return basis @ np.diag(eigenvalues) @ basis.T, basis @ np.diag(np.abs(eigenvalues)) @ basis.T


@pytest.mark.parametrize("pc", ["none", "jacobi", "lu"])
def test_indefinite_newton_solves_the_exact_system_past_negative_curvature(pc):
    """With ``indefinite``, MINRES takes over where CG meets negative curvature and returns the
    exact Newton direction K⁻¹ b, here a descent direction (b's component along the negative
    eigenvector is small, as near a saddle point)."""
    rng = np.random.default_rng(7)
    operator, projected = _indefinite(rng, 30, -0.5)
    rhs = projected @ rng.standard_normal(30)
    negative_direction = np.linalg.eigh(operator)[1][:, 0]
    rhs -= 0.9 * (rhs @ negative_direction) * negative_direction
    exact = np.linalg.solve(operator, rhs)
    assert rhs @ exact > 0.0
    reason, iterations, x, context = _solve(operator, projected, rhs, pc, indefinite=True)
    assert reason > 0 and reason != _compat.KSP_CONVERGED_NEGATIVE_CURVATURE
    assert context.outcome == "exact" and context.curvature_iteration is not None
    np.testing.assert_allclose(x, exact, rtol=1e-8, atol=1e-10)
    assert iterations > context.curvature_iteration
    # Without it the same system gives the projected tangent's direction.
    _, _, x, context = _solve(operator, projected, rhs, pc)
    assert context.outcome == "projected"
    np.testing.assert_allclose(x, np.linalg.solve(projected, rhs), rtol=1e-8, atol=1e-10)


def test_indefinite_newton_keeps_the_projected_direction_where_the_exact_one_ascends():
    """Where K⁻¹ b is not a descent direction (b mostly along the negative eigenvector), the
    solve falls back on the projected tangent, as without ``indefinite``."""
    operator = np.diag([1.0, 2.0, -5.0])
    rhs = np.array([0.1, 0.1, 1.0])  # bᵀK⁻¹b = 0.01 + 0.005 − 0.2 < 0
    projected = np.diag([1.0, 2.0, 5.0])
    reason, _, x, context = _solve(operator, projected, rhs, "lu", indefinite=True)
    assert reason == _compat.KSP_CONVERGED_NEGATIVE_CURVATURE and context.outcome == "projected"
    np.testing.assert_allclose(x, np.linalg.solve(projected, rhs), rtol=1e-12)
    assert rhs @ x > 0.0


def _nearly_singular(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A diagonal operator with eigenvalues of both signs down to 10⁻³, the clamped one, and a
    right-hand side along which the exact direction descends: MINRES needs thousands of
    iterations (6 814 at n = 1 000), CG on the clamped operator a few hundred (428)."""
    negative = -np.logspace(-3.0, 0.0, n // 10)
    positive = np.logspace(-3.0, 0.0, n - n // 10)
    operator = np.concatenate([negative, positive])
    rhs = np.concatenate([1e-3 * np.ones(n // 10), np.ones(n - n // 10)])
    return operator, np.abs(operator), rhs


def test_a_definite_solve_sets_the_budget_of_minres():
    """The iterations of a solve that converged on a definite operator are MINRES's unit."""
    operator, projected, rhs = _nearly_singular(1000)
    reason, iterations, _, context = _solve(projected, projected, rhs, "none", max_it=10_000)
    assert reason > 0 and context.outcome == "exact"
    assert context.definite_iterations == iterations > DEFINITE_FLOOR


def test_minres_stops_at_its_budget_and_the_projected_direction_comes_back(monkeypatch):
    """Past negative curvature MINRES gets MINRES_BUDGET times the last definite solve's
    iterations (at least DEFINITE_FLOOR of them): on a nearly singular exact tangent it stops
    there and the projected tangent's direction comes back. With an unbounded budget the same
    solve runs MINRES to the exact direction, after more iterations than the budget allows."""
    operator, projected, rhs = _nearly_singular(1000)
    budget = MINRES_BUDGET * DEFINITE_FLOOR
    exact_direction = rhs / operator
    assert rhs @ exact_direction > 0.0  # MINRES's direction would be kept: only the budget stops it
    reason, iterations, x, context = _solve(
        operator, projected, rhs, "none", indefinite=True, max_it=50_000, definite_iterations=1
    )
    assert reason == _compat.KSP_CONVERGED_NEGATIVE_CURVATURE and context.outcome == "projected"
    np.testing.assert_allclose(x, rhs / projected, rtol=1e-6)
    _, projected_alone, _, _ = _solve(projected, projected, rhs, "none", max_it=50_000)
    assert iterations == context.curvature_iteration + budget + projected_alone

    monkeypatch.setattr(truncated_cg_module, "MINRES_BUDGET", 10**6)
    reason, iterations, x, context = _solve(
        operator, projected, rhs, "none", indefinite=True, max_it=50_000, definite_iterations=1
    )
    assert reason > 0 and context.outcome == "exact"
    np.testing.assert_allclose(x, exact_direction, rtol=1e-5)
    assert iterations - context.curvature_iteration > budget


# -- Steihaug–Toint: CG bounded by a trust region in the preconditioner's norm -----------------


def _model(operator: np.ndarray, rhs: np.ndarray, x: np.ndarray) -> float:
    """Newton's quadratic model of the step x (SNES steps to −x): −bᵀx + ½ xᵀAx."""
    return float(-rhs @ x + 0.5 * x @ operator @ x)


def _cauchy_model(operator: np.ndarray, rhs: np.ndarray, radius: float) -> float:
    """The model at the Cauchy point: its minimiser along b within ‖x‖₂ ≤ radius."""
    length = radius / np.linalg.norm(rhs)
    curvature = rhs @ operator @ rhs
    if curvature > 0.0:
        length = min(length, (rhs @ rhs) / curvature)
    return _model(operator, rhs, length * rhs)


def test_a_radius_beyond_the_newton_step_changes_nothing():
    rng = np.random.default_rng(11)
    operator = _spd(rng, 30, 0.5)
    rhs = rng.standard_normal(30)
    newton = np.linalg.solve(operator, rhs)
    radius = 1.01 * np.sqrt(newton @ operator @ newton)  # the norm of M = A (preconditioner lu)
    reason, _, x, context = _solve(operator, operator, rhs, "lu", radius=radius)
    assert reason == REASONS.CONVERGED_RTOL and context.outcome == "exact"
    assert not context.boundary
    np.testing.assert_allclose(x, newton, rtol=1e-10)
    assert context.step_norm == pytest.approx(np.sqrt(x @ operator @ x), rel=1e-10)


def test_a_definite_step_stops_on_the_boundary_in_the_preconditioner_norm():
    """With M = A the bounded problem's solution is the Newton step scaled to the radius."""
    rng = np.random.default_rng(12)
    operator = _spd(rng, 30, 0.5)
    rhs = rng.standard_normal(30)
    newton = np.linalg.solve(operator, rhs)
    radius = 0.3 * np.sqrt(newton @ operator @ newton)
    reason, _, x, context = _solve(operator, operator, rhs, "lu", radius=radius)
    assert reason == REASONS.CONVERGED_STEP_LENGTH
    assert context.outcome == "bounded" and context.boundary
    assert np.sqrt(x @ operator @ x) == pytest.approx(radius, rel=1e-10)
    np.testing.assert_allclose(x, 0.3 * newton, rtol=1e-9)
    assert context.step_norm == radius


@pytest.mark.parametrize("negative", [0, 1, 3])
def test_an_indefinite_operator_is_followed_to_the_boundary(negative):
    """Identity preconditioner: the step ends on the Euclidean ball's boundary, is a descent
    direction, and lowers the model at least as much as the Cauchy point (Steihaug's bound).
    With `negative` = 0 the operator is definite and the radius cuts CG short."""
    rng = np.random.default_rng(20 + negative)
    basis, _ = np.linalg.qr(rng.standard_normal((25, 25)))
    eigenvalues = np.linspace(0.5, 10.0, 25)
    eigenvalues[:negative] = -np.linspace(1.0, 4.0, negative)
    operator = basis @ np.diag(eigenvalues) @ basis.T
    rhs = rng.standard_normal(25)
    radius = 0.05 * np.linalg.norm(rhs)
    reason, iterations, x, context = _solve(operator, np.eye(25), rhs, "none", radius=radius)
    assert reason > 0 and context.outcome == "bounded" and context.boundary
    assert np.linalg.norm(x) == pytest.approx(radius, rel=1e-10)
    assert rhs @ x > 0.0
    assert _model(operator, rhs, x) <= _cauchy_model(operator, rhs, radius) + 1e-12
    assert iterations >= 1 or negative > 0


def test_the_step_norm_recurrence_matches_the_preconditioner_norm():
    """Jacobi preconditioning (M = diag A): the recurrence's ‖x‖_M against xᵀ diag(A) x."""
    rng = np.random.default_rng(13)
    operator = _spd(rng, 30, 0.2) + np.diag(np.linspace(1.0, 50.0, 30))
    rhs = rng.standard_normal(30)
    for radius in (np.inf, 0.2):
        _, _, x, context = _solve(operator, operator, rhs, "jacobi", radius=radius)
        norm = np.sqrt(x @ np.diag(np.diag(operator)) @ x)
        assert context.step_norm == pytest.approx(norm, rel=1e-9)
        assert context.boundary == (radius < np.inf)


def test_in_a_trust_region_the_exact_direction_replaces_the_boundary_where_it_descends():
    """``indefinite`` in a trust region: past negative curvature the exact Newton direction
    (descending here) instead of the boundary; where it ascends, Steihaug's boundary point.
    A radius that binds before any negative curvature bounds the step as before."""
    rng = np.random.default_rng(9)
    operator, projected = _indefinite(rng, 25, -0.5)
    negative_direction = np.linalg.eigh(operator)[1][:, 0]
    rhs = projected @ rng.standard_normal(25)
    rhs -= 0.9 * (rhs @ negative_direction) * negative_direction
    exact = np.linalg.solve(operator, rhs)
    radius = 2.0 * np.linalg.norm(exact)
    _, _, x, context = _solve(operator, np.eye(25), rhs, "none", radius=radius, indefinite=True)
    assert context.outcome == "exact" and not context.boundary
    assert context.curvature_iteration is not None
    np.testing.assert_allclose(x, exact, rtol=1e-8, atol=1e-10)
    radius = 0.01 * np.linalg.norm(rhs)
    _, _, x, context = _solve(operator, np.eye(25), rhs, "none", radius=radius, indefinite=True)
    assert context.outcome == "bounded" and context.curvature_iteration is None

    ascending = np.diag([1.0, 2.0, -5.0]), np.array([0.1, 0.1, 1.0])
    radius = 0.5
    _, _, x, context = _solve(*ascending[:1], np.eye(3), ascending[1], "none", radius=radius,
                              indefinite=True)  # fmt: skip
    assert context.outcome == "bounded" and context.boundary
    assert np.linalg.norm(x) == pytest.approx(radius, rel=1e-10)
    _, _, steihaug, _ = _solve(*ascending[:1], np.eye(3), ascending[1], "none", radius=radius)
    np.testing.assert_allclose(x, steihaug, rtol=1e-12)


def _with_dirichlet_rows(matrix: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """``matrix`` with the rows and columns ``fixed`` replaced by those of the identity."""
    matrix = matrix.copy()
    matrix[fixed, :] = 0.0
    matrix[:, fixed] = 0.0
    matrix[fixed, fixed] = 1.0
    return matrix


@pytest.mark.parametrize("radius", [np.inf, 0.05])
@pytest.mark.parametrize("indefinite", [False, True])
def test_dirichlet_rows_get_their_residual_whatever_the_preconditioner_couples(radius, indefinite):
    """Rows where both tangents are the identity and couple to nothing (Dirichlet rows) get the
    right-hand side's entry, exactly: 0 where the iterate already holds its boundary values, also
    where the solve stops early (on the trust region's boundary, at negative curvature, in
    MINRES) and the preconditioner couples those rows to the others, as AMG's coarse corrections
    do. Solved to the end, the Dirichlet rows' entries are the solution's there."""
    rng = np.random.default_rng(21)
    n, fixed = 24, np.array([0, 7, 8, 23])
    operator, projected = (_with_dirichlet_rows(m, fixed) for m in _indefinite(rng, n, -0.5))
    if not indefinite:
        operator = projected
    coupling = _spd(rng, n, 0.3)  # the preconditioner's matrix: every row coupled to every other
    rhs = rng.standard_normal(n)
    rhs[fixed] = 0.0
    _, iterations, x, context = _solve(
        operator, projected, rhs, "lu", radius=radius, indefinite=indefinite,
        preconditioning=coupling, fixed=fixed,
    )  # fmt: skip
    assert iterations > 0 and np.abs(x).max() > 0.0
    assert context.boundary == (radius < np.inf)
    assert np.all(x[fixed] == 0.0)

    rhs[fixed] = [0.5, -1.0, 2.0, 0.25]
    _, _, x, context = _solve(
        projected, projected, rhs, "lu", preconditioning=coupling, fixed=fixed
    )
    np.testing.assert_allclose(x, np.linalg.solve(projected, rhs), rtol=1e-9)
