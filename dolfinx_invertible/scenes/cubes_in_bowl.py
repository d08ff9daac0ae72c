"""Cubes in a bowl: soft cubes fall into a bowl and pile on each other (Fig. 13, "Yummy").

``count`` cubes of side ``size`` (default 8 of 0.2 m; ``--count 25`` for the paper's), each
turned a little about its own axes, start at rest in layers of 2 × 2 (3 × 3 from 9 cubes on)
around the centre of the bowl |x| ≤ 1 m, and fall under gravity (0, 0, −9.81) m/s². The bowl is
an analytic obstacle (:class:`~dolfinx_invertible.contact.Sphere`, our barrier and CCD); the
cubes meet each other through IPC Toolkit (:class:`~dolfinx_invertible.contact.BodyContactTerm`):
no two surfaces may pass through each other, and every stored step records ``min_distance``
and ``intersections`` (must stay 0).

Defaults, and why:

- ``resolution`` 2 (2³ × 6 tetrahedra a cube): enough for the cubes to squash as they land on
  each other, small enough for a run of a minute on two ranks;
- E = 5·10⁴ Pa, ν = 0.4, ρ = 1000 kg/m³: the gel of the bowl-drop scene;
- dt = 0.01 s, 1.2 s: the lowest layer lands at about 0.4 s, the upper ones on top of it;
- damping 0.01 of critical: the drag of the bowl-drop scene.
"""

from __future__ import annotations

import math

import numpy as np

from dolfinx_invertible.contact import Sphere
from dolfinx_invertible.meshes.blocks import cubes_mesh, rotation
from dolfinx_invertible.scenes.contact_scene import ContactScene

__all__ = ["CubesInBowl", "cube_layout"]

#: Radius of the bowl [m], centred at the origin.
BOWL_RADIUS = 1.0
#: Gravity [m/s²].
GRAVITY = (0.0, 0.0, -9.81)
#: Free space between neighbouring cubes at the start, relative to their side.
SPACING = 0.15
#: Each cube's turn about x, y and z [rad]: alternating signs, different for every cube.
TURN = (0.2, 0.15, 0.3)


def cube_layout(count: int, side: float) -> tuple[np.ndarray, list[np.ndarray]]:
    """Return the centres (count, 3) and rotations of the cubes at the start.

    Layers of k × k cubes (k = 2 up to 8 cubes, 3 above) from the bottom layer up, centred on
    the bowl's centre; the pitch is the largest extent of a turned cube plus
    :data:`SPACING` × side, so that no two cubes touch.

    Raises
    ------
    ValueError
        If the cubes do not fit inside the bowl.
    """
    per_side = 2 if count <= 8 else 3
    layers = math.ceil(count / per_side**2)
    rotations = []
    for index in range(count):
        signs = np.array([(-1.0) ** index, (-1.0) ** (index // 2), (-1.0) ** (index // 3)])
        rotations.append(rotation(signs * np.array(TURN)))
    corners = 0.5 * side * np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)])
    extent = max(np.abs(corners @ turn.T).max() for turn in rotations)
    pitch = 2.0 * extent + SPACING * side
    centres = []
    for index in range(count):
        layer, place = divmod(index, per_side**2)
        row, column = divmod(place, per_side)
        centres.append(
            [
                (column - 0.5 * (per_side - 1)) * pitch,
                (row - 0.5 * (per_side - 1)) * pitch,
                (layer - 0.5 * (layers - 1)) * pitch,
            ]
        )
    centres = np.array(centres)
    farthest = max(
        np.linalg.norm(centre + corners @ turn.T, axis=1).max()
        for centre, turn in zip(centres, rotations, strict=True)
    )
    if not farthest < BOWL_RADIUS:
        raise ValueError(
            f"--count {count} cubes of --size {side:g} do not fit into the bowl of radius "
            f"{BOWL_RADIUS:g} m (they reach {farthest:.3g} m from its centre): use fewer or "
            "smaller cubes"
        )
    return centres, rotations


class CubesInBowl(ContactScene):
    """Soft cubes fall into a bowl and pile on each other."""

    name = "cubes-in-bowl"
    description = "soft cubes fall into a bowl and pile up (contact between bodies, ipctk)"
    figure = "Fig. 13"
    defaults = {"E": 5.0e4, "nu": 0.4, "density": 1000.0, "dt": 0.01, "t_end": 1.2,
                "resolution": 2, "size": 0.2, "damping": 0.01, "count": 8}  # fmt: skip
    several_bodies = True

    def create_mesh(self):
        """Return the ``count`` turned cubes of side ``size``, ``resolution`` cells an edge."""
        side = self.parameters.size
        centres, rotations = cube_layout(self.parameters.count, side)
        return cubes_mesh(self.comm, centres, side, self.parameters.resolution, rotations)

    def obstacles(self):
        """Return the bowl: the inside of the sphere of radius 1 m about the origin."""
        return [Sphere((0.0, 0.0, 0.0), BOWL_RADIUS, inside=True)]

    def gravity(self):
        """Return (0, 0, −9.81) m/s²."""
        return GRAVITY
