"""The contact term between surfaces (IPC Toolkit): derivatives by finite differences, the
projected tangent, the κ rule against an independent measurement, the step cap, the refusal of
crossing bodies, and the same values on any number of ranks.
"""

from mpi4py import MPI

import dolfinx
import dolfinx.fem
import ipctk
import numpy as np
import pytest
import ufl
from petsc4py import PETSc

from dolfinx_invertible import _compat
from dolfinx_invertible.contact import BodyContactTerm, GatheredSurface, SurfaceIntersectionError
from dolfinx_invertible.meshes.blocks import cube_cells, cubes_mesh

SIDE = 1.0
GAP = 0.03


def two_cubes(comm, offset=(0.2, 0.1, SIDE + GAP), resolution=2):
    """A cube at the origin and one above it, ``offset`` between their centres."""
    return cubes_mesh(comm, np.array([[0.0, 0.0, 0.0], offset]), SIDE, resolution)


def two_squares(comm, gap=GAP):
    """Two unit squares of 2 × 2 × 2 triangles, one above the other."""
    line = np.linspace(0.0, 1.0, 3)
    grid = np.stack(np.meshgrid(line, line, indexing="ij"), axis=-1).reshape(-1, 2)
    corner = (np.arange(2)[:, None] * 3 + np.arange(2)[None, :]).ravel()
    triangles = np.vstack([np.column_stack([corner, corner + 3, corner + 4]),
                           np.column_stack([corner, corner + 4, corner + 1])])  # fmt: skip
    points = np.vstack([grid, grid + [0.15, 1.0 + gap]])
    cells = np.vstack([triangles, triangles + len(grid)])
    return _compat.create_mesh_from_cells(comm, points, cells, "triangle")


def field(space, seed, scale):
    """A smooth pseudo-random vector field, the same on any partition."""
    function = dolfinx.fem.Function(space)
    d = space.mesh.geometry.dim

    def values(x):
        return np.stack([scale * np.sin(7.1 * x[0] + 3.3 * x[1] + 5.7 * x[2] + seed + 1.9 * k)
                         for k in range(d)])  # fmt: skip

    function.interpolate(values)
    function.x.scatter_forward()
    return function


def total_energy(term):
    return term.comm.allreduce(term.energy(), op=MPI.SUM)


def residual(term):
    array = np.zeros_like(term.u.x.array)
    term.add_residual(array)
    owned = term.u.function_space.dofmap.index_map.size_local * term.surface.dimension
    return array[:owned]


def tangent(term):
    space = term.u.function_space
    mass = dolfinx.fem.form(ufl.inner(ufl.TrialFunction(space), ufl.TestFunction(space)) * ufl.dx)
    matrix = _compat.create_matrix(mass)
    matrix.zeroEntries()
    term.add_tangent(matrix, np.zeros(0, dtype=np.int32))
    matrix.assemble()
    return matrix


def set_displacement(term, values):
    term.u.x.array[:] = values
    term.u.x.scatter_forward()


@pytest.mark.mpi
@pytest.mark.parametrize("dimension", [2, 3])
def test_gradient_and_hessian_match_finite_differences(dimension):
    comm = MPI.COMM_WORLD
    mesh = two_cubes(comm) if dimension == 3 else two_squares(comm)
    space = _compat.vector_function_space(mesh, 1)
    u = field(space, 0.0, 0.004)
    term = BodyContactTerm(u, youngs_modulus=1.0, distance=0.1, project_hessian=False)
    assert comm.allreduce(term.active_pairs()) > 0
    base = u.x.array.copy()
    direction = field(space, 1.0, 1.0).x.array
    owned = len(residual(term))
    gradient = residual(term)
    matrix = tangent(term)
    vector = matrix.createVecRight()
    vector.array[:] = direction[:owned]
    product = matrix.createVecLeft()
    matrix.mult(vector, product)

    step = 1e-6
    set_displacement(term, base + step * direction)
    energy_plus, gradient_plus = total_energy(term), residual(term)
    set_displacement(term, base - step * direction)
    energy_minus, gradient_minus = total_energy(term), residual(term)
    set_displacement(term, base)

    slope = comm.allreduce(float(gradient @ direction[:owned]), op=MPI.SUM)
    assert (energy_plus - energy_minus) / (2 * step) == pytest.approx(slope, rel=1e-6)
    difference = (gradient_plus - gradient_minus) / (2 * step)
    error = comm.allreduce(float(np.sum((difference - product.array) ** 2)), op=MPI.SUM)
    size = comm.allreduce(float(np.sum(difference**2)), op=MPI.SUM)
    assert size > 0.0
    assert np.sqrt(error / size) < 1e-5


