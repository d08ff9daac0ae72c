"""The DOLFINx layer: boundary weights as a surface quadrature, the term's assembled residual and
tangent against finite differences of its energy, the collision-free step on rigid motions, the
separation of swept vertices, refused input. Collective: runs serially and under mpirun, where
every vertex must be counted once whatever the partition.
"""

import math

from mpi4py import MPI

import dolfinx
import numpy as np
import pytest
from contact_meshes import allsum, box, displacement, tangent_matrix
from petsc4py import PETSc

import dolfinx_invertible as di
from dolfinx_invertible import _compat
from dolfinx_invertible.contact import (
    BoundaryVertices,
    Cone,
    ContactTerm,
    HalfSpace,
    RigidMotion,
    Sphere,
)

COMM = MPI.COMM_WORLD
MATERIAL = di.Material(di.NeoHookean(mu=1.0e3, lam=2.0e3), extension=di.C2(eps=0.9))


def boundary_integrals(lower, upper):
    """∫_∂Ω 1 dA and ∫_∂Ω x₀ dA of a box, from its faces."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    size = upper - lower
    d = len(size)
    area = 0.0
    first_moment = 0.0
    for k in range(d):
        face = np.prod(np.delete(size, k))
        area += 2 * face
        # Faces normal to x₀ sit at lower[0] and upper[0]; the others have x₀ centred.
        if k == 0:
            first_moment += face * (lower[0] + upper[0])
        else:
            first_moment += 2 * face * 0.5 * (lower[0] + upper[0])
    return area, first_moment


@pytest.mark.mpi
@pytest.mark.parametrize(
    "cell, degree",
    [
        ("triangle", 1),
        ("quadrilateral", 1),
        ("tetrahedron", 1),
        ("tetrahedron", 2),
        ("hexahedron", 1),
    ],
)
def test_weights_are_a_boundary_quadrature_counting_each_vertex_once(cell, degree):
    d = 2 if cell in ("triangle", "quadrilateral") else 3
    lower, upper = [0.2, -0.1, 0.0][:d], [1.4, 0.5, 0.3][:d]
    cells = [5, 3, 2][:d]
    mesh = box(COMM, lower, upper, cells, cell)
    boundary = BoundaryVertices(displacement(mesh, degree).function_space)
    area, first_moment = boundary_integrals(lower, upper)
    assert boundary.area == pytest.approx(area, rel=1e-12)
    # The P1 hat rule integrates linear functions exactly.
    moment = allsum(COMM, float(np.sum(boundary.weights * boundary.reference[:, 0])))
    assert moment == pytest.approx(first_moment, rel=1e-12)
    grid = np.prod(np.array(cells) + 1) - np.prod(np.maximum(np.array(cells) - 1, 0))
    assert boundary.count == grid
    # Every boundary vertex exactly once over the ranks, each at a boundary point.
    points = np.concatenate(COMM.allgather(boundary.reference))
    assert len(np.unique(np.round(points, 12), axis=0)) == grid
    on_boundary = np.any(np.isclose(points, lower) | np.isclose(points, upper), axis=1)
    assert on_boundary.all()
    expected_spacing = (area / grid) ** (1.0 / (d - 1))
    assert boundary.spacing == pytest.approx(expected_spacing)


def active_obstacles():
    # The bottom of the unit cube just above a floor, its corners close to a bowl, and a cone
    # about the vertical axis whose wall passes near the vertical edges: all three curve away
    # from the body or are flat, so the exact Hessian is already positive semidefinite.
    return [
        HalfSpace((0.0, 0.0, 1.0), -0.06),
        Sphere((0.5, 0.5, 0.5), 0.5 * math.sqrt(3.0) + 0.07, inside=True),
        Cone.between((0.5, 0.5, -1.0), (0.5, 0.5, 1.0), 0.86, 0.76),
    ]


def smooth_displacement(u, amplitude=0.02):
    u.interpolate(
        lambda x: (
            amplitude
            * np.stack(
                [np.sin(3 * x[1] + 1.0), np.cos(2 * x[0] - x[2]), np.sin(x[0] + 2 * x[1]) - 0.5]
            )
        )
    )


def term_on_unit_cube(degree=1, comm=COMM, **options):
    mesh = dolfinx.mesh.create_unit_cube(comm, 3, 3, 3)
    u = displacement(mesh, degree)
    smooth_displacement(u)
    options.setdefault("distance", 0.12)
    term = ContactTerm(u, active_obstacles(), MATERIAL, **options)
    return term, u


def global_energy(term):
    return allsum(term.comm, term.energy())


def residual_vector(term, u):
    vector = _compat.petsc_vector(u).duplicate()
    with vector.localForm() as local:
        local.set(0.0)
        term.add_residual(local.array)
    vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return vector


def random_direction(u, seed):
    direction = u.copy()
    rng = np.random.default_rng(seed)
    direction.interpolate(
        lambda x: np.stack([np.sin(rng.uniform(1, 4) * x[k] + rng.uniform(0, 6)) for k in range(3)])
    )
    return direction


def shifted(u, direction, epsilon):
    values = u.x.array.copy()
    u.x.array[:] = values + epsilon * direction.x.array
    return values


def central_differences(term, u, direction, epsilon=1e-6):
    """The energies at u ± ε·direction and the residual's central difference along it."""
    values = shifted(u, direction, epsilon)
    plus, residual_plus = global_energy(term), residual_vector(term, u)
    u.x.array[:] = values - epsilon * direction.x.array
    minus, residual_minus = global_energy(term), residual_vector(term, u)
    u.x.array[:] = values
    fd = residual_plus.copy()
    fd.axpy(-1.0, residual_minus)
    fd.scale(1.0 / (2 * epsilon))
    return plus, minus, fd


