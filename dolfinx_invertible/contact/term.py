"""The contact barrier as an energy term of a DOLFINx problem (the solvers' ``EnergyTerm``).

:class:`ContactTerm` adds Σᵢ wᵢ Σₒ b(dₒ(Xᵢ + uᵢ, t)) over the boundary vertices to the
potential, its gradient to the residual and its Hessian (exact or SPD-projected) to the
tangent. Each rank evaluates the boundary vertices whose displacement dofs it owns, so every
vertex is counted once and the result does not depend on the partition.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from mpi4py import MPI

import dolfinx.fem
import numpy as np
from petsc4py import PETSc

from dolfinx_invertible.constitutive.material import Material
from dolfinx_invertible.contact.barrier import (
    DEFAULT_DISTANCE_FRACTION,
    Barrier,
    barrier_distance,
    barrier_stiffness,
    youngs_modulus_for_stiffness,
)
from dolfinx_invertible.contact.boundary import BoundaryVertices
from dolfinx_invertible.contact.friction import DEFAULT_FRICTION_VELOCITY, ObstacleFriction
from dolfinx_invertible.contact.obstacle import Obstacle
from dolfinx_invertible.contact.obstacles import Obstacles
from dolfinx_invertible.contact.potential import BarrierPotential
from dolfinx_invertible.contact.step import CollisionFreeStep
from dolfinx_invertible.solvers.results import point_text
from dolfinx_invertible.solvers.terms import ProjectableHessian, StatefulTerm

__all__ = ["ContactTerm"]

# Projection passes of ContactTerm.separate over all obstacles; each pass is exact for a plane
# and converges quadratically on the curved shapes, so few are needed.
_SEPARATION_PASSES = 8


class ContactTerm(StatefulTerm, ProjectableHessian):
    """Frictionless contact of a body with rigid (possibly moving) obstacles, as a barrier.

    Pass it to :class:`~dolfinx_invertible.HyperelasticProblem` (or
    :class:`~dolfinx_invertible.ImplicitDynamics`) as ``terms=[term]`` together with
    ``step_limits=[term.step_limit()]``, the continuous collision detection that keeps every
    Newton iterate outside the obstacles, and, where the obstacles move or rub, with
    ``boundary_update=term.start_step`` (a scene run does this itself: it is a
    :class:`~dolfinx_invertible.solvers.terms.StatefulTerm`). Its step log and summary figures:
    ``min_gap`` (the smallest gap of any boundary vertex, the summary's over the stored steps),
    ``penetrations`` (boundary vertices on or inside an obstacle, summed over the stored steps:
    0 in a correct run), ``contact_vertices`` (within d̂ of an obstacle; the summary's
    ``max_contact_vertices`` is the most at one step), and the summary's ``barrier_distance``
    and ``barrier_stiffness`` (d̂, κ).

    Parameters
    ----------
    u
        The displacement (vector Lagrange P1 or P2; on P2 the barrier acts on the vertex dofs).
    obstacles
        An :class:`~dolfinx_invertible.contact.obstacle.Obstacle`, several, or a
        :class:`~dolfinx_invertible.contact.obstacles.Obstacles`.
    material
        The body's :class:`~dolfinx_invertible.Material`: its Young's modulus sets κ. Not
        needed if ``youngs_modulus`` or ``stiffness`` is given.
    youngs_modulus
        E for the stiffness rule, instead of the material's.
    distance
        d̂; default ``distance_fraction`` × the boundary vertex spacing h.
    distance_fraction
        d̂ / h when ``distance`` is not given.
    stiffness
        κ; default E / ((5 + 2 ln 2) h)
        (:func:`~dolfinx_invertible.contact.barrier.barrier_stiffness`).
    time
        The time at which the obstacles are evaluated until :meth:`set_time` changes it.
    friction
        Coulomb's coefficient μ against the obstacles (0: frictionless), lagged per time step
        (:class:`~dolfinx_invertible.contact.friction.ObstacleFriction`).
    friction_velocity
        ε_v [m/s]: slower sliding sticks (elastically).
    project_hessian
        ``None`` (default): the barrier's exact Hessian where the problem assembles its exact
        tangent (Newton's local phase; against a convex obstacle the barrier is concave along
        the surface), each vertex block's SPD projection elsewhere
        (:class:`~dolfinx_invertible.solvers.terms.ProjectableHessian`); ``True``: always the
        projection; ``False``: always the exact Hessian.

    Attributes
    ----------
    boundary
        The :class:`~dolfinx_invertible.contact.boundary.BoundaryVertices` this rank evaluates.
    obstacles, barrier, potential
        The :class:`~dolfinx_invertible.contact.obstacles.Obstacles`, the
        :class:`~dolfinx_invertible.contact.barrier.Barrier` (d̂, κ) and the
        :class:`~dolfinx_invertible.contact.potential.BarrierPotential`.
    time
        The current time of the obstacles.
    """

    def __init__(
        self,
        u: dolfinx.fem.Function,
        obstacles: Obstacle | Sequence[Obstacle] | Obstacles,
        material: Material | None = None,
        *,
        youngs_modulus: float | None = None,
        distance: float | None = None,
        distance_fraction: float = DEFAULT_DISTANCE_FRACTION,
        stiffness: float | None = None,
        time: float = 0.0,
        friction: float = 0.0,
        friction_velocity: float = DEFAULT_FRICTION_VELOCITY,
        project_hessian: bool | None = None,
    ) -> None:
        self._choose_projection(project_hessian)
        self.u = u
        self.obstacles = Obstacles(obstacles)
        self.boundary = BoundaryVertices(u.function_space)
        if self.obstacles.dimension != self.boundary.dimension:
            raise ValueError(
                f"the obstacles are {self.obstacles.dimension}D but the mesh is "
                f"{self.boundary.dimension}D"
            )
        spacing = self.boundary.spacing
        if distance is None:
            distance = barrier_distance(spacing, distance_fraction)
        if stiffness is None:
            stiffness = barrier_stiffness(
                youngs_modulus_for_stiffness(material, youngs_modulus), spacing
            )
        self.barrier = Barrier(distance, stiffness)
        self.potential = BarrierPotential(self.obstacles, self.barrier)
        self.comm = u.function_space.mesh.comm
        self.friction = ObstacleFriction(friction, friction_velocity) if friction > 0.0 else None
        self.time = float(time)
        self.set_time(time)
        self.min_gap = math.inf
        self.penetration_count = 0
        self.max_contact_vertices = 0

    # -- state --------------------------------------------------------------------------------
    def set_time(self, t: float) -> None:
        """Evaluate the obstacles at time ``t`` from now on (call before each step).

        With friction, the current state is the start of a step from the previous time to
        ``t``: its normal forces, tangent planes and the obstacles' motion over the step are
        lagged here.
        """
        t = float(t)
        if not math.isfinite(t):
            raise ValueError(f"time must be finite, got {t!r}")
        if self.friction is not None:
            self.friction.lag(
                self.positions(), self.boundary.weights, self.obstacles, self.barrier, self.time, t
            )
        self.time = t

    def start_step(self, t: float) -> None:
        """Move the obstacles to ``t`` (:meth:`set_time`), then the swept vertices out of them.

        The :class:`~dolfinx_invertible.solvers.terms.StatefulTerm` hook: ``u`` holds the
        attempt's initial guess, which :meth:`separate` may adjust.
        """
        self.set_time(t)
        self.separate()

    def step_quantities(self) -> dict[str, float | int]:
        """Return ``min_gap``, ``penetrations`` and ``contact_vertices`` now (collective)."""
        figures = {
            "min_gap": self.minimum_gap(),
            "penetrations": self.penetrations(),
            "contact_vertices": self.active_vertices(),
        }
        self.min_gap = min(self.min_gap, figures["min_gap"])
        self.penetration_count += figures["penetrations"]
        self.max_contact_vertices = max(self.max_contact_vertices, figures["contact_vertices"])
        return figures

    def summary_quantities(self) -> dict[str, float | int]:
        """Return the figures over the stored steps, and d̂ and κ."""
        return {
            "min_gap": self.min_gap,
            "penetrations": self.penetration_count,
            "barrier_distance": self.barrier.distance,
            "barrier_stiffness": self.barrier.stiffness,
            "max_contact_vertices": self.max_contact_vertices,
        }

    def checkpoint_state(self) -> dict[str, float | int | None]:
        """Return the figures accumulated over the stored steps."""
        return {
            "min_gap": None if math.isinf(self.min_gap) else self.min_gap,
            "penetrations": self.penetration_count,
            "max_contact_vertices": self.max_contact_vertices,
        }

    def restore(self, state: dict[str, float | int | None]) -> None:
        """Continue the figures from :meth:`checkpoint_state`."""
        self.min_gap = math.inf if state["min_gap"] is None else float(state["min_gap"])
        self.penetration_count = int(state["penetrations"])
        self.max_contact_vertices = int(state["max_contact_vertices"])

    def describe_state(self) -> str:
        """Say how many boundary vertices the barrier holds and which is closest (collective).

        For a failed solve's message: the vertices within d̂, the smallest gap, the obstacle
        (numbered from 0 in the order given) and where the vertex is.
        """
        gaps = self.gaps()
        candidate = (math.inf, -1, ())
        if gaps.size:
            obstacle, vertex = np.unravel_index(int(np.argmin(gaps)), gaps.shape)
            candidate = (
                float(gaps[obstacle, vertex]),
                int(obstacle),
                tuple(self.positions()[vertex]),
            )
        gap, obstacle, where = min(self.comm.allgather(candidate), key=lambda item: item[0])
        text = (
            f"obstacle contact: {self.active_vertices()} boundary vertices within "
            f"d̂ = {self.barrier.distance:.3g} of an obstacle"
        )
        if obstacle >= 0:
            name = type(self.obstacles[obstacle]).__name__
            text += (
                f"; the smallest gap {gap:.3g}, to obstacle {obstacle} ({name}), at "
                f"{point_text(where)}"
            )
        return text

    def positions(self) -> np.ndarray:
        """Return the current positions X + u of this rank's boundary vertices, (n, d)."""
        return self.boundary.positions(self.u.x.array)

    def gaps(self) -> np.ndarray:
        """Gaps of this rank's boundary vertices to every obstacle, (obstacles, n)."""
        return self.obstacles.gaps(self.positions(), self.time)

    def minimum_gap(self) -> float:
        """Smallest gap of any boundary vertex to any obstacle, over all ranks."""
        gaps = self.gaps()
        local = float(np.min(gaps)) if gaps.size else math.inf
        return self.comm.allreduce(local, op=MPI.MIN)

    def penetrations(self) -> int:
        """Boundary vertices on or inside an obstacle (some gap ≤ 0), over all ranks."""
        gaps = self.gaps()
        local = int(np.count_nonzero(~np.all(gaps > 0.0, axis=0))) if gaps.size else 0
        return self.comm.allreduce(local, op=MPI.SUM)

    def active_vertices(self) -> int:
        """Boundary vertices within d̂ of some obstacle (the barrier acts), over all ranks."""
        gaps = self.gaps()
        local = int(np.count_nonzero(np.any(gaps < self.barrier.distance, axis=0)))
        return self.comm.allreduce(local, op=MPI.SUM)

    def contact_force(self, obstacle: int | None = None) -> np.ndarray:
        """Total force the obstacles (or obstacle number ``obstacle``) exert on the body.

        −Σᵢ ∂E/∂xᵢ over all boundary vertices and ranks, a vector of d entries.
        """
        acting = self.obstacles if obstacle is None else Obstacles(self.obstacles[obstacle])
        potential = BarrierPotential(acting, self.barrier)
        gradient = potential.gradient(self.positions(), self.boundary.weights, self.time)
        return -self.comm.allreduce(np.sum(gradient, axis=0), op=MPI.SUM)

    def separate(self, gap: float | None = None) -> int:
        """Move the boundary vertices that are on or inside an obstacle out to ``gap``.

        An obstacle that moved between two steps may have swept over boundary vertices of the
        previous state, the initial guess of the next solve, where the barrier is undefined.
        This moves each such vertex along the gap's gradient (a few projection passes over the
        obstacles) until its gaps are at least ``gap`` (default d̂/2), changing ``u`` only
        there; the solve then starts from a feasible state and relaxes the distorted
        elements around it. Call it after :meth:`set_time` and before the solve (in
        ``boundary_update`` of :class:`~dolfinx_invertible.ImplicitDynamics`, in the load
        update of a load-stepping loop).

        Returns
        -------
        int
            Vertices moved, over all ranks.
        """
        target = 0.5 * self.barrier.distance if gap is None else float(gap)
        if not (math.isfinite(target) and target > 0.0):
            raise ValueError(f"gap must be a finite number > 0, got {gap!r}")
        positions = self.positions()
        infeasible = np.flatnonzero(
            ~np.all(self.obstacles.gaps(positions, self.time) > 0.0, axis=0)
        )
        if len(infeasible):
            points = positions[infeasible]
            for _ in range(_SEPARATION_PASSES):
                for obstacle in self.obstacles:
                    gaps, gradients, _ = obstacle.gap_derivatives(points, self.time)
                    short = gaps < target
                    length2 = np.einsum("ij,ij->i", gradients, gradients)
                    short &= length2 > 0.0
                    shift = (target - gaps[short]) / length2[short]
                    points[short] += shift[:, None] * gradients[short]
                if np.all(self.obstacles.gaps(points, self.time) >= 0.5 * target):
                    break
            dofs = self.boundary.dofs[infeasible]
            self.u.x.array[dofs] = points - self.boundary.reference[infeasible]
        moved = self.comm.allreduce(len(infeasible), op=MPI.SUM)
        if moved:
            self.u.x.scatter_forward()
        return moved

    def step_limit(self, fraction: float = 0.9) -> CollisionFreeStep:
        """Return the collision-free step cap of this term (a ``StepLimit``).

        See :class:`~dolfinx_invertible.contact.step.CollisionFreeStep`.
        """
        return CollisionFreeStep(self, fraction=fraction)

    # -- EnergyTerm ---------------------------------------------------------------------------
    def energy(self) -> float:
        """Return this rank's share of the barrier energy at the current ``u`` (+∞: penetrated).

        With friction, the step's friction potential is included.
        """
        positions = self.positions()
        value = self.potential.energy(positions, self.boundary.weights, self.time)
        if self.friction is not None:
            value += self.friction.energy(positions)
        return value

    def add_residual(self, residual: np.ndarray) -> None:
        """Add the barrier's gradient into the local residual array (owned dofs only).

        NaN goes into the dofs of a vertex on or inside an obstacle, which makes the solve fail
        (and a step controller cut the step) instead of continuing from an infeasible state.
        """
        positions = self.positions()
        gradient = self.potential.gradient(positions, self.boundary.weights, self.time)
        if self.friction is not None:
            gradient += self.friction.gradient(positions)
        residual[self.boundary.dofs] += gradient

    def add_tangent(self, matrix: PETSc.Mat, constrained: np.ndarray) -> None:
        """Add the barrier Hessian (a d × d block per active vertex), projected or exact.

        :attr:`projected` says which. With friction, its (positive semidefinite) Hessian too.
        """
        positions = self.positions()
        points, blocks = self.potential.hessians(
            positions, self.boundary.weights, self.time, project=self.projected
        )
        if self.friction is not None:
            sliding, sliding_blocks = self.friction.hessians(positions)
            points = np.concatenate([points, sliding])
            blocks = np.concatenate([blocks, sliding_blocks])
        if len(points) == 0:
            return
        rows = self.boundary.dofs[points].astype(PETSc.IntType)
        if len(constrained):
            # PETSc skips negative indices: the Dirichlet rows and columns stay untouched.
            rows[np.isin(rows, constrained)] = -1
        d = rows.shape[1]
        matrix.setValuesLocalRCV(
            rows, rows, blocks.reshape(len(points), d * d), addv=PETSc.InsertMode.ADD_VALUES
        )

    def __repr__(self) -> str:
        return (
            f"ContactTerm(obstacles={self.obstacles!r}, barrier={self.barrier!r}, "
            f"time={self.time!r})"
        )