def test_projected_hessian_is_positive_semidefinite():
    mesh = two_cubes(MPI.COMM_SELF)
    u = field(_compat.vector_function_space(mesh, 1), 0.0, 0.006)
    exact = BodyContactTerm(u, youngs_modulus=1.0, distance=0.1, project_hessian=False)
    projected = BodyContactTerm(u, youngs_modulus=1.0, distance=0.1)
    eigenvalues = {}
    for name, term in (("exact", exact), ("projected", projected)):
        matrix = tangent(term)
        dense = matrix.convert("dense").getDenseArray()
        eigenvalues[name] = np.linalg.eigvalsh(0.5 * (dense + dense.T))
    scale = eigenvalues["projected"].max()
    # This configuration has negative curvature, which the projection removes.
    assert eigenvalues["exact"].min() < -1e-6 * scale
    assert eigenvalues["projected"].min() > -1e-10 * scale


def test_stiffness_rule_gives_a_layer_of_material():
    """κ's rule: at a gap of d̂/2, pushing two faces together is as stiff as E/d̂ per area.

    Measured on meshes (not the calibration patch of the rule): a cube of side 1 above the
    middle of a cube of side 2, both at the same spacing; the second derivative of the energy as
    the small cube moves rigidly towards the large one, per unit area of its bottom face. The
    vertices along the small face's rim also carry the area of the side faces (ipctk's vertex
    areas), a share that falls like h: the ratio to E/d̂, extrapolated to h → 0 from two
    meshes (Richardson, first order), is 1.
    """
    ratios = []
    for resolution in (4, 8):
        apart = 0.1 * SIDE
        cubes = [
            ([0, 0, 0], 2 * SIDE, 2 * resolution),
            ([0, 0, 1.5 * SIDE + apart], SIDE, resolution),
        ]
        mesh = _compat.create_mesh_from_cells(MPI.COMM_SELF, *_merged(cubes), "tetrahedron")
        space = _compat.vector_function_space(mesh, 1)
        youngs_modulus = 1e3
        term = BodyContactTerm(dolfinx.fem.Function(space), youngs_modulus=youngs_modulus)
        upper = space.tabulate_dof_coordinates()[:, 2] > SIDE + 0.5 * apart

        def energy(gap, term=term, upper=upper, apart=apart):
            values = np.zeros((len(upper), 3))
            values[upper, 2] = gap - apart
            set_displacement(term, values.ravel())
            return total_energy(term)

        gap, step = 0.5 * term.distance, 1e-3 * term.distance
        curvature = (energy(gap + step) - 2 * energy(gap) + energy(gap - step)) / step**2
        ratios.append(curvature / SIDE**2 / (youngs_modulus / term.distance))
    assert ratios[0] > ratios[1] > 1.0
    assert 2 * ratios[1] - ratios[0] == pytest.approx(1.0, abs=0.1)


def _merged(cubes):
    """Points and cells of several axis-aligned cubes given as (centre, side, resolution)."""
    points, cells, offset = [], [], 0
    for centre, side, resolution in cubes:
        unit_points, unit_cells = cube_cells(resolution)
        points.append(np.asarray(centre) + side * unit_points)
        cells.append(unit_cells + offset)
        offset += len(unit_points)
    return np.concatenate(points), np.concatenate(cells)


@pytest.mark.mpi
def test_step_cap_stops_before_the_surfaces_meet():
    comm = MPI.COMM_WORLD
    mesh = two_cubes(comm, offset=(0.2, 0.1, SIDE + 0.2))
    space = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(space)
    term = BodyContactTerm(u, youngs_modulus=1.0)
    motion = dolfinx.fem.Function(space)
    motion.interpolate(lambda x: np.stack([0 * x[0], 0 * x[0], -0.4 * (x[2] > 0.5 * SIDE)]))
    vector = _compat.petsc_vector(motion)
    cap = term.step_limit(fraction=0.9).largest_step(vector)
    # The first contact is at half the step: the cap is at most 0.9 of it.
    assert 0.3 < cap <= 0.45 + 1e-9
    set_displacement(term, cap * motion.x.array)
    assert term.intersections() == 0 and term.minimum_distance() > 0.0
    # Away from each other, nothing is in the way.
    assert term.step_limit().largest_step(vector, sign=-1.0) == 1.0


