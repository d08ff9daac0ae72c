"""Material parameters given as DOLFINx Constants: read at every assembly, never recompiled.

The FEniCSx tutorial writes ``mu = fem.Constant(mesh, 3846.0)``; a sweep over ``mu.value`` must
change the assembled forms exactly as a new material with that value would, and anything that is
not a real number or a scalar Constant (a UFL expression, an array) is refused at once.
"""

from __future__ import annotations

import time

from mpi4py import MPI

import dolfinx
import dolfinx.fem.petsc
import numpy as np
import pytest
import ufl
from petsc4py import PETSc

from dolfinx_invertible import C1, C2, HyperelasticForms, Material, NeoHookean, _compat, lame
from dolfinx_invertible.fem import kernels

pytestmark = pytest.mark.mpi

MU, LAM = lame(10.0, 0.3)


def _state():
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2)
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))
    # Compressed to J ≈ 0.81 in part of the cube: the C2 extension is active there.
    u.interpolate(lambda x: np.stack([-0.3 * x[0] ** 2, 0.02 * x[2], 0.01 * x[1]]))
    u.x.scatter_forward()
    return mesh, u


def _residual(forms) -> np.ndarray:
    vector = dolfinx.fem.petsc.assemble_vector(forms.residual)
    vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return vector.array.copy()


def _energy(forms) -> float:
    return MPI.COMM_WORLD.allreduce(dolfinx.fem.assemble_scalar(forms.energy), op=MPI.SUM)


@pytest.mark.parametrize("extension", ["C2", "C1"])
def test_sweep_over_constant_values_matches_new_materials(extension):
    mesh, u = _state()
    mu = dolfinx.fem.Constant(mesh, MU)
    lam = dolfinx.fem.Constant(mesh, PETSc.ScalarType(LAM))
    eps = dolfinx.fem.Constant(mesh, 0.9 if extension == "C2" else 0.5)

    def make(mu_value, lam_value, eps_value):
        if extension == "C2":
            return Material(NeoHookean(mu=mu_value, lam=lam_value), C2(eps=eps_value))
        # k = None: 20·E, which must follow the Constants too.
        return Material(NeoHookean(mu=mu_value, lam=lam_value), C1(eps=eps_value))

    forms = HyperelasticForms(u, make(mu, lam, eps))
    first = _residual(forms)
    _energy(forms)
    compiled = kernels.compiled_kernels()
    for mu_value, lam_value, eps_value in [(2.0 * MU, LAM, 0.9), (0.5 * MU, 3.0 * LAM, 0.8)]:
        if extension == "C1":
            eps_value -= 0.4
        mu.value = mu_value
        lam.value = lam_value
        eps.value = eps_value
        swept = _residual(forms)
        reference = HyperelasticForms(u, make(mu_value, lam_value, eps_value))
        expected = _residual(reference)
        assert np.abs(swept - expected).max() <= 1e-14 * np.abs(expected).max()
        assert not np.allclose(swept, first)
        assert _energy(forms) == pytest.approx(_energy(reference), rel=1e-14)
    # The kernels of both materials were compiled before the sweep (same kind): nothing new.
    assert kernels.compiled_kernels() == compiled


def test_batch_api_reads_the_current_value():
    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, 1, 1)
    mu = dolfinx.fem.Constant(mesh, MU)
    material = Material(NeoHookean(mu=mu, lam=LAM), C2())
    F = np.array([np.diag([1.2, 0.9]), np.diag([1.0, -0.5])])
    before = material.stress(F)
    mu.value = 3.0 * MU
    np.testing.assert_array_equal(
        material.stress(F), Material(NeoHookean(mu=3.0 * MU, lam=LAM), C2()).stress(F)
    )
    assert not np.allclose(material.stress(F), before)
    assert material.model.mu == 3.0 * MU
    mu.value = -1.0
    with pytest.raises(ValueError, match="mu"):
        material.energy(F)


def test_set_material_keeps_the_constants():
    mesh, u = _state()
    mu = dolfinx.fem.Constant(mesh, MU)
    forms = HyperelasticForms(u, Material(NeoHookean(mu=mu, lam=LAM), C2()))
    _residual(forms)
    forms.set_material(Material(NeoHookean(mu=2.0 * MU, lam=LAM), C2()))  # a number now
    mu.value = 5.0 * MU  # no longer read
    expected = _residual(HyperelasticForms(u, Material(NeoHookean(mu=2.0 * MU, lam=LAM), C2())))
    assert np.abs(_residual(forms) - expected).max() <= 1e-14 * np.abs(expected).max()
    other = dolfinx.fem.Constant(mesh, MU)
    with pytest.raises(ValueError, match="build new forms"):
        forms.set_material(Material(NeoHookean(mu=other, lam=LAM), C2()))


@pytest.mark.parametrize(
    "make_value",
    [
        lambda mesh: 2.0 * dolfinx.fem.Constant(mesh, MU),  # a UFL expression
        lambda mesh: ufl.as_ufl(MU) * dolfinx.fem.Constant(mesh, 1.0),
        lambda mesh: np.array([MU]),
        lambda mesh: dolfinx.fem.Constant(mesh, np.array([MU, MU])),  # not scalar
        lambda mesh: "3846.0",
    ],
)
def test_anything_else_is_refused_at_once(make_value):
    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, 1, 1)
    value = make_value(mesh)
    start = time.perf_counter()
    with pytest.raises(TypeError, match="real number or a scalar dolfinx.fem.Constant"):
        NeoHookean(mu=value, lam=LAM)
    with pytest.raises(TypeError, match="lam must be"):
        NeoHookean(mu=MU, lam=value)
    with pytest.raises(TypeError, match="eps must be"):
        C2(eps=value)
    assert time.perf_counter() - start < 1.0
