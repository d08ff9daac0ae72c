"""ParaView reads a ResultWriter series as written, and renders it.

A small series on a unit cube with deformations whose J is known in every cell (the identity,
an affine map, and two folds that mirror a slab of cells) is written with ResultWriter and
opened with ParaView's own XDMF3 reader in pvbatch. The expected values come from the
deformations (numpy on the grid's nodes), and the cell ranges also from the arrays handed to
the writer. ParaView reads these files in single precision (the XDMF data items carry no
Precision, whose default is 4 bytes), hence the float32 tolerances.

Serial only: ParaView runs as a separate process of its own, so MPI adds nothing here. The
tests fail, and do not skip, without ParaView: ``make test`` installs it.
"""

import shutil
import struct

from mpi4py import MPI

import dolfinx.mesh
import numpy as np
import pytest
from dolfinx_helpers import MATERIALS, affine_displacement, deformation

from dolfinx_invertible import _compat
from dolfinx_invertible.fem.diagnostics import DIAGNOSTIC_NAMES, cell_diagnostics
from dolfinx_invertible.io import paraview
from dolfinx_invertible.io.xdmf import DISPLACEMENT_NAME, ResultWriter

CELLS = (4, 2, 2)  # cells per edge: vertex planes at x = 0.25, 0.5, 0.75
NUM_POINTS = 5 * 3 * 3
NUM_CELLS = 6 * 4 * 2 * 2
AFFINE = deformation(3, 0.6)
# (time, kind, parameters); a fold x0 -> c - s (x0 - c) for x0 > c has J = -s right of the plane
# x0 = c and J = 1 left of it, exactly, since c is a vertex plane of the mesh.
STEPS = [
    (0.0, "identity", None),
    (0.5, "affine", None),
    (1.0, "fold", (0.5, 1.0)),
    (1.5, "fold", (0.75, 0.5)),
]
RELATIVE_FLOAT32 = 1e-6


def deformation_map(kind, parameters, x):
    """phi(x) for points x of shape (3, n)."""
    if kind == "identity":
        return x.copy()
    if kind == "affine":
        return AFFINE @ x
    centre, scale = parameters
    phi = x.copy()
    phi[0] = np.where(x[0] > centre, centre - scale * (x[0] - centre), x[0])
    return phi


def expected_cell_values(kind, parameters, midpoints_x):
    """(J, smallest signed singular value) of every cell, from its midpoint's x."""
    if kind == "identity":
        return np.ones_like(midpoints_x), np.ones_like(midpoints_x)
    if kind == "affine":
        J = np.linalg.det(AFFINE)
        return np.full_like(midpoints_x, J), np.full_like(midpoints_x, np.linalg.svd(AFFINE)[1][-1])
    centre, scale = parameters
    folded = midpoints_x > centre
    # F = diag(-s, 1, 1) in the folded cells: signed singular values (-s, 1, 1).
    return np.where(folded, -scale, 1.0), np.where(folded, -min(scale, 1.0), 1.0)


def grid_nodes():
    axes = [np.linspace(0.0, 1.0, n + 1) for n in CELLS]
    return np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")])


@pytest.fixture(scope="module")
def pvbatch():
    try:
        found = paraview.find_pvbatch()
    except paraview.ParaViewNotFoundError as error:
        pytest.fail(str(error))  # it says that `make test` installs ParaView
    if shutil.which("Xvfb") is None:
        pytest.fail("Xvfb is missing, needed to render: `make test` installs it (package xvfb).")
    return found


@pytest.fixture(scope="module")
def series(tmp_path_factory):
    """Path of the series and the diagnostics written at each step."""
    comm = MPI.COMM_SELF
    mesh = dolfinx.mesh.create_unit_cube(comm, *CELLS)
    material = MATERIALS["C2"]()
    path = tmp_path_factory.mktemp("paraview") / "fold.xdmf"
    written = []
    with ResultWriter(path, mesh) as writer:
        for t, kind, parameters in STEPS:
            if kind == "affine":
                # P2: the writer interpolates it to the vertices.
                u = affine_displacement(mesh, AFFINE, degree=2)
            else:
                u = dolfinx.fem.Function(_compat.vector_function_space(mesh, 1))
                u.interpolate(lambda x, k=kind, p=parameters: deformation_map(k, p, x) - x)
            diagnostics = cell_diagnostics(u, material)
            writer.write(t, u, diagnostics)
            written.append({name: values.copy() for name, values in diagnostics.items()})
    return path, written, mesh


@pytest.fixture(scope="module")
def inspected(pvbatch, series):
    return paraview.inspect_xdmf(series[0])


def assert_range(actual, expected):
    np.testing.assert_allclose(actual, expected, rtol=RELATIVE_FLOAT32, atol=RELATIVE_FLOAT32)


def test_reader_sees_the_series(inspected, series):
    path = series[0]
    assert inspected["path"] == str(path.resolve())
    assert inspected["reader"] == "Xdmf3ReaderS"
    assert inspected["paraview_version"].startswith("5.")
    assert inspected["times"] == [t for t, _, _ in STEPS]
    assert inspected["point_arrays"] == [DISPLACEMENT_NAME]
    assert inspected["cell_arrays"] == sorted(DIAGNOSTIC_NAMES)
    assert inspected["number_of_points"] == NUM_POINTS
    assert inspected["number_of_cells"] == NUM_CELLS
    assert len(inspected["steps"]) == len(STEPS)
    for step, (t, _, _) in zip(inspected["steps"], STEPS):
        assert step["time"] == t
        assert step["number_of_points"] == NUM_POINTS
        assert step["number_of_cells"] == NUM_CELLS
        assert step["cell_types"] == ["vtkTetra"]
        # The undeformed mesh: the reader does not move the points by the displacement.
        assert_range(step["bounds"], [0.0, 1.0] * 3)
        assert set(step["point_data"]) == {DISPLACEMENT_NAME}
        assert set(step["cell_data"]) == set(DIAGNOSTIC_NAMES)


