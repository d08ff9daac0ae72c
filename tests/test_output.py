"""Per-cell diagnostics and the XDMF/JSONL result writer, on real DOLFINx meshes.

Runs serially and under mpirun: files are read back on rank 0 only, after a barrier, and the
checks compare values through the coordinates rather than through any node or cell order.
"""

import json

import dolfinx.fem
import dolfinx.mesh
import numpy as np
import pytest
from helpers import EPS_C1, EPS_C2, LAM, MU
from mpi4py import MPI

import dolfinx_invertible as di
from dolfinx_invertible import _compat
from dolfinx_invertible.diagnostics import ENERGY_SENTINEL, cell_diagnostics, summary
from dolfinx_invertible.output import DISPLACEMENT_NAME, ResultWriter

COMM = MPI.COMM_WORLD

# Upper triangular with shear, so that det A is set by the last diagonal entry.
SHEAR = {
    2: np.array([[1.2, 0.3], [0.0, 1.0]]),
    3: np.array([[1.1, 0.2, 0.1], [0.0, 0.9, 0.3], [0.0, 0.0, 1.0]]),
}
MATERIALS = {
    "plain": lambda: di.Material(di.NeoHookean(mu=MU, lam=LAM)),
    "C1": lambda: di.Material(di.NeoHookean(mu=MU, lam=LAM), extension=di.C1(eps=EPS_C1)),
    "C2": lambda: di.Material(di.NeoHookean(mu=MU, lam=LAM), extension=di.C2(eps=EPS_C2)),
    "IFE": lambda: di.Material(di.NeoHookean(mu=MU, lam=LAM), extension=di.IFE()),
}


def deformation(d, det):
    A = SHEAR[d].copy()
    A[-1, -1] = det / np.prod(np.diag(A)[:-1])
    return A


def unit_mesh(d):
    if d == 2:
        return dolfinx.mesh.create_unit_square(COMM, 4, 4)
    return dolfinx.mesh.create_unit_cube(COMM, 2, 2, 2)


def affine_displacement(mesh, A, degree=1, scale=1.0):
    """u = scale·(A − I)x, exact in any Lagrange space."""
    d = mesh.geometry.dim
    u = dolfinx.fem.Function(_compat.vector_function_space(mesh, "Lagrange", degree))
    u.interpolate(lambda x: scale * (A - np.eye(d)) @ x[:d])
    return u


def read_series(path):
    """(points, cells, [(t, point_data, cell_data), ...]) of an XDMF time series, via meshio."""
    try:
        import h5py  # noqa: F401
    except ImportError:
        pytest.fail("meshio needs h5py to read XDMF/HDF5 files: install python3-h5py")
    import meshio

    with meshio.xdmf.TimeSeriesReader(str(path)) as reader:
        points, cells = reader.read_points_cells()
        steps = [reader.read_data(k) for k in range(reader.num_steps)]
    return points, cells, steps


@pytest.fixture
def directory(tmp_path_factory):
    """One directory shared by all ranks (rank 0's temporary directory)."""
    path = tmp_path_factory.mktemp("output") if COMM.rank == 0 else None
    return COMM.bcast(path, root=0)


# --------------------------------------------------------------------------------------------
# cell_diagnostics
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("material_name", list(MATERIALS))
@pytest.mark.parametrize("det", [0.8, -0.5])
@pytest.mark.parametrize("d,degree", [(2, 1), (2, 2), (3, 1)])
def test_affine_deformation(d, degree, det, material_name):
    material = MATERIALS[material_name]()
    A = deformation(d, det)
    mesh = unit_mesh(d)
    diagnostics = cell_diagnostics(affine_displacement(mesh, A, degree), material)

    num_owned = mesh.topology.index_map(d).size_local
    assert set(diagnostics) == {
        "min_J",
        "inverted",
        "energy_density",
        "min_singular_value",
        "region",
    }
    for name, values in diagnostics.items():
        assert values.shape == (num_owned,), name
        assert values.dtype == np.float64, name
        assert np.all(np.isfinite(values)), name

    np.testing.assert_allclose(diagnostics["min_J"], np.linalg.det(A), rtol=0, atol=1e-12)
    assert np.all(diagnostics["inverted"] == (1.0 if det <= 0 else 0.0))
    smallest = np.linalg.svd(A, compute_uv=False)[-1] * np.sign(np.linalg.det(A))
    np.testing.assert_allclose(diagnostics["min_singular_value"], smallest, rtol=1e-12)
    assert np.all(diagnostics["region"] == float(material.regions(A)))

    if material_name == "IFE":
        expected = 0.0  # stress-only: no energy
    else:
        expected = material.energy(A)
        if not np.isfinite(expected):
            expected = ENERGY_SENTINEL
    np.testing.assert_allclose(diagnostics["energy_density"], expected, rtol=1e-12)


