"""Ball hit: a fast rigid ball strikes a body resting on the ground and squashes it (Fig. 9).

A cube of side L (``--size``, default 0.5 m) rests on the ground z = 0 (a half-space) under
gravity. A rigid ball of radius L/2 comes straight down onto the middle of its top at
:data:`BALL_SPEED`, on a prescribed path through where the body is: its lowest point goes down
to :data:`LOWEST` × L above the ground and it then flies back up at the same speed. The body
under the ball is squashed to a fifth of its height in a few milliseconds and spreads over the
frictionless ground; the ball sweeps over several boundary vertices per step, which the contact
term moves back out onto the ball's surface before each solve, and cells under the ball invert.
After the ball has left, the body springs back and the inverted cells recover.

Defaults, and why:

- ``resolution`` 6 (6³ × 6 tetrahedra): cells small against the ball, so that the squashed
  region has several layers, yet a run of well under a minute;
- E = 10⁵ Pa, ν = 0.45, ρ = 1000 kg/m³: a rubbery solid whose wave speed √(E/ρ) = 10 m/s equals
  the ball's speed, so that the hit is faster than the body can get out of the way;
- dt = 2 ms: the ball moves 2 cm a step, under a third of a cell; 0.2 s: the hit (0.09 s) and
  the recovery after it (the body jumps off the ground as it springs back);
- damping 0.1 of critical (mass-proportional, 13/s): the body's ringing after the hit dies
  down within the run.
"""

from __future__ import annotations

import dolfinx

from dolfinx_invertible.contact import HalfSpace, RigidMotion, Sphere
from dolfinx_invertible.scenes.contact_scene import ContactScene

__all__ = ["BallHit"]

#: Speed of the ball on its way down and back up [m/s].
BALL_SPEED = 10.0
#: Radius of the ball over the body's size.
BALL_RADIUS = 0.5
#: Height of the ball's lowest point above the ground at the bottom of its path, over the size.
LOWEST = 0.2
#: Height of the ball's lowest point above the body's top at t = 0, over the size.
START = 0.1
#: Gravity [m/s²].
GRAVITY = (0.0, 0.0, -9.81)


class BallHit(ContactScene):
    """A cube on the ground squashed by a fast rigid ball coming down on it and leaving again."""

    name = "ball-hit"
    description = "a rigid ball strikes a body on the ground at 10 m/s and squashes it (contact)"
    figure = "Fig. 9"
    defaults = {"E": 1.0e5, "nu": 0.45, "density": 1000.0, "dt": 0.002, "t_end": 0.2,
                "resolution": 6, "size": 0.5, "damping": 0.1}  # fmt: skip
    takes_mesh_file = True

    def __init__(self, parameters, comm):
        super().__init__(parameters, comm)
        #: The most cells inverted at one step until the ball is back at its starting height.
        self.inverted_during_hit = 0

    def create_mesh(self):
        """Return the cube [−L/2, L/2]² × [lift, lift + L] just above the ground.

        The lift, a tenth of a cell, is about the barrier distance: the body starts touching
        the ground's barrier and settles within a few steps. A body from ``--mesh PATH`` is
        fitted into the same box, standing on its bottom.
        """
        size, n = self.parameters.size, self.parameters.resolution
        half, lift = 0.5 * size, 0.1 * size / n
        box = ([-half, -half, lift], [half, half, lift + size])
        if self.mesh_file is not None:
            return self.read_mesh_file(box, anchor=(0, 0, -1))
        return dolfinx.mesh.create_box(self.comm, list(box), [n, n, n])

    def ball_height(self, t: float) -> float:
        """Return the height of the ball's lowest point at time t: down, then back up."""
        size = self.parameters.size
        lowest, start = LOWEST * size, (1.0 + START) * size
        return lowest + abs(start - lowest - BALL_SPEED * t)

    def hit_time(self) -> float:
        """Return the time at which the ball is lowest (it is back up at twice that)."""
        return (1.0 + START - LOWEST) * self.parameters.size / BALL_SPEED

    def obstacles(self):
        """Return the ground z = 0 and the ball on its path above the body's centre."""
        size = self.parameters.size
        radius = BALL_RADIUS * size
        start = self.ball_height(0.0)
        motion = RigidMotion(3, translation=lambda t: (0.0, 0.0, self.ball_height(t) - start))
        ball = Sphere((0.0, 0.0, start + radius), radius, motion=motion)
        return [HalfSpace((0.0, 0.0, 1.0), 0.0), ball]

    def gravity(self):
        """Return (0, 0, −9.81) m/s²."""
        return GRAVITY

    def record(self, run) -> None:
        """Also follow the most inverted cells until the ball is back at its starting height."""
        super().record(run)
        inverted = run.diagnostics.get("inverted_cells", 0)
        if run.time <= 2.0 * self.hit_time():
            self.inverted_during_hit = max(self.inverted_during_hit, inverted)

    def checkpoint_state(self):
        """Add the most inverted cells during the hit so far."""
        return {**super().checkpoint_state(), "inverted_during_hit": self.inverted_during_hit}

    def restore(self, state) -> None:
        """Continue from :meth:`checkpoint_state`."""
        super().restore(state)
        self.inverted_during_hit = int(state["inverted_during_hit"])

    def quantities(self, run):
        """Add the time the ball is lowest, the time it is back up, and the inverted cells then."""
        return {
            **super().quantities(run),
            "hit_time": self.hit_time(),
            "ball_leaves": 2.0 * self.hit_time(),
            "max_inverted_during_hit": self.inverted_during_hit,
        }