@pytest.mark.mpi
@pytest.mark.parametrize("gap", [GAP, 0.2])
def test_a_step_shorter_than_half_the_closest_distance_needs_no_ccd(gap, monkeypatch):
    comm = MPI.COMM_WORLD
    mesh = two_cubes(comm, offset=(0.2, 0.1, SIDE + gap))
    space = _compat.vector_function_space(mesh, 1)
    term = BodyContactTerm(dolfinx.fem.Function(space), youngs_modulus=1.0)
    start = term.positions()
    bound = term.distance_bound(start)
    # Within d̂ the bound is the smallest distance itself; farther apart it is d̂, below it.
    if gap < term.distance:
        assert bound == pytest.approx(term.minimum_distance(), rel=1e-12)
    else:
        assert bound == term.distance < term.minimum_distance()
    calls = []
    ccd = ipctk.compute_collision_free_stepsize
    monkeypatch.setattr(
        ipctk, "compute_collision_free_stepsize", lambda *a, **k: calls.append(1) or ccd(*a, **k)
    )
    limit = term.step_limit(fraction=0.9)
    for seed in range(4):
        motion = field(space, seed, 1.0)
        reach = np.max(np.linalg.norm(term.surface.motion(motion.x.array), axis=1))
        motion.x.array[:] *= 0.999 * 0.9 * bound / (2.0 * comm.allreduce(reach, op=MPI.MAX))
        vector = _compat.petsc_vector(motion)
        assert limit.largest_step(vector) == 1.0 and not calls
        # ipctk's CCD along the same stretched path agrees: nothing collides.
        end = start + term.surface.motion(motion.x.array) / 0.9
        assert ccd(term.collision_mesh, np.asfortranarray(start), np.asfortranarray(end)) == 1.0
        # Twice as far the bound does not hold, and the CCD is asked.
        vector.scale(2.0)
        limit.largest_step(vector)
        assert len(calls) == 1
        calls.clear()


@pytest.mark.mpi
def test_surface_is_gathered_whole_on_every_rank():
    comm = MPI.COMM_WORLD
    resolution = 3
    mesh = two_cubes(comm, resolution=resolution)
    surface = GatheredSurface(_compat.vector_function_space(mesh, 2))
    per_cube = 6 * resolution**2 + 2
    assert len(surface) == 2 * per_cube
    assert len(surface.facets) == 2 * 6 * 2 * resolution**2
    assert surface.body_count == 2
    assert np.bincount(surface.bodies).tolist() == [per_cube, per_cube]
    assert surface.area == pytest.approx(12 * SIDE**2)
    assert comm.allreduce(len(surface.owned), op=MPI.SUM) == len(surface)
    # Every rank holds the same surface.
    assert comm.allgather(surface.reference.tobytes()) == [surface.reference.tobytes()] * comm.size


@pytest.mark.mpi
def test_the_gathered_surface_is_the_same_on_any_number_of_ranks():
    """Vertices, facets and bodies in one order whatever the partition (ipctk's sets and sums
    then see the same surface); every vertex of a facet is a surface vertex of its body."""
    spaces = [
        _compat.vector_function_space(two_cubes(comm), 1)
        for comm in (MPI.COMM_SELF, MPI.COMM_WORLD)
    ]
    surfaces = [GatheredSurface(space) for space in spaces]
    serial, distributed = surfaces
    # The positions as the meshes have them: a partition may round a coordinate differently.
    np.testing.assert_allclose(distributed.reference, serial.reference, rtol=0.0, atol=1e-14)
    assert np.array_equal(distributed.facets, serial.facets)
    assert np.array_equal(distributed.bodies, serial.bodies)
    # Numbered x first, then y, then z.
    steps = np.diff(np.round(serial.reference, 9), axis=0)
    first = np.argmax(steps != 0.0, axis=1)
    assert np.all(steps[np.arange(len(steps)), first] > 0.0)
    assert np.all(np.diff(serial.facets, axis=1) > 0)
    assert np.all(serial.bodies[serial.facets] == serial.bodies[serial.facets[:, :1]])
    # The numbering still maps each vertex to its own displacement: X + u at u = X reads 2 X.
    for space, surface in zip(spaces, surfaces, strict=True):
        u = dolfinx.fem.Function(space)
        u.interpolate(lambda x: x[:3])
        np.testing.assert_allclose(surface.positions(u.x.array), 2.0 * surface.reference)


