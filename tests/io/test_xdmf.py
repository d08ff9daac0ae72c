"""The XDMF/JSONL result writer, on real DOLFINx meshes.

Runs serially and under mpirun: files are read back on rank 0 only, after a barrier, and the
checks compare values through the coordinates rather than through any node or cell order.
"""

import hashlib
import json
import xml.etree.ElementTree as ElementTree

import numpy as np
import pytest
from dolfinx_helpers import (
    COMM,
    MATERIALS,
    affine_displacement,
    deformation,
    read_series,
    unit_mesh,
)

from dolfinx_invertible import _compat
from dolfinx_invertible.fem.diagnostics import cell_diagnostics, summary
from dolfinx_invertible.io import xdmf as xdmf_module
from dolfinx_invertible.io.xdmf import DISPLACEMENT_NAME, ResultWriter

pytestmark = pytest.mark.mpi


# --------------------------------------------------------------------------------------------
# ResultWriter
# --------------------------------------------------------------------------------------------
def owned_midpoints(mesh):
    """x coordinate of the midpoint of every owned cell, in local cell order."""
    d = mesh.topology.dim
    num_owned = mesh.topology.index_map(d).size_local
    vertices = _compat.scalar_function_space(mesh, 1, "Lagrange")
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


def fingerprint(path):
    """(mtime, size, hash) of a file: changes whenever the file is written to."""
    stat = path.stat()
    return stat.st_mtime_ns, stat.st_size, hashlib.sha256(path.read_bytes()).hexdigest()


def fingerprints(directory):
    return {path: fingerprint(path) for path in directory.rglob("*") if path.is_file()}


def write_steps(writer, mesh, A, times):
    for t in times:
        writer.write(
            t, affine_displacement(mesh, A, scale=t), {"midpoint_x": owned_midpoints(mesh)}
        )


def test_each_step_has_its_own_hdf5_file(directory):
    import h5py

    mesh = unit_mesh(2)
    A = deformation(2, 0.8)
    path = directory / "steps.xdmf"
    times = [0.0, 0.5, 1.0]
    with ResultWriter(path, mesh) as writer:
        mesh_file = fingerprint(path.with_suffix(".h5")) if COMM.rank == 0 else None
        write_steps(writer, mesh, A, times)
    COMM.barrier()
    if COMM.rank != 0:
        return

    # The mesh file is written once, when the writer starts, and holds no step.
    assert fingerprint(path.with_suffix(".h5")) == mesh_file
    with h5py.File(path.with_suffix(".h5"), "r") as mesh_data:
        assert set(mesh_data) == {"Mesh"}
    folder = directory / "steps.steps"
    names = [f"{step:06d}.h5" for step in range(len(times))]
    assert sorted(file.name for file in folder.iterdir()) == names  # no working files left
    series = ElementTree.parse(path).getroot().findall("Domain/Grid[@Name='time_series']/Grid")
    assert len(series) == len(times)
    for name, grid in zip(names, series):
        with h5py.File(folder / name, "r") as step_data:
            assert set(step_data) == {"Function"}
            assert set(step_data["Function"]) == {DISPLACEMENT_NAME, "midpoint_x"}
            for field in step_data["Function"].values():
                assert len(field) == 1  # this step's time only
        references = {item.text.split(":")[0] for item in grid.iter("DataItem")}
        assert references == {f"steps.steps/{name}"}

    points, _, steps = read_series(path)
    assert [t for t, _, _ in steps] == times
    for t, point_data, _ in steps:
        expected = t * points[:, :2] @ (A - np.eye(2)).T
        np.testing.assert_allclose(point_data[DISPLACEMENT_NAME][:, :2], expected, atol=1e-12)


def test_a_step_cut_off_before_its_merge_leaves_the_earlier_steps_readable(directory, monkeypatch):
    """A run killed while HDF5 writes or closes a step: only that step's data is damaged."""
    mesh = unit_mesh(2)
    A = deformation(2, 0.8)
    path = directory / "cut.xdmf"
    writer = ResultWriter(path, mesh)
    write_steps(writer, mesh, A, [1.0, 2.0])
    COMM.barrier()
    before = fingerprints(directory) if COMM.rank == 0 else None

    # Rank 0 fails to put the new series in place: the step's data is written, not referenced.
    def killed(path, text):
        raise RuntimeError("killed")

    monkeypatch.setattr(xdmf_module, "_replace_atomically", killed)
    with pytest.raises(RuntimeError, match="killed"):
        write_steps(writer, mesh, A, [3.0])
    COMM.barrier()
    if COMM.rank == 0:
        # Damage every HDF5 file the cut-off step wrote to, as a kill while closing can.
        written = [
            file
            for file, state in fingerprints(directory).items()
            if file.suffix == ".h5" and before.get(file) != state
        ]
        assert written
        for file in written:
            size = file.stat().st_size
            with open(file, "r+b") as damaged:
                damaged.truncate(size // 2)
        points, _, steps = read_series(path)
        assert [t for t, _, _ in steps] == [1.0, 2.0]
        for t, point_data, _ in steps:
            expected = t * points[:, :2] @ (A - np.eye(2)).T
            np.testing.assert_allclose(point_data[DISPLACEMENT_NAME][:, :2], expected, atol=1e-12)
    COMM.barrier()

    writer.close()
    COMM.barrier()
    if COMM.rank == 0:
        # The files of the step that was never merged are not left looking like part of the run.
        assert sorted(file.name for file in (directory / "cut.steps").iterdir()) == [
            "000000.h5",
            "000001.h5",
        ]


def test_a_new_run_removes_the_steps_of_the_previous_one(directory):
    mesh = unit_mesh(2)
    A = deformation(2, 0.8)
    path = directory / "again.xdmf"
    with ResultWriter(path, mesh) as writer:
        write_steps(writer, mesh, A, [0.0, 1.0, 2.0])
    with ResultWriter(path, mesh) as writer:
        COMM.barrier()
        if COMM.rank == 0:
            assert not (directory / "again.steps").exists()
        COMM.barrier()
        write_steps(writer, mesh, A, [5.0])
    COMM.barrier()
    if COMM.rank == 0:
        assert [file.name for file in (directory / "again.steps").iterdir()] == ["000000.h5"]
        assert [t for t, _, _ in read_series(path)[2]] == [5.0]


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