def test_region_codes_of_the_cases_above():
    """The affine cases cover the plain model, the extensions and the undefined region."""
    material = MATERIALS["plain"]()
    assert material.regions(deformation(2, 0.8)) == 0
    assert material.regions(deformation(2, -0.5)) == -1
    assert MATERIALS["C2"]().regions(deformation(2, -0.5)) > 0
    assert MATERIALS["C1"]().regions(deformation(3, -0.5)) > 0


def test_summary_counts_all_ranks():
    mesh = unit_mesh(2)
    material = MATERIALS["C2"]()
    # Inverted only left of x = 0.5: u folds the left half over.
    space = _compat.vector_function_space(mesh, "Lagrange", 1)
    u = dolfinx.fem.Function(space)
    u.interpolate(lambda x: np.vstack([np.where(x[0] < 0.5, -2.0 * x[0], -1.0), 0.0 * x[1]]))
    diagnostics = cell_diagnostics(u, material)
    result = summary(diagnostics, COMM)

    assert result["cells"] == 32
    # F = diag(-1, 1) on the 16 cells left of x = 0.5, F = I right of it.
    assert result["inverted_cells"] == 16
    assert result["extended_cells"] == 16
    assert result["undefined_cells"] == 0
    assert result["min_J"] == pytest.approx(-1.0, abs=1e-12)
    assert result["min_singular_value"] == pytest.approx(-1.0, abs=1e-12)
    json.dumps(result)  # plain numbers, ready for the log


def test_summary_names_missing_keys():
    with pytest.raises(KeyError, match="region"):
        summary({"min_J": np.ones(2), "inverted": np.zeros(2)}, COMM)


# --------------------------------------------------------------------------------------------
# ResultWriter
# --------------------------------------------------------------------------------------------
def owned_midpoints(mesh):
    """x coordinate of the midpoint of every owned cell, in local cell order."""
    d = mesh.topology.dim
    num_owned = mesh.topology.index_map(d).size_local
    vertices = _compat.scalar_function_space(mesh, "Lagrange", 1)
    coordinates = vertices.tabulate_dof_coordinates()
    return coordinates[_compat.cell_dofs(vertices)[:num_owned]].mean(axis=1)[:, 0]


def test_writer_round_trip(directory):
    mesh = unit_mesh(2)
    A = deformation(2, 0.8)
    material = MATERIALS["C2"]()
    path = directory / "series.xdmf"
    times = [0.0, 0.5, 1.0]
    with ResultWriter(path, mesh) as writer:
        for step, t in enumerate(times):
            u = affine_displacement(mesh, A, degree=2, scale=t)
            diagnostics = cell_diagnostics(u, material)
            diagnostics["midpoint_x"] = owned_midpoints(mesh)
            record = {"newton_iterations": np.int64(step + 2), "wall_time": 0.1 * step}
            record.update(summary(diagnostics, COMM))
            writer.write(t, u, diagnostics, record=record)
        assert writer.steps_written == 3
    COMM.barrier()
    if COMM.rank != 0:
        return

    points, cells, steps = read_series(path)
    assert points.shape == (25, 2)  # XY geometry of a 2D mesh
    assert sum(len(block.data) for block in cells) == 32
    assert [t for t, _, _ in steps] == times
    for t, point_data, cell_data in steps:
        assert set(point_data) == {DISPLACEMENT_NAME}
        assert set(cell_data) == {
            "min_J",
            "inverted",
            "energy_density",
            "min_singular_value",
            "region",
            "midpoint_x",
        }
        displacement = point_data[DISPLACEMENT_NAME]
        expected = t * points[:, :2] @ (A - np.eye(2)).T
        np.testing.assert_allclose(displacement[:, :2], expected, atol=1e-12)
        np.testing.assert_array_equal(displacement[:, 2], 0.0)

        # The cell data lines up with the topology read back.
        midpoints = np.concatenate([points[block.data].mean(axis=1)[:, 0] for block in cells])
        midpoint_x = np.concatenate(cell_data["midpoint_x"]).ravel()
        np.testing.assert_allclose(midpoint_x, midpoints, atol=1e-12)
        min_J = np.concatenate(cell_data["min_J"]).ravel()
        np.testing.assert_allclose(min_J, np.linalg.det(np.eye(2) + t * (A - np.eye(2))))

    lines = path.with_suffix(".jsonl").read_text().splitlines()
    assert len(lines) == 3
    for step, (line, t) in enumerate(zip(lines, times)):
        entry = json.loads(line)
        assert entry["step"] == step
        assert entry["time"] == t
        assert entry["newton_iterations"] == step + 2
        assert entry["wall_time"] == pytest.approx(0.1 * step)
        assert entry["cells"] == 32
        assert entry["inverted_cells"] == 0