@pytest.mark.mpi
@pytest.mark.parametrize("friction", [0.0, 0.5])
def test_distributed_equals_serial(friction):
    # Each rank adds the rows of the vertices it owns: the sums are the serial values, the
    # tangent's included.
    values = {}
    for comm in (MPI.COMM_SELF, MPI.COMM_WORLD):
        mesh = two_cubes(comm)
        space = _compat.vector_function_space(mesh, 1)
        u = field(space, 0.0, 0.004)
        term = BodyContactTerm(
            u, youngs_modulus=1.0, distance=0.1, friction=friction, friction_velocity=1e-3
        )
        motion = field(space, 2.0, 0.05)
        if friction:
            term.set_time(0.01)  # the friction lagged here; then the surfaces slip
            set_displacement(term, u.x.array + 0.02 * motion.x.array)
        gradient = residual(term)
        matrix = tangent(term)
        direction = _compat.petsc_vector(motion)
        product = direction.duplicate()
        matrix.mult(direction, product)
        values[comm.size] = (
            total_energy(term),
            np.sqrt(comm.allreduce(float(gradient @ gradient), op=MPI.SUM)),
            matrix.norm(PETSc.NormType.FROBENIUS),
            product.norm(),
            term.minimum_distance(),
            term.step_limit().largest_step(direction),
        )
        assert term.active_pairs() > 0
        assert (term._tangential is not None) == bool(friction)  # the friction acts
    serial, distributed = values[1], values[MPI.COMM_WORLD.size]
    np.testing.assert_allclose(distributed, serial, rtol=1e-11)


@pytest.mark.mpi
def test_the_state_names_the_closest_pair_and_its_bodies_for_a_failed_solve():
    """Two cubes, one a gap GAP above the other, with d̂ wider than the gap: the clause a
    failed solve's message adds counts the pairs, gives the gap, both bodies and a point
    between the facing sides, and κ at its initial value."""
    mesh = two_cubes(MPI.COMM_WORLD)
    term = BodyContactTerm(dolfinx.fem.Function(_compat.vector_function_space(mesh, 1)),
                           youngs_modulus=1.0, distance=0.05)  # fmt: skip
    text = term.describe_state()
    pairs = term.active_pairs()
    assert pairs > 0 and term.minimum_distance() == pytest.approx(GAP, rel=1e-12)
    prefix = (
        f"contact: {pairs} surface pairs within d̂ = 0.05 m, κ = {term.stiffness:.3g} (1 × its "
        f"initial value); the closest pair {GAP:.3g} m apart, between bodies 0 and 1, at ("
    )
    assert text.startswith(prefix)
    point = [float(value) for value in text[len(prefix) : -1].split(", ")]
    bottom_top = term.surface.reference[:, 2].min() + SIDE
    assert bottom_top - 1e-9 <= point[2] <= bottom_top + GAP + 1e-9


def test_crossing_bodies_are_refused_naming_them():
    mesh = two_cubes(MPI.COMM_SELF, offset=(0.3, 0.2, 0.8))
    term = BodyContactTerm(dolfinx.fem.Function(_compat.vector_function_space(mesh, 1)),
                           youngs_modulus=1.0)  # fmt: skip
    assert term.intersections() > 0
    with pytest.raises(SurfaceIntersectionError, match=r"body [01]'s .* crosses body [01]'s"):
        term.check_intersection_free()


@pytest.mark.mpi
def test_a_body_that_starts_compressed_gets_a_distance_to_match():
    """d̂ follows the surface spacing as the bodies start: both cubes at half their size (a
    uniform compression about the origin, no surface crossing) halve d̂ and h."""
    mesh = two_cubes(MPI.COMM_WORLD, resolution=1)
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))
    undeformed = BodyContactTerm(u, youngs_modulus=1.0e3)
    u.interpolate(lambda x: -0.5 * x)
    compressed = BodyContactTerm(u, youngs_modulus=1.0e3)
    assert compressed.spacing == pytest.approx(0.5 * undeformed.spacing, rel=1e-12)
    assert compressed.distance == pytest.approx(0.5 * undeformed.distance, rel=1e-12)
    assert undeformed.spacing == pytest.approx(undeformed.surface.spacing, rel=1e-12)


def test_cube_cells_fill_the_cube():
    points, cells = cube_cells(3)
    corners = points[cells]
    volumes = np.linalg.det(corners[:, 1:] - corners[:, :1]) / 6
    assert np.sum(np.abs(volumes)) == pytest.approx(1.0)
    assert np.all(np.abs(volumes) > 0)