@pytest.mark.mpi
@pytest.mark.parametrize("degree", [1, 2])
def test_residual_and_tangent_are_derivatives_of_the_energy(degree):
    term, u = term_on_unit_cube(degree)
    assert term.active_vertices() >= 20
    assert term.penetrations() == 0
    residual = residual_vector(term, u)
    matrix = tangent_matrix(u.function_space)
    term.add_tangent(matrix, np.zeros(0, dtype=np.int32))
    matrix.assemble()
    product = residual.duplicate()
    epsilon = 1e-6
    for seed in range(3):
        direction = random_direction(u, seed)
        direction_vector = _compat.petsc_vector(direction)
        plus, minus, fd = central_differences(term, u, direction, epsilon)
        slope = residual.dot(direction_vector)
        assert slope == pytest.approx((plus - minus) / (2 * epsilon), rel=1e-6)
        matrix.mult(direction_vector, product)
        difference = product.copy()
        difference.axpy(-1.0, fd)
        assert difference.norm() <= 1e-6 * fd.norm()
        assert fd.norm() > 0.0
    # The tangent is symmetric positive semidefinite.
    assert matrix.isSymmetric(1e-10 * matrix.norm())
    direction_vector = _compat.petsc_vector(random_direction(u, 7))
    matrix.mult(direction_vector, product)
    assert product.dot(direction_vector) >= 0.0


@pytest.mark.mpi
def test_tangent_leaves_out_constrained_rows_and_columns():
    term, u = term_on_unit_cube()
    matrix = tangent_matrix(u.function_space)
    # Constrain the z components of this rank's bottom vertices (active against the floor).
    bottom = term.boundary.dofs[np.isclose(term.boundary.reference[:, 2], 0.0), 2]
    term.add_tangent(matrix, bottom.astype(np.int32))
    matrix.assemble()
    full = tangent_matrix(u.function_space)
    term.add_tangent(full, np.zeros(0, dtype=np.int32))
    full.assemble()
    assert allsum(COMM, len(bottom)) > 0
    rows = u.function_space.dofmap.index_map.local_range[0] * 3 + bottom
    for row in rows.astype(np.int32):
        columns, values = matrix.getRow(int(row))
        assert np.all(values == 0.0)
    assert full.norm() > matrix.norm() > 0.0


def test_serial_and_distributed_terms_agree():
    term, _ = term_on_unit_cube()
    serial, _ = term_on_unit_cube(comm=MPI.COMM_SELF)
    assert global_energy(term) == pytest.approx(serial.energy(), rel=1e-12)
    assert term.minimum_gap() == pytest.approx(serial.minimum_gap(), rel=1e-12)
    np.testing.assert_allclose(term.contact_force(), serial.contact_force(), rtol=1e-11)
    assert term.active_vertices() == serial.active_vertices()


test_serial_and_distributed_terms_agree = pytest.mark.mpi(test_serial_and_distributed_terms_agree)