def test_readable_after_failure(directory):
    mesh = unit_mesh(2)
    A = deformation(2, -0.5)
    path = directory / "crashed.xdmf"
    log_path = directory / "logs" / "crashed_steps.jsonl"
    with pytest.raises(RuntimeError, match="simulated"):
        with ResultWriter(path, mesh, log_path=log_path) as writer:
            for t in (1.0, 2.0):
                u = affine_displacement(mesh, A, scale=t)
                writer.write(t, u, cell_diagnostics(u, MATERIALS["C1"]()), record={"t2": t * t})
            raise RuntimeError("simulated solver failure")
    COMM.barrier()
    if COMM.rank != 0:
        return

    points, _, steps = read_series(path)
    assert [t for t, _, _ in steps] == [1.0, 2.0]
    assert set(steps[0][2]) >= {"min_J", "region"}
    for t, point_data, _ in steps:
        expected = t * points[:, :2] @ (A - np.eye(2)).T
        np.testing.assert_allclose(point_data[DISPLACEMENT_NAME][:, :2], expected, atol=1e-12)
    entries = [json.loads(line) for line in log_path.read_text().splitlines()]
    assert [entry["t2"] for entry in entries] == [1.0, 4.0]


def test_readable_while_open(directory):
    """Each step is on disk and unlocked as soon as write returns (e.g. for ParaView)."""
    mesh = unit_mesh(2)
    path = directory / "live.xdmf"
    with ResultWriter(path, mesh) as writer:
        u = affine_displacement(mesh, deformation(2, 0.8))
        writer.write(0.0, u)
        COMM.barrier()
        if COMM.rank == 0:
            _, _, steps = read_series(path)
            assert len(steps) == 1
            assert set(steps[0][1]) == {DISPLACEMENT_NAME}
        COMM.barrier()
        writer.write(1.0, u)
        COMM.barrier()
        if COMM.rank == 0:
            assert len(read_series(path)[2]) == 2
        COMM.barrier()


def test_wrong_length_diagnostic_names_key(directory):
    mesh = unit_mesh(2)
    u = affine_displacement(mesh, deformation(2, 0.8))
    num_owned = mesh.topology.index_map(2).size_local
    with ResultWriter(directory / "bad.xdmf", mesh) as writer:
        with pytest.raises(ValueError, match="'too_long'"):
            writer.write(0.0, u, {"good": np.zeros(num_owned), "too_long": np.zeros(num_owned + 1)})
        # Only rank 0 wrong: every rank raises, none is left waiting in a collective write.
        lengths = num_owned + 1 if COMM.rank == 0 else num_owned
        with pytest.raises(ValueError, match="'only_rank_0'"):
            writer.write(0.0, u, {"only_rank_0": np.zeros(lengths)})
        with pytest.raises(ValueError, match="'two_d'"):
            writer.write(0.0, u, {"two_d": np.zeros((num_owned, 1))})
        # A failed call writes nothing, and the writer goes on.
        assert writer.steps_written == 0
        writer.write(0.0, u, {"good": np.zeros(num_owned)})
        assert writer.steps_written == 1


def test_bad_arguments(directory):
    mesh = unit_mesh(2)
    u = affine_displacement(mesh, deformation(2, 0.8))
    num_owned = mesh.topology.index_map(2).size_local
    with pytest.raises(ValueError, match=".xdmf"):
        ResultWriter(directory / "series.h5", mesh)
    with ResultWriter(directory / "arguments.xdmf", mesh) as writer:
        with pytest.raises(ValueError, match="reserved"):
            writer.write(0.0, u, {DISPLACEMENT_NAME: np.zeros(num_owned)})
        with pytest.raises(ValueError, match="diagnostic name"):
            writer.write(0.0, u, {"a/b": np.zeros(num_owned)})
        with pytest.raises(ValueError, match="reserved"):
            writer.write(0.0, u, record={"time": 3.0})
        with pytest.raises(ValueError, match="not JSON"):
            writer.write(0.0, u, record={"solver": object()})
        writer.write(1.0, u)
        with pytest.raises(ValueError, match="greater than the previous time"):
            writer.write(1.0, u)
    with pytest.raises(RuntimeError, match="closed"):
        writer.write(2.0, u)


def test_non_finite_record_values_are_null(directory):
    mesh = unit_mesh(2)
    path = directory / "nonfinite.xdmf"
    with ResultWriter(path, mesh) as writer:
        writer.write(0.0, affine_displacement(mesh, deformation(2, 0.8)), record={"e": np.inf})
    COMM.barrier()
    if COMM.rank == 0:
        assert json.loads(path.with_suffix(".jsonl").read_text()) == {
            "step": 0,
            "time": 0.0,
            "e": None,
        }
