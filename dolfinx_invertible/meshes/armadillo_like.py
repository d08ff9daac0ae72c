"""An armadillo-like solid for the scatter scene: a body with limbs, a tail, ears and a hole.

Not a scan: a gmsh (OpenCASCADE) construction of simple shapes fused together, with thin parts
(ears, tail), a through hole in the torso and a few thousand tetrahedra at the default
resolution. Its bounding box is about ``size`` long.
"""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.meshes.cache import cached_mesh
from dolfinx_invertible.meshes.gmsh_model import meshed_tetrahedra

__all__ = ["generate", "mesh"]


def generate(resolution: int, size: float) -> tuple[np.ndarray, np.ndarray]:
    """Build the solid with gmsh; return (points, tetrahedra)."""
    import gmsh

    # gmsh keeps global state: initialise and finalise around one construction.
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("armadillo_like")
        occ = gmsh.model.occ
        torso = occ.addSphere(0.0, 0.0, 0.0, 0.25)
        occ.dilate([(3, torso)], 0.0, 0.0, 0.0, 1.5, 1.0, 0.8)
        head = occ.addSphere(0.42, 0.0, 0.1, 0.12)
        parts = [(3, head)]
        for x in (-0.2, 0.2):
            for y in (-0.15, 0.15):
                parts.append((3, occ.addCylinder(x, y, -0.05, 0.0, 0.0, -0.3, 0.05)))
        parts.append((3, occ.addCylinder(-0.35, 0.0, 0.0, -0.3, 0.0, 0.1, 0.035)))  # tail
        for y in (-0.06, 0.06):  # ears: thin, but never thinner than a few cells
            parts.append((3, occ.addCone(0.45, y, 0.18, 0.0, 0.0, 0.1, 0.035, 0.02)))
        body, _ = occ.fuse([(3, torso)], parts)
        hole = occ.addCylinder(0.0, -0.4, 0.0, 0.0, 0.8, 0.0, 0.07)
        occ.cut(body, [(3, hole)])
        occ.synchronize()
        box = gmsh.model.getBoundingBox(-1, -1)
        extent = max(box[3] - box[0], box[4] - box[1], box[5] - box[2])
        length = extent / (6.0 * resolution)
        gmsh.option.setNumber("Mesh.CharacteristicLengthMin", 0.7 * length)
        gmsh.option.setNumber("Mesh.CharacteristicLengthMax", length)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.option.setNumber("Mesh.Optimize", 1)
        gmsh.model.mesh.generate(3)
        points, cells = meshed_tetrahedra()
        return (points - np.array(box[:3])) * (size / extent), cells
    finally:
        gmsh.finalize()


def mesh(comm, *, resolution: int = 4, size: float = 1.0):
    """Return the armadillo-like mesh (generated on first use, then read from the cache)."""
    key = f"armadillo_like-r{resolution}-s{size:g}"
    return cached_mesh(comm, key, lambda: generate(resolution, size))
