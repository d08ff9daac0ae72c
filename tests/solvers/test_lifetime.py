"""Solvers and scene runs are freed when dropped, with their meshes and MPI communicators.

A mesh, its function spaces and every vector hold MPI communicators, and MPICH gives a process
2 048 of them: a script (or a test session) that builds a few hundred problems aborts in MPI
when they are never freed. A SNES callback bound to the object that owns the SNES is a
reference cycle through a petsc4py object, which Python's cycle collector cannot see through
in some petsc4py releases; these tests fail on such a release when a callback keeps its owner.
"""

from __future__ import annotations

import gc
import weakref

from mpi4py import MPI

import dolfinx
import numpy as np
import ufl

from dolfinx_invertible import C2, Material, NeoHookean, _compat, lame
from dolfinx_invertible.contact import ContactTerm, HalfSpace
from dolfinx_invertible.scenes import Parameters, get_scene, run_scene
from dolfinx_invertible.solvers import HyperelasticProblem, ImplicitDynamics


def _cube(comm):
    mesh = dolfinx.mesh.create_unit_cube(comm, 2, 2, 2, dolfinx.mesh.CellType.tetrahedron)
    return mesh, dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))


def _material():
    mu, lam = lame(1.0e4, 0.3)
    return Material(NeoHookean(mu=mu, lam=lam), C2())


def _freed(reference: weakref.ref) -> bool:
    gc.collect()
    return reference() is None


def test_a_solved_static_problem_is_freed_with_its_mesh():
    mesh, u = _cube(MPI.COMM_WORLD)
    bottom = dolfinx.mesh.locate_entities_boundary(mesh, 2, lambda x: np.isclose(x[2], 0.0))
    dofs = dolfinx.fem.locate_dofs_topological(u.function_space, 2, bottom)
    bc = dolfinx.fem.dirichletbc(np.zeros(3), dofs, u.function_space)
    load = dolfinx.fem.Constant(mesh, np.array([0.0, 0.0, -50.0]))
    problem = HyperelasticProblem(u, _material(), [bc], external_energy=ufl.dot(load, u) * ufl.dx)
    assert problem.solve().converged
    mesh_reference, problem_reference = weakref.ref(mesh), weakref.ref(problem)
    del mesh, u, bc, load, problem
    assert _freed(problem_reference)
    assert _freed(mesh_reference)


def test_a_time_stepper_with_contact_is_freed_with_its_mesh():
    mesh, u = _cube(MPI.COMM_WORLD)
    u.interpolate(lambda x: np.vstack([0.0 * x[0], 0.0 * x[1], 0.05 + 0.0 * x[2]]))
    material = _material()
    term = ContactTerm(u, HalfSpace((0.0, 0.0, 1.0), 0.0), material)
    dynamics = ImplicitDynamics(
        u,
        material,
        density=1.0e3,
        dt=0.01,
        gravity=(0.0, 0.0, -9.81),
        terms=[term],
        step_limits=[term.step_limit()],
    )
    assert dynamics.step().converged
    mesh_reference = weakref.ref(mesh)
    del mesh, u, term, dynamics
    assert _freed(mesh_reference)


def test_a_scene_run_leaves_no_mesh_alive():
    meshes: list[weakref.ref] = []
    scene = get_scene("collapse")
    parameters = Parameters(**{**scene.defaults, "resolution": 2, "t_end": 0.03})
    summary = run_scene(
        scene,
        parameters,
        comm=MPI.COMM_WORLD,
        on_step=lambda run: meshes.append(weakref.ref(run.mesh)),
    )
    assert summary["completed"] and meshes
    assert all(_freed(reference) for reference in meshes)