@pytest.mark.mpi
def test_collision_free_step_is_exact_for_rigid_translations():
    term, u = term_on_unit_cube(distance=0.01)
    limit = term.step_limit(fraction=0.9)
    x = np.concatenate(COMM.allgather(term.positions()))
    velocity = np.array([0.1, -0.2, -1.0])
    direction = u.copy()
    direction.interpolate(lambda p: np.tile(velocity[:, None], (1, p.shape[1])))
    vector = _compat.petsc_vector(direction)
    # sign −1 moves the body by −α·direction: towards +z, away from the floor, into the bowl.
    floor = (x[:, 2] + 0.06) / 1.0
    expected_floor = np.min(floor)
    sphere_c, sphere_r = np.array([0.5, 0.5, 0.5]), 0.5 * math.sqrt(3.0) + 0.07

    def sphere_root(point, p):
        # |point + α p − c|² = r², the positive root, by numpy's polynomial solver.
        offset = point - sphere_c
        roots = np.roots([p @ p, 2 * offset @ p, offset @ offset - sphere_r**2])
        return min(r.real for r in roots if abs(r.imag) < 1e-14 and r.real > 0)

    expected_bowl = min(sphere_root(point, -velocity) for point in x)
    cone = active_obstacles()[2]
    expected_cone = np.min(cone.path_crossing(x, np.tile(-velocity, (len(x), 1))))
    expected = min(1.0, 0.9 * min(expected_bowl, expected_cone))
    assert limit.largest_step(vector, sign=-1.0) == pytest.approx(expected, rel=1e-12)
    assert expected < 1.0
    # Downwards the floor comes first: its gap is linear in the step.
    scaled = vector.copy()
    scaled.scale(-1.0)
    down = limit.largest_step(scaled, sign=-1.0)
    expected_down = min(
        1.0,
        0.9
        * min(
            expected_floor,
            min(sphere_root(point, velocity) for point in x),
            float(np.min(cone.path_crossing(x, np.tile(velocity, (len(x), 1))))),
        ),
    )
    assert down == pytest.approx(expected_down, rel=1e-12)
    # A tiny motion is not capped.
    scaled.scale(1e-6)
    assert limit.largest_step(scaled, sign=-1.0) == 1.0


@pytest.mark.mpi
def test_moving_obstacle_is_evaluated_at_the_term_time_and_swept_vertices_separate():
    mesh = dolfinx.mesh.create_unit_cube(COMM, 3, 3, 3)
    u = displacement(mesh)
    plate = HalfSpace(
        (0.0, 0.0, -1.0), -1.05, motion=RigidMotion(3, translation=lambda t: (0.0, 0.0, -t))
    )
    term = ContactTerm(u, plate, MATERIAL, distance=0.02)
    assert term.minimum_gap() == pytest.approx(0.05)
    term.set_time(0.04)
    assert term.minimum_gap() == pytest.approx(0.01)
    assert math.isfinite(global_energy(term))
    term.set_time(0.3)  # the plate has swept over the top layer (z = 1) and reached z = 0.75
    assert term.minimum_gap() == pytest.approx(-0.25)
    assert term.penetrations() == 16
    assert global_energy(term) == math.inf
    local = np.zeros_like(u.x.array)
    term.add_residual(local)
    assert allsum(COMM, int(np.isnan(local).sum())) == 16 * 3
    moved = term.separate()
    assert moved == 16
    assert term.penetrations() == 0
    assert term.minimum_gap() == pytest.approx(0.01, rel=1e-12)  # d̂/2
    z = term.positions()[:, 2]
    top = np.isclose(term.boundary.reference[:, 2], 1.0)
    np.testing.assert_allclose(z[top], 0.74, rtol=1e-12)
    assert term.separate() == 0


def test_bad_input_is_refused():
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
    floor = HalfSpace((0.0, 0.0, 1.0), -0.1)
    with pytest.raises(ValueError, match="degree"):
        ContactTerm(displacement(mesh, 3), floor, MATERIAL)
    with pytest.raises(ValueError, match="2D but the mesh is 3D"):
        ContactTerm(displacement(mesh), HalfSpace((0.0, 1.0), 0.0), MATERIAL)
    with pytest.raises(ValueError, match="scale"):
        ContactTerm(displacement(mesh), floor)
    with pytest.raises(ValueError, match="Material"):
        ContactTerm(displacement(mesh), floor, "rubber")
    with pytest.raises(ValueError, match="distance"):
        ContactTerm(displacement(mesh), floor, MATERIAL, distance=-1.0)
    with pytest.raises(ValueError, match="time"):
        ContactTerm(displacement(mesh), floor, MATERIAL).set_time(math.nan)
    with pytest.raises(ValueError, match="fraction"):
        ContactTerm(displacement(mesh), floor, MATERIAL).step_limit(fraction=1.5)
    scalar = dolfinx.fem.Function(_compat.scalar_function_space(mesh, 1, "Lagrange"))
    with pytest.raises(ValueError, match="components"):
        ContactTerm(scalar, floor, MATERIAL)


