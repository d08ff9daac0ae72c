"""Contact between the surfaces of the bodies of one mesh, self-contact included, on IPC Toolkit.

:class:`BodyContactTerm` is an energy term of a DOLFINx problem (the solvers' ``EnergyTerm``):
the IPC barrier potential of every pair of non-adjacent surface primitives (vertex–triangle and
edge–edge in 3D, vertex–edge in 2D) closer than d̂, its gradient in the residual and its
Hessian, exact or SPD-projected, in the tangent. :class:`SurfaceCollisionFreeStep` is its step
cap (a ``StepLimit``): continuous collision detection along the Newton direction, so that no
iterate of the line search lets two surfaces pass through each other.

What comes from IPC Toolkit (``ipctk``): the collision mesh, the broad phase (hash grid), the
collision set and its barrier potential with gradient and projected Hessian (area-weighted),
the narrow-phase CCD (additive), the minimum distance and the edge–triangle
intersection predicate. What is ours: the surface gathered over
the MPI ranks (:class:`~dolfinx_invertible.contact.surface.GatheredSurface`), the choice of d̂
and κ from the mesh and the material, the assembly into the PETSc system, and the checks.

Every rank computes the same potential on the same gathered surface and adds the rows of the
surface vertices it owns, so serial and parallel runs agree to round-off.
"""

from __future__ import annotations

import math

from mpi4py import MPI

import dolfinx.fem
import ipctk
import numpy as np
import scipy.sparse
from petsc4py import PETSc

from dolfinx_invertible.constitutive.material import Material
from dolfinx_invertible.constitutive.validation import check_open_unit_interval
from dolfinx_invertible.contact.barrier import (
    DEFAULT_DISTANCE_FRACTION,
    barrier_distance,
    youngs_modulus_for_stiffness,
)
from dolfinx_invertible.contact.friction import DEFAULT_FRICTION_VELOCITY
from dolfinx_invertible.contact.surface import GatheredSurface
from dolfinx_invertible.solvers.results import point_text
from dolfinx_invertible.solvers.terms import ProjectableHessian, StatefulTerm

__all__ = ["BodyContactTerm", "SurfaceCollisionFreeStep", "SurfaceIntersectionError"]

# One thread per MPI rank, as for BLAS (the Makefile's OMP_NUM_THREADS=1): the ranks already
# fill the cores, and ipctk's threaded reductions would sum in a varying order, so that the same
# state could give energies that differ in the last bits from one evaluation to the next.
ipctk.set_num_threads(1)


#: IPC's bound of the adaptive κ: 100 times the initial stiffness.
ADAPTIVE_STIFFNESS_RANGE = 100.0
#: The adaptive κ doubles while the smallest distance keeps falling below this share of d̂.
ADAPTIVE_DISTANCE_FRACTION = 0.05


class SurfaceIntersectionError(ValueError):
    """The surfaces of the bodies intersect (or touch) where they may not, e.g. at t = 0."""


