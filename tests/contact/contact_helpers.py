"""Obstacles shared by the contact tests: every shape, static and moving, in 2D and 3D."""

import numpy as np

from dolfinx_invertible.contact import Cone, Cylinder, HalfSpace, RigidMotion, Sphere


def motion(dimension):
    """A motion with translation and rotation, both nonlinear in time."""
    if dimension == 2:
        return RigidMotion(
            2,
            translation=lambda t: (0.3 * t, -0.2 * t * t),
            angle=lambda t: 0.9 * t,
            pivot=(0.1, -0.2),
        )
    return RigidMotion(
        3,
        translation=lambda t: (0.1 * t, -0.2 * t, 0.3 * t * t),
        angle=lambda t: 0.7 * t + 0.2 * t * t,
        axis=(1.0, 2.0, -0.5),
        pivot=(0.2, 0.1, -0.3),
    )


def shapes(dimension, moving=None):
    """(name, obstacle) for every shape; cylinders and cones are their 2D strips and wedges."""
    motion_ = motion(dimension) if moving else None
    if dimension == 2:
        return [
            ("half-space", HalfSpace((0.3, 1.0), -0.2, motion=motion_)),
            ("ball", Sphere((0.1, 0.2), 0.7, motion=motion_)),
            ("bowl", Sphere((0.1, 0.2), 1.1, inside=True, motion=motion_)),
            ("strip", Cylinder((0.0, 0.1), (1.0, 0.4), 0.5, motion=motion_)),
            ("channel", Cylinder((0.0, 0.1), (1.0, 0.4), 0.9, inside=True, motion=motion_)),
            ("wedge", Cone((0.0, 0.0), (1.0, 0.2), 0.9, -0.25, motion=motion_)),
        ]
    return [
        ("half-space", HalfSpace((0.3, -0.4, 1.0), -0.2, motion=motion_)),
        ("ball", Sphere((0.1, 0.2, -0.1), 0.7, motion=motion_)),
        ("bowl", Sphere((0.1, 0.2, -0.1), 1.1, inside=True, motion=motion_)),
        ("roller", Cylinder((0.0, 0.1, 0.0), (1.0, 0.4, -0.3), 0.5, motion=motion_)),
        ("tube", Cylinder((0.0, 0.1, 0.0), (1.0, 0.4, -0.3), 0.9, inside=True, motion=motion_)),
        ("cone", Cone((0.0, 0.0, 0.1), (0.2, -0.3, 1.0), 0.9, -0.25, motion=motion_)),
    ]


def random_points(dimension, count, seed=0, scale=1.3):
    return np.random.default_rng(seed).uniform(-scale, scale, (count, dimension))