def test_default_parameters_follow_the_rules():
    mesh = dolfinx.mesh.create_unit_cube(MPI.COMM_SELF, 4, 4, 4)
    u = displacement(mesh)
    term = ContactTerm(u, HalfSpace((0.0, 0.0, 1.0), -0.1), MATERIAL)
    h = term.boundary.spacing
    assert h == pytest.approx(math.sqrt(6.0 / 98.0))  # 6 faces, 5³ − 3³ boundary vertices
    assert term.barrier.distance == pytest.approx(0.1 * h)
    E = MATERIAL.model.youngs_modulus
    assert term.barrier.stiffness == pytest.approx(E / ((5 + 2 * math.log(2)) * h))
    custom = ContactTerm(
        u, HalfSpace((0.0, 0.0, 1.0), -0.1), youngs_modulus=2 * E, distance_fraction=0.3
    )
    assert custom.barrier.stiffness == pytest.approx(2 * term.barrier.stiffness)
    assert custom.barrier.distance == pytest.approx(0.3 * h)
    fixed = ContactTerm(u, HalfSpace((0.0, 0.0, 1.0), -0.1), stiffness=5.0, distance=0.2)
    assert (fixed.barrier.stiffness, fixed.barrier.distance) == (5.0, 0.2)


@pytest.mark.mpi
def test_the_hessian_is_exact_or_projected_as_the_problem_asks():
    # A ball just above the cube's top: there the barrier is concave along the surface, so its
    # exact Hessian (what finite differences of the residual give) is indefinite and differs
    # from the projection.
    ball = Sphere((0.5, 0.5, 1.0 + 0.3 + 0.03), 0.3)
    mesh = dolfinx.mesh.create_unit_cube(COMM, 3, 3, 3)
    u = displacement(mesh)
    term = ContactTerm(u, ball, MATERIAL, distance=0.12)
    assert term.project_hessian is None and term.projected  # no problem has asked yet
    assert allsum(COMM, term.active_vertices()) > 0
    problem = di.HyperelasticProblem(u, MATERIAL, terms=[term])
    assert not term.projected  # "auto": exact, replaced where it gives no descent
    matrices = {}
    for projected in (True, False):
        problem.energy_problem.set_term_projection(projected)
        matrices[projected] = tangent_matrix(u.function_space)
        term.add_tangent(matrices[projected], np.zeros(0, dtype=np.int32))
        matrices[projected].assemble()
    exact, positive = matrices[False], matrices[True]
    direction = random_direction(u, 3)
    _, _, fd = central_differences(term, u, direction)
    direction_vector = _compat.petsc_vector(direction)
    product = fd.duplicate()
    exact.mult(direction_vector, product)
    product.axpy(-1.0, fd)
    assert product.norm() <= 1e-6 * fd.norm()
    difference = exact.copy()
    difference.axpy(-1.0, positive)
    assert difference.norm() > 1e-3 * positive.norm()
    # The problem's fixed tangents ask for the projection: nothing would replace a bad direction.
    for project in (True, False):
        di.HyperelasticProblem(u, MATERIAL, terms=[term], project=project)
        assert term.projected
    fixed = ContactTerm(u, ball, MATERIAL, distance=0.12, project_hessian=False)
    di.HyperelasticProblem(u, MATERIAL, terms=[fixed], project=True)
    assert not fixed.projected
    with pytest.raises(ValueError, match="project_hessian"):
        ContactTerm(u, ball, MATERIAL, project_hessian="yes")


@pytest.mark.mpi
def test_the_state_names_the_closest_obstacle_for_a_failed_solve():
    """The clause a failed solve's message adds: the vertices the barrier holds and the smallest
    gap, the obstacle and the point, as the term's own figures and an independent search say."""
    term, u = term_on_unit_cube()
    text = term.describe_state()
    gaps = term.gaps()
    local = (float(gaps.min()), int(np.argmin(gaps.min(axis=1)))) if gaps.size else (np.inf, -1)
    smallest, obstacle = min(term.comm.allgather(local))
    assert smallest == term.minimum_gap() and 0.0 < smallest < term.barrier.distance
    name = type(active_obstacles()[obstacle]).__name__
    assert text.startswith(
        f"obstacle contact: {term.active_vertices()} boundary vertices within d̂ = 0.12 of an "
        f"obstacle; the smallest gap {smallest:.3g}, to obstacle {obstacle} ({name}), at ("
    )
    assert term.active_vertices() > 0
