"""Truncated CG against dense linear algebra on small symmetric matrices (serial PETSc)."""

from __future__ import annotations

import numpy as np
import pytest
from petsc4py import PETSc

from dolfinx_invertible import _compat
from dolfinx_invertible.solvers.truncated_cg import truncated_cg

REASONS = PETSc.KSP.ConvergedReason


def _matrix(dense: np.ndarray) -> PETSc.Mat:
    matrix = PETSc.Mat().createDense(dense.shape, array=dense.copy(), comm=PETSc.COMM_SELF)
    matrix.assemble()
    return matrix


def _solve(
    operator: np.ndarray,
    preconditioner: np.ndarray,
    rhs: np.ndarray,
    pc: str,
    *,
    restart: bool = True,
):
    A, P = _matrix(operator), _matrix(preconditioner)
    b = PETSc.Vec().createWithArray(rhs.copy(), comm=PETSc.COMM_SELF)
    x = b.duplicate()
    ksp = PETSc.KSP().create(comm=PETSc.COMM_SELF)
    context = truncated_cg(ksp)
    ksp.setOperators(P, P)  # the preconditioner sees only the SPD matrix
    context.operator = A
    context.restart = restart
    ksp.getPC().setType(pc)
    ksp.setTolerances(rtol=1e-12, atol=0.0, max_it=500)
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
