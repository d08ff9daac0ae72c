"""A chain of linked rings: the bodies of the links scene.

``count`` tori (centre-line radius ``major``, tube radius ``minor``) hang one below the other,
turned a quarter turn each about the vertical, each passing through the hole of the next with a
clearance ``clearance`` between the tubes: disjoint bodies, linked. Meshed by gmsh
(OpenCASCADE) with about ``resolution`` cells across the tube's radius, on rank 0, once, into
the mesh cache (:func:`~dolfinx_invertible.meshes.cache.cached_mesh`).
"""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.meshes.cache import cached_mesh
from dolfinx_invertible.meshes.gmsh_model import meshed_tetrahedra

__all__ = ["generate", "mesh", "ring_pitch"]


def ring_pitch(major: float, minor: float, clearance: float) -> float:
    """Vertical distance between the centres of two linked rings, (2R − 2r − clearance).

    The lower ring's top then lies ``clearance`` above the upper ring's bottom, tube surface to
    tube surface, where the two cross.
    """
    pitch = 2.0 * major - 2.0 * minor - clearance
    # The upper ring's tube must pass through the lower ring's hole: |pitch − R| + r < R − r.
    if not (clearance > 0.0 and abs(pitch - major) + minor < major - minor):
        raise ValueError(
            f"rings of radii {major:g} and {minor:g} with a clearance of {clearance:g} cannot be "
            "linked: the tube must be thinner than a quarter of the ring"
        )
    return pitch


def generate(
    count: int, major: float, minor: float, clearance: float, resolution: int
) -> tuple[np.ndarray, np.ndarray]:
    """Build the chain with gmsh; return (points, tetrahedra). Ring 0 is centred at the origin."""
    import gmsh

    pitch = ring_pitch(major, minor, clearance)
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("rings")
        occ = gmsh.model.occ
        for index in range(count):
            # OpenCASCADE's torus lies in the xy plane: stand it up, a quarter turn per ring.
            ring = occ.addTorus(0.0, 0.0, 0.0, major, minor)
            occ.rotate([(3, ring)], 0, 0, 0, 1, 0, 0, np.pi / 2)
            occ.rotate([(3, ring)], 0, 0, 0, 0, 0, 1, (index % 2) * np.pi / 2)
            occ.translate([(3, ring)], 0.0, 0.0, -index * pitch)
        occ.synchronize()
        length = minor / resolution
        gmsh.option.setNumber("Mesh.CharacteristicLengthMin", 0.7 * length)
        gmsh.option.setNumber("Mesh.CharacteristicLengthMax", length)
        gmsh.option.setNumber("Mesh.Optimize", 1)
        gmsh.model.mesh.generate(3)
        return meshed_tetrahedra()
    finally:
        gmsh.finalize()


def mesh(comm, *, count: int, major: float, minor: float, clearance: float, resolution: int):
    """Return the chain's mesh (generated on first use, then read from the cache)."""
    key = f"rings-n{count}-R{major:g}-r{minor:g}-c{clearance:g}-res{resolution}"
    return cached_mesh(comm, key, lambda: generate(count, major, minor, clearance, resolution))