def separation_curvature(distance: float, spacing: float, dimension: int) -> float:
    """Curvature, per unit area (length in 2D), of IPC Toolkit's potential with κ = 1.

    Measured, not derived: two parallel flat patches triangulated at the surface vertex
    spacing h (20 cells a side) at a gap of d̂/2 are moved apart uniformly; the second
    derivative of ipctk's area-weighted potential with respect to the gap, divided by one
    patch's area, is returned. The rule for κ then needs no knowledge of how ipctk weighs and
    squares its distances, and sees the same ratio d̂/h as the mesh.
    """
    cells = 20
    side = cells * spacing
    gap = 0.5 * distance
    if dimension == 2:
        line = np.linspace(0.0, side, cells + 1)
        bottom = np.column_stack([line, np.zeros_like(line)])
        top = np.column_stack([line, np.full_like(line, gap)])
        segments = np.column_stack([np.arange(cells), np.arange(1, cells + 1)])
        vertices = np.vstack([bottom, top])
        edges = np.vstack([segments, segments + len(line)]).astype(np.int32)
        faces = np.zeros((0, 3), dtype=np.int32)
        area = side
    else:
        grid = np.linspace(0.0, side, cells + 1)
        xs, ys = np.meshgrid(grid, grid, indexing="ij")
        flat = np.column_stack([xs.ravel(), ys.ravel()])
        count = len(flat)
        corner = (np.arange(cells)[:, None] * (cells + 1) + np.arange(cells)[None, :]).ravel()
        triangles = np.vstack(
            [
                np.column_stack([corner, corner + cells + 1, corner + cells + 2]),
                np.column_stack([corner, corner + cells + 2, corner + 1]),
            ]
        )
        vertices = np.vstack(
            [np.column_stack([flat, np.zeros(count)]), np.column_stack([flat, np.full(count, gap)])]
        )
        faces = np.vstack([triangles, triangles[:, ::-1] + count]).astype(np.int32)
        edges = ipctk.edges(np.asfortranarray(faces)).astype(np.int32)
        area = side * side
    mesh = ipctk.CollisionMesh(
        np.asfortranarray(vertices), np.asfortranarray(edges), np.asfortranarray(faces)
    )
    collisions = _collision_set()
    collisions.build(mesh, np.asfortranarray(vertices), distance)
    potential = ipctk.BarrierPotential(distance, 1.0)
    hessian = potential.hessian(collisions, mesh, np.asfortranarray(vertices))
    motion = np.zeros_like(vertices)
    motion[len(vertices) // 2 :, dimension - 1] = 1.0
    flat_motion = motion.ravel()
    return float(flat_motion @ (hessian @ flat_motion)) / area


def _collision_set() -> ipctk.NormalCollisions:
    collisions = ipctk.NormalCollisions()
    # Area weighting makes the potential converge under refinement. ipctk's "improved max
    # approximator" is left off: in ipctk 1.6.1 its collision set, and the energy with it (by
    # 1e-4 of itself), depends on the order of the surface vertices (GatheredSurface's, by
    # position, the same on any number of ranks, but an arbitrary one), and in the piles it
    # cost failed attempts where they are coarse (docs/contact.md); the plain IPC set does not.
    collisions.use_area_weighting = True
    collisions.collision_set_type = ipctk.NormalCollisions.CollisionSetType.IPC
    return collisions


class BodyContactTerm(StatefulTerm, ProjectableHessian):
    """Frictionless contact between (and within) the bodies of one mesh, by IPC Toolkit.

    Pass it to :class:`~dolfinx_invertible.HyperelasticProblem` (or
    :class:`~dolfinx_invertible.ImplicitDynamics`) as ``terms=[term]`` together with
    ``step_limits=[term.step_limit()]`` and, in time stepping, ``boundary_update=
    term.start_step``. Call :meth:`check_intersection_free` before the first solve: the
    barrier cannot start from surfaces that cross. A scene run does all of this itself (it is a
    :class:`~dolfinx_invertible.solvers.terms.StatefulTerm`) and logs, at every stored step,
    ``min_distance`` (the smallest distance between surface primitives; the summary's is the
    smallest over the steps), ``intersections`` (crossing surface facet pairs; the summary
    sums them: 0 in a correct run) and ``body_barrier_stiffness`` (κ as adapted so far).

    Parameters
    ----------
    u
        The displacement (vector Lagrange P1 or P2 on a simplex mesh; on P2 the surface is
        made of the vertex dofs).
    material
        The body's :class:`~dolfinx_invertible.Material`: its Young's modulus sets κ. Not
        needed if ``youngs_modulus`` or ``stiffness`` is given.
    youngs_modulus
        E for the stiffness rule, instead of the material's.
    distance
        d̂; default ``distance_fraction`` × the surface vertex spacing h of the bodies as they
        start (X + u when the term is made): a body that starts compressed, as the collapse
        does, gets a d̂ to match, instead of one that spans its whole compressed surface.
    distance_fraction
        d̂ / h when ``distance`` is not given.
    stiffness
        κ; default such that the barrier's stiffness per unit area at a gap of d̂/2 is E / d̂,
        that of a layer of the material as thick as the barrier's range: pressed, the barrier
        zone gives way no more than the material beside it. Ten times softer (E / h at
        d̂ = h/10), a landing pressed the gaps to 10⁻³ d̂, deep into the barrier's logarithm,
        and Newton needed a third more iterations (docs/contact.md, "A barrier as stiff as
        the material").
    project_hessian
        ``None`` (default): the exact Hessian where the problem assembles its exact tangent
        (Newton's local phase), its SPD projection (ipctk's, per collision) elsewhere
        (:class:`~dolfinx_invertible.solvers.terms.ProjectableHessian`); ``True``: always the
        projection; ``False``: always the exact Hessian.
    friction
        Coulomb's coefficient μ between the surfaces (0: frictionless): ipctk's lagged friction
        (``TangentialCollisions``, ``FrictionPotential``), its normal forces, tangent bases and
        the slip's origin fixed at each :meth:`set_time`.
    friction_velocity
        ε_v [m/s]: slower sliding sticks (elastically).
    adaptive_stiffness
        IPC's adaptive κ (ipctk's ``update_barrier_stiffness``), once per time step in
        :meth:`set_time`: while the smallest distance keeps falling below
        ``adaptive_fraction`` × d̂, κ doubles, up to 100 times its initial value (IPC's bound).
    adaptive_fraction
        The share of d̂ below which κ adapts. IPC's threshold, 10⁻⁹ of the bounding-box
        diagonal, is 10⁻⁶ d̂ at IPC's d̂ and was never reached in our scenes, while the
        Newton steps of a landing were already capped short by the CCD at gaps of 1 % of d̂
        (docs/contact.md, "Where the pile's landing goes").

    Attributes
    ----------
    surface
        The :class:`~dolfinx_invertible.contact.surface.GatheredSurface`.
    collision_mesh
        The ``ipctk.CollisionMesh`` of the surface.
    spacing
        h: the surface vertex spacing as the bodies start.
    distance, stiffness
        d̂ and κ (κ as adapted so far).
    max_stiffness
        The bound of the adaptive κ.
    adaptive_fraction
        The share of d̂ below which κ adapts.
    """

    def __init__(
        self,
        u: dolfinx.fem.Function,
        material: Material | None = None,
        *,
        youngs_modulus: float | None = None,
        distance: float | None = None,
        distance_fraction: float = DEFAULT_DISTANCE_FRACTION,
        stiffness: float | None = None,
        project_hessian: bool | None = None,
        friction: float = 0.0,
        friction_velocity: float = DEFAULT_FRICTION_VELOCITY,
        adaptive_stiffness: bool = True,
        adaptive_fraction: float = ADAPTIVE_DISTANCE_FRACTION,
    ) -> None:
        self.u = u
        if not (math.isfinite(friction) and friction >= 0.0):
            raise ValueError(f"friction must be a number >= 0, got {friction!r}")
        if not (math.isfinite(friction_velocity) and friction_velocity > 0.0):
            raise ValueError(f"friction_velocity must be > 0, got {friction_velocity!r}")
        self.friction = float(friction)
        self.friction_velocity = float(friction_velocity)
        self.time = 0.0
        self._tangential: ipctk.TangentialCollisions | None = None
        self._friction_potential: ipctk.FrictionPotential | None = None
        self._slip_origin: np.ndarray | None = None
        self._choose_projection(project_hessian)
        self.surface = GatheredSurface(u.function_space)
        self.comm = self.surface.comm
        dimension = self.surface.dimension
        facets = np.asfortranarray(self.surface.facets.astype(np.int32))
        if dimension == 3:
            faces = facets
            edges = np.asfortranarray(ipctk.edges(faces).astype(np.int32))
        else:
            faces = np.zeros((0, 3), dtype=np.int32, order="F")
            edges = facets
        self.faces = np.ascontiguousarray(faces)
        self.edges = np.ascontiguousarray(edges)
        self.collision_mesh = ipctk.CollisionMesh(
            np.asfortranarray(self.surface.reference), edges, faces
        )
        self.spacing = spacing = self.surface.spacing_at(self.positions())
        self.distance = (
            barrier_distance(spacing, distance_fraction) if distance is None else float(distance)
        )
        if not (math.isfinite(self.distance) and self.distance > 0.0):
            raise ValueError(f"distance must be a finite number > 0, got {distance!r}")
        if stiffness is None:
            youngs_modulus = youngs_modulus_for_stiffness(material, youngs_modulus)
            stiffness = youngs_modulus / (
                self.distance * separation_curvature(self.distance, spacing, dimension)
            )
        self.stiffness = float(stiffness)
        if not (math.isfinite(self.stiffness) and self.stiffness > 0.0):
            raise ValueError(f"stiffness must be a finite number > 0, got {stiffness!r}")
        self.potential = ipctk.BarrierPotential(self.distance, self.stiffness)
        self.adaptive_stiffness = bool(adaptive_stiffness)
        self.adaptive_fraction = check_open_unit_interval("adaptive_fraction", adaptive_fraction)
        self.max_stiffness = ADAPTIVE_STIFFNESS_RANGE * self.stiffness
        reference = self.surface.reference
        self._diagonal = float(np.linalg.norm(reference.max(axis=0) - reference.min(axis=0)))
        self._last_minimum: float | None = None  # the smallest distance at the last step's start
        self._collisions = _collision_set()
        self._collisions_at: np.ndarray | None = None
        self._minimum_at: tuple[np.ndarray, float] | None = None
        #: The smallest distance and the crossing pairs summed over the stored steps.
        self.min_distance = math.inf
        self.intersection_count = 0
        self._global_dofs = self.surface.global_dofs().astype(PETSc.IntType)
        owned = self.surface.owned
        self._facets_of_edges: np.ndarray | None = None
        self._couplings: scipy.sparse.coo_matrix | None = None
        self._owned_rows = (owned[:, None] * dimension + np.arange(dimension)).ravel()

    # -- state --------------------------------------------------------------------------------
    def set_time(self, t: float) -> None:
        """Start a time step ending at ``t`` from the current state (collective).

        With ``adaptive_stiffness``, a step forward adapts κ to the smallest distance now and
        at the previous step's start. With friction, the step's friction is lagged here
        (ipctk's tangential collisions at the current positions, with the barrier's normal
        forces) and the slip is measured from the current positions.
        """
        t = float(t)
        if not math.isfinite(t):
            raise ValueError(f"time must be finite, got {t!r}")
        if self.adaptive_stiffness and t > self.time:
            self._adapt_stiffness(self.minimum_distance())
        if self.friction > 0.0:
            step = t - self.time
            self._tangential = None
            if step > 0.0:
                positions = self.positions()
                collisions = self._collisions_for(positions)
                tangential = ipctk.TangentialCollisions()
                tangential.build(
                    self.collision_mesh,
                    np.asfortranarray(positions),
                    collisions,
                    self.potential,
                    self.friction,
                )
                if len(tangential):
                    self._tangential = tangential
                    self._friction_potential = ipctk.FrictionPotential(
                        self.friction_velocity * step
                    )
                    self._slip_origin = positions
        self.time = t

    def _adapt_stiffness(self, minimum: float) -> None:
        # A retried step starts from the same state: its distance is not smaller, κ stays.
        # ipctk's distances are squared.
        if self._last_minimum is not None:
            stiffness = ipctk.update_barrier_stiffness(
                self._last_minimum**2,
                minimum**2,
                self.max_stiffness,
                self.stiffness,
                self._diagonal,
                dhat_epsilon_scale=self.adaptive_fraction * self.distance / self._diagonal,
            )
            if stiffness != self.stiffness:
                self.stiffness = float(stiffness)
                self.potential = ipctk.BarrierPotential(self.distance, self.stiffness)
        self._last_minimum = minimum

    def start_step(self, t: float) -> None:
        """Start the step ending at ``t``: :meth:`set_time` (the stateful term's hook)."""
        self.set_time(t)

    def check_start(self) -> None:
        """Refuse surfaces that cross or touch (:meth:`check_intersection_free`)."""
        self.check_intersection_free()

    def step_quantities(self) -> dict[str, float | int]:
        """Return ``min_distance``, ``intersections`` and κ of the current state (collective).

        κ as adapted so far is ``body_barrier_stiffness`` (``barrier_stiffness`` is the
        obstacles' in a scene that has both).
        """
        figures = {
            "min_distance": self.minimum_distance(),
            "intersections": self.intersections(),
            "body_barrier_stiffness": self.stiffness,
        }
        self.min_distance = min(self.min_distance, figures["min_distance"])
        self.intersection_count += figures["intersections"]
        return figures

    def summary_quantities(self) -> dict[str, float | int]:
        """Return the smallest distance over the stored steps, the crossings summed, the last κ."""
        return {
            "min_distance": self.min_distance,
            "intersections": self.intersection_count,
            "body_barrier_stiffness": self.stiffness,
        }

    def checkpoint_state(self) -> dict[str, float | None]:
        """Return what a restart needs besides the displacement: κ as adapted, its history."""
        return {
            "stiffness": self.stiffness,
            "last_minimum": self._last_minimum,
            "min_distance": None if math.isinf(self.min_distance) else self.min_distance,
            "intersections": self.intersection_count,
        }

    def restore(self, state: dict[str, float | None]) -> None:
        """Continue from :meth:`checkpoint_state`."""
        self.stiffness = float(state["stiffness"])
        self.potential = ipctk.BarrierPotential(self.distance, self.stiffness)
        last = state["last_minimum"]
        self._last_minimum = None if last is None else float(last)
        distance = state.get("min_distance")
        self.min_distance = math.inf if distance is None else float(distance)
        self.intersection_count = int(state.get("intersections", 0))

    def _slip(self, positions: np.ndarray) -> np.ndarray:
        return np.asfortranarray(positions - self._slip_origin)

    def positions(self) -> np.ndarray:
        """Return the current positions of all surface vertices (collective), (N, d)."""
        return self.surface.positions(self.u.x.array)

    def _collisions_for(self, positions: np.ndarray) -> ipctk.NormalCollisions:
        if self._collisions_at is None or not np.array_equal(self._collisions_at, positions):
            self._collisions.build(
                self.collision_mesh,
                np.asfortranarray(positions),
                self.distance,
                broad_phase=ipctk.HashGrid(),
            )
            self._collisions_at = positions.copy()
        return self._collisions

    def describe_state(self) -> str:
        """Say how close the surfaces are, which bodies are closest and the stiffness (collective).

        For a failed solve's message: the pairs within d̂, the closest pair's distance, its
        bodies (connected components of the surface, numbered from 0) and where it is, and κ
        against its initial value.
        """
        positions = self.positions()
        collisions = self._collisions_for(positions)
        initial = self.max_stiffness / ADAPTIVE_STIFFNESS_RANGE
        text = (
            f"contact: {len(collisions)} surface pairs within d̂ = {self.distance:.3g} m, "
            f"κ = {self.stiffness:.3g} ({self.stiffness / initial:.3g} × its initial value)"
        )
        closest = self._closest_pair(positions, collisions)
        if closest is not None:
            distance, vertices = closest
            bodies = sorted({int(self.surface.bodies[vertex]) for vertex in vertices})
            where = point_text(positions[vertices].mean(axis=0))
            between = (
                f"within body {bodies[0]}"
                if len(bodies) == 1
                else "between bodies " + " and ".join(str(body) for body in bodies)
            )
            text += f"; the closest pair {distance:.3g} m apart, {between}, at {where}"
        return text

    def _closest_pair(
        self, positions: np.ndarray, collisions: ipctk.NormalCollisions
    ) -> tuple[float, list[int]] | None:
        """Return the smallest distance of a collision of the set and its surface vertices."""
        points = np.asfortranarray(positions)
        edges, faces = self.collision_mesh.edges, self.collision_mesh.faces
        closest = None
        # One Python call per pair: only for a failed solve's message.
        for index in range(len(collisions)):
            collision = collisions[index]
            squared = float(collision.compute_distance(collision.dof(points, edges, faces)))
            if closest is None or squared < closest[0]:
                vertices = [int(v) for v in collision.vertex_ids(edges, faces) if v >= 0]
                closest = (squared, vertices)
        if closest is None:
            return None
        return math.sqrt(max(closest[0], 0.0)), closest[1]

    def active_pairs(self) -> int:
        """Pairs of surface primitives closer than d̂ (the barrier acts on them; collective)."""
        return len(self._collisions_for(self.positions()))

    def minimum_distance(self) -> float:
        """Smallest distance between non-adjacent surface primitives, capped at h (collective).

        Pairs farther apart than the surface vertex spacing h are not searched: h is returned
        when no pair is that close.
        """
        positions = np.asfortranarray(self.positions())
        # The runner logs it at a step's end and the adaptive κ reads it at the next step's
        # start, from the same positions: search once.
        if self._minimum_at is not None and np.array_equal(self._minimum_at[0], positions):
            return self._minimum_at[1]
        spacing = self.spacing
        # Within d̂ the barrier's own collision set holds every pair, and usually it is built at
        # these positions already; the wider search costs a broad phase with h for inflation.
        minimum = self._smallest_within_barrier(positions)
        if minimum is None:
            nearby = _collision_set()
            nearby.build(self.collision_mesh, positions, spacing, broad_phase=ipctk.HashGrid())
            minimum = _smallest_distance(nearby, self.collision_mesh, positions)
        minimum = spacing if minimum is None else min(minimum, spacing)
        self._minimum_at = (positions.copy(), minimum)
        return minimum

    def _smallest_within_barrier(self, positions: np.ndarray) -> float | None:
        """Return the smallest distance of a pair closer than d̂, ``None`` if there is none."""
        return _smallest_distance(
            self._collisions_for(positions), self.collision_mesh, np.asfortranarray(positions)
        )

    def distance_bound(self, positions: np.ndarray) -> float:
        """Return a lower bound of the distance of any two non-adjacent surface primitives.

        The smallest distance of a pair closer than d̂, else d̂ (collective).
        """
        minimum = self._smallest_within_barrier(positions)
        return self.distance if minimum is None else minimum

    def intersecting_pairs(self, positions: np.ndarray | None = None) -> np.ndarray:
        """Pairs of surface facets that cross each other, (k, 2), each pair once (collective).

        In 3D a triangle pair crosses where an edge of one passes through the other (ipctk's
        exact edge–triangle predicate); in 2D where two segments cross. Facets sharing a
        vertex are not tested.
        """
        if positions is None:
            positions = self.positions()
        if self._facets_of_edges is None and self.surface.dimension == 3:
            self._facets_of_edges = _facets_of_edges(self.faces, self.edges)
        return _intersecting_facets(
            self.surface, self.edges, self.faces, positions, self._facets_of_edges
        )

    def intersections(self) -> int:
        """Return the number of crossing surface facet pairs (0 in a correct run; collective)."""
        return len(self.intersecting_pairs())

    def check_intersection_free(self, when: str = "at t = 0") -> None:
        """Raise :class:`SurfaceIntersectionError` if two surface facets cross or touch.

        The message names the two bodies (connected components of the surface, numbered from
        0) and the first crossing facet pair with their centroids.
        """
        positions = self.positions()
        pairs = self.intersecting_pairs(positions)
        if len(pairs):
            first, second = (int(index) for index in pairs[0])
            raise SurfaceIntersectionError(
                f"the surfaces intersect {when}: {self._describe(first, positions)} crosses "
                f"{self._describe(second, positions)} ({len(pairs)} crossing facet pairs in all)"
            )
        distance = self.minimum_distance()
        if not distance > 0.0:
            raise SurfaceIntersectionError(
                f"two surface primitives touch {when} (distance {distance:.3g}); the barrier "
                "needs a positive gap"
            )

    def _describe(self, facet: int, positions: np.ndarray) -> str:
        vertices = self.surface.facets[facet]
        body = int(self.surface.bodies[vertices[0]])
        centroid = point_text(positions[vertices].mean(axis=0))
        return f"body {body}'s surface facet {facet} (centroid {centroid})"

    def step_limit(
        self, fraction: float = 0.9, narrow_phase: ipctk.NarrowPhaseCCD | None = None
    ) -> SurfaceCollisionFreeStep:
        """Return the continuous collision detection step cap of this term."""
        return SurfaceCollisionFreeStep(self, fraction=fraction, narrow_phase=narrow_phase)

    # -- EnergyTerm ---------------------------------------------------------------------------
    def energy(self) -> float:
        """Return this rank's share of the barrier energy: all of it on rank 0 (collective)."""
        positions = self.positions()
        collisions = self._collisions_for(positions)
        value = float(self.potential(collisions, self.collision_mesh, np.asfortranarray(positions)))
        if self._tangential is not None:
            value += float(
                self._friction_potential(
                    self._tangential, self.collision_mesh, self._slip(positions)
                )
            )
        return value if self.comm.rank == 0 else 0.0

    def add_residual(self, residual: np.ndarray) -> None:
        """Add the barrier's (and friction's) gradient into this rank's rows (collective)."""
        positions = self.positions()
        collisions = self._collisions_for(positions)
        gradient = np.zeros(len(self._global_dofs))
        if len(collisions):
            gradient += self.potential.gradient(
                collisions, self.collision_mesh, np.asfortranarray(positions)
            )
        if self._tangential is not None:
            gradient += self._friction_potential.gradient(
                self._tangential, self.collision_mesh, self._slip(positions)
            )
        residual[self.surface.owned_dofs.ravel()] += gradient[self._owned_rows]

    def add_tangent(self, matrix: PETSc.Mat, constrained: np.ndarray) -> None:
        """Add the barrier (and friction) Hessian into this rank's rows (collective).

        The Hessian is the SPD-projected or the exact one as :attr:`projected` says.

        The coupling of two surface vertices that come close lies outside the finite-element
        sparsity pattern: the matrix grows, once per new pair. Every coupling this term ever
        added is added again (as 0 where it does not act now), so that all matrices it is
        assembled into have nested patterns (:mod:`dolfinx_invertible.solvers.patterns`).
        """
        # On every rank, even one that adds nothing: PETSc's assembly takes a collective path
        # only on the ranks whose matrix may grow, and all must take the same one.
        matrix.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        positions = self.positions()
        collisions = self._collisions_for(positions)
        fixed = np.isin(self.surface.owned_dofs, constrained).astype(np.float64)
        fixed = self.surface.gather(fixed).ravel() > 0.5
        hessian = scipy.sparse.csr_matrix((len(self._global_dofs),) * 2)
        if len(collisions):
            hessian = hessian + self._hessian(positions, collisions)
        if self._tangential is not None:
            hessian = hessian + self._friction_potential.hessian(
                self._tangential,
                self.collision_mesh,
                self._slip(positions),
                project_hessian_to_psd=self._projection_method(),
            )
        rows = self._with_every_coupling(scipy.sparse.csr_matrix(hessian)[self._owned_rows])
        if rows.nnz == 0:
            return
        columns = np.where(fixed, -1, self._global_dofs)[rows.indices].astype(PETSc.IntType)
        row_numbers = np.where(fixed, -1, self._global_dofs)[self._owned_rows]
        matrix.setValuesIJV(
            rows.indptr.astype(PETSc.IntType),
            columns,
            rows.data,
            addv=PETSc.InsertMode.ADD_VALUES,
            rowmap=row_numbers.astype(PETSc.IntType),
        )

    def _with_every_coupling(self, rows: scipy.sparse.csr_matrix) -> scipy.sparse.csr_matrix:
        """``rows`` with explicit zeros at every coupling added before; remembers the union."""
        rows = rows.tocoo()
        if self._couplings is not None:
            rows = scipy.sparse.coo_matrix(
                (
                    np.concatenate([rows.data, np.zeros(self._couplings.nnz)]),
                    (
                        np.concatenate([rows.row, self._couplings.row]),
                        np.concatenate([rows.col, self._couplings.col]),
                    ),
                ),
                shape=rows.shape,
            )
        # Summing duplicates keeps explicit zeros: the union's pattern survives.
        union = rows.tocsr()
        union.sum_duplicates()
        self._couplings = union.tocoo()
        return union

    def _hessian(self, positions, collisions) -> scipy.sparse.spmatrix:
        return self.potential.hessian(
            collisions,
            self.collision_mesh,
            np.asfortranarray(positions),
            project_hessian_to_psd=self._projection_method(),
        )

    def _projection_method(self) -> ipctk.PSDProjectionMethod:
        return ipctk.PSDProjectionMethod.CLAMP if self.projected else ipctk.PSDProjectionMethod.NONE

    def __repr__(self) -> str:
        return (
            f"BodyContactTerm(surface vertices={len(self.surface)}, bodies="
            f"{self.surface.body_count}, distance={self.distance!r}, "
            f"stiffness={self.stiffness!r})"
        )


class SurfaceCollisionFreeStep:
    """Largest step along a Newton direction for which no two surface primitives collide.

    ipctk's CCD along the straight paths of the surface vertices; the step returned is
    ``fraction`` of the first time of contact (1 if there is none within 1).

    Parameters
    ----------
    term
        The :class:`BodyContactTerm`.
    fraction
        The share of the first time of contact a step may reach, in (0, 1).
    narrow_phase
        ipctk's narrow-phase CCD; default its additive CCD (conservative, with its own
        rescaling of 0.9). Tight inclusion (``ipctk.TightInclusionCCD()``) is as safe but
        slow where surfaces press together: in a self-contact collapse, one call on 4 588
        candidate pairs took 6.6 s against 0.18 s.
    """

    def __init__(
        self,
        term: BodyContactTerm,
        *,
        fraction: float = 0.9,
        narrow_phase: ipctk.NarrowPhaseCCD | None = None,
    ) -> None:
        self.term = term
        self.fraction = check_open_unit_interval("fraction", fraction)
        self.narrow_phase = ipctk.AdditiveCCD() if narrow_phase is None else narrow_phase

    def largest_step(self, direction: PETSc.Vec, sign: float = 1.0) -> float:
        """Largest α ≤ 1 for ``u + α · sign · direction`` (a PETSc Vec; collective)."""
        term = self.term
        start = term.positions()
        motion = float(sign) * term.surface.motion(direction.getArray(readonly=True))
        # Along the path stretched by 1/fraction, the first contact time t is fraction × the
        # first contact in units of the Newton step: exactly the cap (1 when t reaches 1).
        end = start + motion / self.fraction
        # No vertex moving farther than r, no two primitives close in by more than 2r: a step
        # that short against the closest pair needs no CCD (Newton's last iterations, free fall).
        reach = float(np.max(np.linalg.norm(motion, axis=1), initial=0.0)) / self.fraction
        if 2.0 * reach < term.distance_bound(start):
            step = 1.0
        else:
            step = ipctk.compute_collision_free_stepsize(
                term.collision_mesh,
                np.asfortranarray(start),
                np.asfortranarray(end),
                broad_phase=ipctk.HashGrid(),
                narrow_phase_ccd=self.narrow_phase,
            )
        return term.comm.allreduce(min(1.0, float(step)), op=MPI.MIN)


def _smallest_distance(
    collisions: ipctk.NormalCollisions, mesh: ipctk.CollisionMesh, positions: np.ndarray
) -> float | None:
    """Return the smallest distance of a collision set's pairs, ``None`` for an empty set."""
    if len(collisions) == 0:
        return None
    # ipctk measures squared distances.
    squared = float(collisions.compute_minimum_distance(mesh, np.asfortranarray(positions)))
    return math.sqrt(max(squared, 0.0))


def _intersecting_facets(
    surface: GatheredSurface,
    edges: np.ndarray,
    faces: np.ndarray,
    positions: np.ndarray,
    facet_of_edge: np.ndarray | None,
) -> np.ndarray:
    """Facet pairs that cross (see :meth:`BodyContactTerm.intersecting_pairs`)."""
    points = np.asfortranarray(positions)
    grid = ipctk.HashGrid()
    if surface.dimension == 3:
        grid.build(points, np.asfortranarray(edges), np.asfortranarray(faces), 0.0)
        candidates = grid.detect_edge_face_candidates()
        pairs = np.array([(c.edge_id, c.face_id) for c in candidates], dtype=np.int64)
        if len(pairs) == 0:
            return np.zeros((0, 2), dtype=np.int64)
        edge_vertices = edges[pairs[:, 0]]
        face_vertices = faces[pairs[:, 1]]
        shared = (edge_vertices[:, :, None] == face_vertices[:, None, :]).any(axis=(1, 2))
        pairs = pairs[~shared]
        crossing = [
            (edge, face)
            for edge, face in pairs
            if ipctk.is_edge_intersecting_triangle(
                positions[edges[edge, 0]],
                positions[edges[edge, 1]],
                *(positions[vertex] for vertex in faces[face]),
            )
        ]
        # An edge borders two triangles: each of them crosses the triangle the edge crosses.
        found = {
            tuple(sorted((int(facet), int(face))))
            for edge, face in crossing
            for facet in facet_of_edge[edge]
            if facet >= 0 and not set(faces[facet]) & set(faces[face])
        }
    else:
        grid.build(
            points, np.asfortranarray(edges), np.zeros((0, 3), dtype=np.int32, order="F"), 0.0
        )
        candidates = grid.detect_edge_edge_candidates()
        found = set()
        for candidate in candidates:
            first, second = int(candidate.edge0_id), int(candidate.edge1_id)
            if set(edges[first]) & set(edges[second]):
                continue
            if ipctk.segment_segment_intersect(
                positions[edges[first, 0]],
                positions[edges[first, 1]],
                positions[edges[second, 0]],
                positions[edges[second, 1]],
            ):
                found.add(tuple(sorted((first, second))))
    return np.array(sorted(found), dtype=np.int64).reshape(-1, 2)


def _facets_of_edges(faces: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Return the (up to two) triangles each edge borders, (E, 2), −1 where there is none."""
    key = {tuple(sorted(edge)): index for index, edge in enumerate(edges.tolist())}
    result = np.full((len(edges), 2), -1, dtype=np.int64)
    filled = np.zeros(len(edges), dtype=np.int64)
    for face, (a, b, c) in enumerate(faces.tolist()):
        for edge in ((a, b), (b, c), (c, a)):
            index = key[tuple(sorted(edge))]
            if filled[index] < 2:
                result[index, filled[index]] = face
                filled[index] += 1
    return result
