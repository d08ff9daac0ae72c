"""A user's mesh file: read, checked, scaled and placed; a scene runs on it; bad files refused.

The meshes are made here (gmsh, meshio, DOLFINx's XDMF writer), so each check knows its answer
from the construction: the ball's volume, where a bad cell was put, how many pieces there are.
"""

from __future__ import annotations

import json
import subprocess
import sys

from mpi4py import MPI

import meshio
import numpy as np
import pytest

from dolfinx_invertible.meshes import MeshFileError, read_mesh
from dolfinx_invertible.meshes.files import check_cells, read_cells
from dolfinx_invertible.scenes import SCENES, Parameters, get_scene, run_scene

#: Two tetrahedra sharing the face (0, 1, 2), their apexes on opposite sides of it.
TWO_TETRAHEDRA = (
    np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.3, 0.3, -1.0]], dtype=float),
    np.array([[0, 1, 2, 3], [0, 1, 2, 4]]),
)


def ball_msh(path, *, radius=0.4, mesh_size=0.2, centre=(0.0, 0.0, 0.0), second=None):
    """Write a ball (and a second, separate one at ``second``) meshed by gmsh to ``path``."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("ball")
        volumes = [gmsh.model.occ.addSphere(*centre, radius)]
        if second is not None:
            volumes.append(gmsh.model.occ.addSphere(*second, radius))
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, volumes, 1)
        gmsh.option.setNumber("Mesh.MeshSizeMax", mesh_size)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


def _write(path, points, cells):
    meshio.write(path, meshio.Mesh(points, cells), file_format="gmsh22", binary=False)
    return path


def _total_volume(mesh) -> float:
    import dolfinx
    import ufl

    one = dolfinx.fem.Constant(mesh, 1.0)
    local = dolfinx.fem.assemble_scalar(dolfinx.fem.form(one * ufl.dx(domain=mesh)))
    return mesh.comm.allreduce(local, op=MPI.SUM)


def test_a_gmsh_ball_is_fitted_into_a_box_where_the_anchor_says(tmp_path):
    path = ball_msh(tmp_path / "ball.msh", centre=(3.0, -1.0, 2.0))
    _, cells = read_cells(path)
    box = ([0.0, 0.0, 0.0], [2.0, 5.0, 3.0])
    corner = read_mesh(MPI.COMM_SELF, path, box=box, anchor=(-1, -1, -1))
    centred = read_mesh(MPI.COMM_SELF, path, box=box)
    high = read_mesh(MPI.COMM_SELF, path, box=box, anchor=(1, 1, 0))
    assert corner.topology.index_map(3).size_global == len(cells)
    x = corner.geometry.x
    # The x room (2) binds: a meshed ball is about as wide in every direction.
    assert np.allclose(x.min(axis=0), 0.0) and np.isclose(np.ptp(x[:, 0]), 2.0)
    assert np.allclose(np.ptp(x, axis=0), 2.0, rtol=0.05)
    y = centred.geometry.x
    assert np.allclose(0.5 * (y.min(axis=0) + y.max(axis=0)), [1.0, 2.5, 1.5])
    z = high.geometry.x
    assert np.allclose(z.max(axis=0)[:2], [2.0, 5.0])
    assert np.isclose(0.5 * (z[:, 2].min() + z[:, 2].max()), 1.5)
    # A ball of radius 0.4 scaled to diameter 2 is a polyhedron inside the unit ball.
    assert 0.9 * 4.0 / 3.0 * np.pi < _total_volume(corner) < 4.0 / 3.0 * np.pi


def test_an_xdmf_mesh_reads_as_dolfinx_wrote_it(tmp_path):
    import dolfinx
    import dolfinx.io

    box = dolfinx.mesh.create_box(MPI.COMM_SELF, [[1.0, 2.0, 3.0], [2.0, 4.0, 3.5]], [2, 3, 1])
    path = tmp_path / "box.xdmf"
    with dolfinx.io.XDMFFile(MPI.COMM_SELF, str(path), "w") as file:
        file.write_mesh(box)
    kept = read_mesh(MPI.COMM_SELF, path)
    assert kept.topology.index_map(3).size_global == box.topology.index_map(3).size_global
    assert np.isclose(_total_volume(kept), 1.0)
    assert np.allclose(kept.geometry.x.min(axis=0), [1.0, 2.0, 3.0])


def test_vertex_order_does_not_matter_but_overlap_does():
    points, cells = TWO_TETRAHEDRA
    check_cells("two", points, cells)
    check_cells("two", points, cells[:, [1, 0, 2, 3]])  # one cell listed the other way round
    folded = points.copy()
    folded[4, 2] = 0.5  # the second apex on the first one's side of the shared face
    with pytest.raises(MeshFileError, match=r"inverted cells: cell 0 .* overlaps its neighbour 1"):
        check_cells("two", folded, cells)


@pytest.mark.parametrize("case", ["missing", "garbage", "suffix", "surface", "triangles-2d",
                                  "mixed", "second-order", "zero-volume", "inverted",
                                  "non-manifold", "two-pieces"])  # fmt: skip
def test_a_bad_mesh_is_refused_naming_the_file_and_the_cell(tmp_path, case):
    points, cells = TWO_TETRAHEDRA
    path = tmp_path / f"{case}.msh"
    expected = {
        "missing": "no such file",
        "garbage": "cannot read the mesh",
        "suffix": "must end in .msh or .xdmf",
        "surface": "needs a 3D body of tetrahedra; the file holds",
        "triangles-2d": "needs a 3D body of tetrahedra; the file holds 2 triangle",
        "mixed": "mixed cell types tetra, hexahedron",
        "second-order": "cells are tetra10; the scene needs straight (first-order)",
        "zero-volume": "1 cell(s) of zero volume, the first cell 1 (centroid 0.3125, 0.3125, 0)",
        "inverted": "inverted cells: cell 0",
        "non-manifold": "a face shared by more than two cells",
        "two-pieces": "2 disconnected pieces where the scene needs one body",
    }[case]
    if case == "garbage":
        path.write_text("$MeshFormat\nthis is not a mesh\n")
    elif case == "suffix":
        path = tmp_path / "ball.stl"
        path.write_text("solid nothing\n")
    elif case == "surface":
        _write(path, points, [("triangle", np.array([[0, 1, 2], [0, 1, 3]]))])
    elif case == "triangles-2d":
        _write(path, points[:4] * [1, 1, 0], [("triangle", np.array([[0, 1, 2], [1, 3, 2]]))])
    elif case == "mixed":
        cube = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float) + 5
        hexahedron = np.array([[5, 6, 8, 7, 9, 10, 12, 11]])
        _write(path, np.vstack([points, cube]), [("tetra", cells), ("hexahedron", hexahedron)])
    elif case == "second-order":
        _write(path, np.vstack([points, np.zeros((6, 3))]), [("tetra10", np.arange(10)[None])])
    elif case == "zero-volume":
        flat = np.vstack([points, [[0.25, 0.25, 0.0]]])  # a vertex in the shared face's plane
        _write(path, flat, [("tetra", np.array([[0, 1, 2, 3], [0, 1, 2, 5]]))])
    elif case == "inverted":
        folded = points.copy()
        folded[4, 2] = 0.5
        _write(path, folded, [("tetra", cells)])
    elif case == "non-manifold":
        third = np.vstack([points, [[0.2, 0.2, 2.0]]])
        _write(path, third, [("tetra", np.vstack([cells, [[0, 1, 2, 5]]]))])
    elif case == "two-pieces":
        ball_msh(path, mesh_size=0.3, second=(2.0, 0.0, 0.0))
    with pytest.raises(MeshFileError, match=expected.replace("(", r"\(").replace(")", r"\)")) as e:
        read_mesh(MPI.COMM_SELF, path)
    assert str(path) in str(e.value)
    completed = subprocess.run(
        [sys.executable, "-m", "dolfinx_invertible", "run", "collapse", "--mesh", str(path),
         "--quiet", "--out", str(tmp_path / "run")],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert completed.returncode == 2, completed.stderr
    lines = completed.stderr.strip().splitlines()
    if case == "suffix":  # not a mesh file: the scene's --mesh names are offered instead
        expected = "--mesh must be cube or a .msh/.xdmf file"
    assert len(lines) == 1 and lines[0].startswith("error: ") and expected in lines[0], lines
    assert not (tmp_path / "run" / "summary.json").exists()


def test_a_scene_without_a_free_body_refuses_a_mesh_file(tmp_path):
    scene = get_scene("stretch-bar")
    parameters = Parameters(**{**scene.defaults, "mesh": str(tmp_path / "ball.msh")})
    with pytest.raises(ValueError, match="the stretch-bar scene does not take a mesh file"):
        run_scene(scene, parameters)
    with pytest.raises(ValueError, match="--mesh must be cube or armadillo-like or a .msh/.xdmf"):
        scene = get_scene("scatter")
        run_scene(scene, Parameters(**{**scene.defaults, "mesh": "sphere"}))


def test_the_bowl_refuses_a_body_that_does_not_fit(tmp_path):
    path = ball_msh(tmp_path / "ball.msh", mesh_size=0.3)
    scene = get_scene("bowl-drop")
    with pytest.raises(ValueError, match="does not fit into the bowl"):
        run_scene(scene, Parameters(**{**scene.defaults, "mesh": str(path), "size": 2.5}))


@pytest.mark.mpi
def test_collapse_recovers_on_a_gmsh_ball(directory):
    comm = MPI.COMM_WORLD
    path = directory / "ball.msh"
    if comm.rank == 0:
        ball_msh(path)
    comm.barrier()
    scene = get_scene("collapse")
    parameters = Parameters(**{**scene.defaults, "mesh": str(path)})
    summary = run_scene(scene, parameters, output=directory / "run")
    assert summary["ranks"] == comm.size and summary["parameters"]["mesh"] == str(path)
    assert summary["outcome"] == "recovered", summary
    assert summary["max_inverted"] > 0 or summary["min_J_reached"] < 1e-3  # it was collapsed
    _, cells = read_cells(path)
    assert summary["dofs"] == 3 * len(np.unique(cells))
    if comm.rank == 0:
        assert json.loads((directory / "run" / "summary.json").read_text())["outcome"] == (
            "recovered"
        )


def test_collapse_on_a_gmsh_ball_from_the_command_line(tmp_path):
    path = ball_msh(tmp_path / "ball.msh")
    completed = subprocess.run(
        [sys.executable, "-m", "dolfinx_invertible", "run", "collapse", "--mesh", str(path),
         "--quiet", "--out", str(tmp_path / "run")],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert completed.returncode == 0, completed.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["outcome"] == "recovered" and summary["parameters"]["mesh"] == str(path)


@pytest.mark.parametrize("name", [name for name in SCENES if get_scene(name).takes_mesh_file])
def test_every_scene_fits_a_file_body_into_the_box_of_its_own(tmp_path, name):
    path = ball_msh(tmp_path / "ball.msh", mesh_size=0.3, centre=(7.0, 0.0, -3.0))
    scene = get_scene(name)
    boxes = []
    for mesh in ("cube", str(path)):
        instance = scene(Parameters(**{**scene.defaults, "mesh": mesh}), MPI.COMM_SELF)
        x = instance.create_mesh().geometry.x
        boxes.append((x.min(axis=0), x.max(axis=0)))
    (own_low, own_high), (low, high) = boxes
    tolerance = 1e-12 * np.max(own_high - own_low)
    assert np.all(low >= own_low - tolerance) and np.all(high <= own_high + tolerance)
    # The ball fills the box in one direction, and touches or is centred on every pair of sides.
    assert np.any(np.isclose(high - low, own_high - own_low))
    for axis in range(3):
        gaps = (low[axis] - own_low[axis], own_high[axis] - high[axis])
        assert min(gaps) < tolerance or np.isclose(*gaps), (axis, gaps)