def test_needs_a_scale_for_the_stiffness():
    mesh = two_cubes(MPI.COMM_SELF)
    with pytest.raises(ValueError, match="stiffness needs a scale"):
        BodyContactTerm(dolfinx.fem.Function(_compat.vector_function_space(mesh, 1)))
    assert PETSc.IntType is not None


@pytest.mark.mpi
def test_stiffness_adapts_while_the_smallest_distance_keeps_falling_below_a_share_of_dhat():
    """IPC's rule with its threshold a share of d̂: κ doubles at a step whose distance fell
    below 5 % of d̂, and fell further since the last step; a retried step or a distance that
    does not fall leaves it; it stops at 100 times its start."""
    comm = MPI.COMM_WORLD
    mesh = two_cubes(comm, resolution=1)
    space = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(space)
    term = BodyContactTerm(u, youngs_modulus=1.0e3)
    initial = term.stiffness
    points = mesh.geometry.x
    middle = 0.5 * (
        comm.allreduce(points[:, 2].min(), op=MPI.MIN)
        + comm.allreduce(points[:, 2].max(), op=MPI.MAX)
    )
    epsilon = 0.05 * term.distance
    upper = space.tabulate_dof_coordinates()[:, 2] > middle

    def step(t, gap):
        u.x.array[:] = 0.0
        u.x.array.reshape(-1, 3)[upper, 2] = gap - GAP
        term.set_time(t)
        assert term.minimum_distance() == pytest.approx(gap, rel=1e-3)
        return term.stiffness / initial

    assert step(1.0, 1.01 * epsilon) == 1.0
    assert step(2.0, 0.99 * epsilon) == 1.0  # the distance was above ε at the last step
    assert step(3.0, 0.25 * epsilon) == 2.0
    assert step(4.0, 0.25 * epsilon) == 2.0  # not falling
    term.set_time(3.0)  # a cut step goes back to its start and retries from the same state
    assert step(3.5, 0.25 * epsilon) == 2.0
    ratios = [step(5.0 + k, 0.2 * epsilon * 0.8**k) for k in range(8)]
    # Doubling is exact in floating point; the cap is 100 κ₀ rounded.
    assert ratios == pytest.approx([4.0, 8.0, 16.0, 32.0, 64.0, 100.0, 100.0, 100.0], rel=1e-14)
    state = term.checkpoint_state()
    fresh = BodyContactTerm(u, youngs_modulus=1.0e3, adaptive_stiffness=False)
    fresh.restore(state)
    assert fresh.stiffness == term.stiffness and fresh.energy() == term.energy()


@pytest.mark.mpi
def test_friction_between_surfaces_resists_the_slip_with_its_gradient():
    """ipctk's lagged friction: the energy's slope matches the gradient; sliding costs energy."""
    comm = MPI.COMM_WORLD
    mesh = two_cubes(comm)
    space = _compat.vector_function_space(mesh, 1)
    u = field(space, 0.0, 0.004)
    term = BodyContactTerm(u, youngs_modulus=1.0, distance=0.1, friction=0.5,
                           friction_velocity=0.01)  # fmt: skip
    frictionless = BodyContactTerm(u, youngs_modulus=1.0, distance=0.1)
    term.set_time(0.0)
    term.set_time(0.01)  # lagged at the current state, for a step of 0.01
    base = u.x.array.copy()
    upper = space.tabulate_dof_coordinates()[:, 2] > 0.5 * SIDE
    slip = np.zeros((len(upper), 3))
    slip[upper, 0] = 0.003
    set_displacement(term, base + slip.ravel())
    owned = len(residual(term))
    gradient = residual(term) - residual(frictionless)
    # The friction's force on the upper cube points against its slip.
    along = comm.allreduce(float(gradient @ slip.ravel()[:owned]), op=MPI.SUM)
    assert along > 0.0
    direction = field(space, 1.0, 1.0).x.array
    step = 1e-7
    current = u.x.array.copy()
    set_displacement(term, current + step * direction)
    plus = total_energy(term)
    set_displacement(term, current - step * direction)
    minus = total_energy(term)
    set_displacement(term, current)
    slope = comm.allreduce(float(residual(term) @ direction[:owned]), op=MPI.SUM)
    assert (plus - minus) / (2 * step) == pytest.approx(slope, rel=1e-5)
