"""Write meshes/armadillo_like.msh: the scatter scene's armadillo-like solid at its defaults.

    python meshes/generate.py                 # from the repository root; needs gmsh

The points and tetrahedra come from the package's own generator
(``dolfinx_invertible.meshes.armadillo_like.generate``) at the scatter scene's default
``resolution`` and ``size``: the mesh ``run scatter --mesh armadillo-like`` reads from its cache.
gmsh writes them as MSH 4.1 (ASCII), the tetrahedra in physical volume 1 ("body").
"""

import argparse
from pathlib import Path

import gmsh
import numpy as np

from dolfinx_invertible.meshes import armadillo_like
from dolfinx_invertible.scenes.parameters import Parameters
from dolfinx_invertible.scenes.scatter import Scatter

#: gmsh's element type of the 4-node tetrahedron.
TETRAHEDRON = 4


def write_msh(path: Path, points: np.ndarray, tetrahedra: np.ndarray) -> None:
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(path.stem)
        volume = gmsh.model.addDiscreteEntity(3)
        tags = np.arange(1, len(points) + 1)
        gmsh.model.mesh.addNodes(3, volume, tags, points.ravel())
        gmsh.model.mesh.addElementsByType(volume, TETRAHEDRON, [], (tetrahedra + 1).ravel())
        gmsh.model.addPhysicalGroup(3, [volume], 1)
        gmsh.model.setPhysicalName(3, 1, "body")
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def main() -> None:
    defaults = Parameters(**Scatter.defaults)
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=int, default=defaults.resolution)
    parser.add_argument("--size", type=float, default=defaults.size)
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "armadillo_like.msh")
    arguments = parser.parse_args()
    points, tetrahedra = armadillo_like.generate(arguments.resolution, arguments.size)
    write_msh(arguments.out, points, tetrahedra)
    print(
        f"{arguments.out}: {len(points)} points, {len(tetrahedra)} tetrahedra, "
        f"{arguments.out.stat().st_size} bytes"
    )


if __name__ == "__main__":
    main()