def test_displacement_ranges(inspected):
    x = grid_nodes()
    for step, (_, kind, parameters) in zip(inspected["steps"], STEPS):
        summary = step["point_data"][DISPLACEMENT_NAME]
        u = deformation_map(kind, parameters, x) - x
        assert summary["components"] == 3
        assert summary["data_type"] in ("float", "double")
        assert_range(summary["component_ranges"], [[c.min(), c.max()] for c in u])
        magnitude = np.linalg.norm(u, axis=0)
        assert_range(summary["range"], [magnitude.min(), magnitude.max()])


def test_cell_ranges_match_the_run(inspected, series):
    _, written, mesh = series
    vertices = _compat.scalar_function_space(mesh, 1, "Lagrange")
    coordinates = vertices.tabulate_dof_coordinates()
    midpoints_x = coordinates[_compat.cell_dofs(vertices)].mean(axis=1)[:, 0]
    expected_inverted = []
    for step, values, (_, kind, parameters) in zip(inspected["steps"], written, STEPS):
        # Against what the run wrote ...
        for name in DIAGNOSTIC_NAMES:
            summary = step["cell_data"][name]
            assert summary["components"] == 1
            assert_range(summary["range"], [values[name].min(), values[name].max()])
        # ... and against the deformation itself.
        J, smallest = expected_cell_values(kind, parameters, midpoints_x)
        assert_range(step["cell_data"]["min_J"]["range"], [J.min(), J.max()])
        assert_range(
            step["cell_data"]["min_singular_value"]["range"], [smallest.min(), smallest.max()]
        )
        inverted = J <= 0
        assert_range(step["cell_data"]["inverted"]["range"], [inverted.min(), inverted.max()])
        assert step["inverted_cells"] == np.count_nonzero(inverted)
        expected_inverted.append(int(np.count_nonzero(inverted)))
    # The folds invert the half and the quarter of the cube right of x = 0.5 and x = 0.75.
    assert expected_inverted == [0, 0, NUM_CELLS // 2, NUM_CELLS // 4]


def test_relative_file_name(pvbatch, series, monkeypatch):
    """A bare file name reaches ParaView as an absolute path (5.11 misplaces the .h5 else)."""
    path = series[0]
    monkeypatch.chdir(path.parent)
    info = paraview.inspect_xdmf(path.name)
    assert info["path"] == str(path.resolve())
    assert info["steps"][-1]["inverted_cells"] == NUM_CELLS // 4


def test_missing_paraview_says_how_to_install(series):
    with pytest.raises(paraview.ParaViewNotFoundError, match="make test"):
        paraview.inspect_xdmf(series[0], executable="no-such-pvbatch-here")
    with pytest.raises(FileNotFoundError):
        paraview.inspect_xdmf(series[0].with_name("missing.xdmf"))


def read_png(path):
    """(width, height) from the header and the pixels as an (height, width, channels) array."""
    import matplotlib.image

    header = path.read_bytes()[:24]
    assert header[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", header[16:24])
    return (width, height), matplotlib.image.imread(path)


def red_pixels(pixels):
    r, g, b = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    return int(np.count_nonzero((r > 0.3) & (r > 3 * g) & (r > 3 * b)))


def test_render_picture(pvbatch, series, tmp_path):
    path = series[0]
    size = (320, 240)
    worst = paraview.render(path, tmp_path / "worst.png", size=size)
    # The default time: the step with the most inverted cells.
    assert worst["time"] == 1.0
    assert worst["inverted_cells"] == NUM_CELLS // 2
    # Warped: the fold at x = 0.5 with s = 1 maps the cube onto its left half.
    assert_range(worst["bounds"], [0.0, 0.5, 0.0, 1.0, 0.0, 1.0])
    header_size, pixels = read_png(tmp_path / "worst.png")
    assert header_size == size
    assert pixels.shape[:2] == (size[1], size[0])
    colours = np.unique(pixels.reshape(-1, pixels.shape[2]), axis=0)
    assert len(colours) > 10
    assert red_pixels(pixels) > 100

    rest = paraview.render(path, tmp_path / "rest.png", time=0.0, size=size)
    assert rest["time"] == 0.0
    assert rest["inverted_cells"] == 0
    _, pixels = read_png(tmp_path / "rest.png")
    assert red_pixels(pixels) == 0
    assert len(np.unique(pixels.reshape(-1, pixels.shape[2]), axis=0)) > 10


def test_render_rejects_bad_input(pvbatch, series, tmp_path):
    path = series[0]
    with pytest.raises(ValueError, match="outside the time steps"):
        paraview.render(path, tmp_path / "late.png", time=5.0)
    with pytest.raises(ValueError, match="size"):
        paraview.render(path, tmp_path / "tiny.png", size=(4, 4))
    with pytest.raises(ValueError, match="time must be"):
        paraview.render(path, tmp_path / "word.png", time="worst")


def test_render_runs_names_pictures_by_directory(pvbatch, series, tmp_path):
    path = series[0]
    results = paraview.render_runs([path.parent], tmp_path, time="last", size=(64, 48))
    assert [result["png"] for result in results] == [str(tmp_path / path.parent.name / "fold.png")]
    assert results[0]["time"] == STEPS[-1][0]
    assert read_png(tmp_path / path.parent.name / "fold.png")[0] == (64, 48)
