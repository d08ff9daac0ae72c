"""Primary contours in the 2D singular-value plane (Stomakhin et al. 2012, §3.2, Figs. 1–2).

With g = ∇Ψ̂(σ) and H = ∇²Ψ̂(σ) of a material in plane strain and v the eigenvector of H with
the largest-magnitude eigenvalue, the primary contour is {σ : v·g = 0}: where the stiffest
direction carries no force. A stretched element relaxes its stiff mode first and then follows
this curve, so a contour that crosses into σ₂ < 0 (corotated: σ₁ + σ₂ = 2) drives stretched
elements through inversion, and one that stays out (fixed corotated: J = 1 for large λ/μ) does
not.

Tracing. v is defined only up to sign, so v·g is not a function one can contour as it stands.
Marching squares on a grid of spacing ``spacing`` fixes the sign per grid edge instead: v at
the end of an edge is turned towards v at its start before the two values of v·g are compared,
and a crossing is refined on its edge the same way (Illinois false position, v at the trial
point turned towards v at the start). A refined crossing is kept when |v·g| ≤ 10⁻⁶ |g| there.
That rejects the sign changes across a jump of v, which are not zeros: where H jumps (the C1
extension's region boundaries, the kink of the canonical energy at σ₁ + σ₂ = 0) and where the
largest-magnitude eigenvalue switches between the two eigenvectors (indefinite H). A cell with
an odd number of crossings on its edges holds a point of repeated eigenvalues, around which v
turns by half a turn; the contour ends there. Contouring v·g itself, not a sign-invariant
product such as g × Hg (zero wherever g is any eigenvector), keeps the secondary contour
(g along v) out of the zero set: at large λ/μ it runs within a grid cell of the primary one.

Conventions. Points are signed singular values (σ₁, σ₂); the canonical points of the polar SVD
(the IFE convention) have σ₁ ≥ |σ₂|, σ₂ < 0 meaning inverted. The batch API evaluates any
signed pair through its canonical equivalent, so the traced function is the mirror image of the
canonical wedge elsewhere; by default the polylines are clipped to the wedge and the figures
shade the rest of the window.

Scene data. ``--mattress DIR`` and ``--triangles DIR`` (:func:`run`'s ``mattress`` and
``triangles``) take the output directory of a ``mattress-2d`` or ``triangles-2d`` run, whose
``trajectories.npy`` (elements × steps × 2, the IFE convention) and ``summary.json`` (the
material) replace the computed stand-ins of the stretch and relaxation figures.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time
from collections.abc import Sequence

import numpy as np

from dolfinx_invertible.constitutive import (
    C1,
    C2,
    Corotated,
    FixedCorotated,
    Material,
    NeoHookean,
    lame,
)
from dolfinx_invertible.reports import add_output_arguments

__all__ = [
    "DEFAULT_OUTPUT",
    "WINDOW",
    "add_arguments",
    "branches_through_rest",
    "command",
    "contour_residual",
    "distance_to_unit_volume",
    "fixed_corotated_distances",
    "gradient_field",
    "load_scene_trajectories",
    "overlay_trajectories",
    "plot_contours",
    "primary_contour",
    "relaxation_trajectories",
    "report_materials",
    "run",
    "stretch_trajectories",
]

#: Where ``report contours`` writes by default.
DEFAULT_OUTPUT = pathlib.Path("results/reports/contours")

#: Plotted window ((σ₁ min, σ₁ max), (σ₂ min, σ₂ max)): the canonical wedge σ₁ ≥ |σ₂| up to a
#: stretch of 4, with its apex and part of the invalid region.
WINDOW = ((-0.5, 4.0), (-1.5, 2.5))

#: |v·g| / |g| at or below which a refined crossing is on the primary contour.
PRIMARY_TOLERANCE = 1e-6

#: Young's modulus and Poisson ratio of the report's materials (λ/μ = 9, plane strain). The
#: contours depend only on λ/μ and the extensions' ε and k/μ.
YOUNGS_MODULUS = 1.0e5
POISSON_RATIO = 0.45

#: Deformations the three relaxing elements start from (canonical σ).
RELAXATION_STARTS = np.array([[2.6, -0.9], [0.45, 0.3], [3.4, 1.7]])

#: Lateral spring κ/μ of the three stretched elements.
LATERAL_STIFFNESS = (0.0, 1.0, 4.0)

#: λ/μ of the fixed corotated convergence check, and the range of σ₁ it measures on.
FIXED_COROTATED_RATIOS = (1.0, 10.0, 100.0)
MEASURED_STRETCH = (1.0, 3.0)

_REFINE_ITERATIONS = 60
# 1 − 1/golden ratio: far from every simple fraction.
_GRID_SHIFT = 0.3819660112501051
_REST = np.array([1.0, 1.0])
_COLORS = ("tab:orange", "tab:green", "tab:purple")
# σ₂ below −this counts as inverted: the wedge's apex σ = 0 is reached up to round-off.
_INVERTED = 1e-12


# --- evaluation -------------------------------------------------------------------------------


def _check_window(window) -> tuple[tuple[float, float], tuple[float, float]]:
    try:
        (low_1, high_1), (low_2, high_2) = window
        bounds = tuple(float(value) for value in (low_1, high_1, low_2, high_2))
    except (TypeError, ValueError) as error:
        raise ValueError(
            f"window must be ((sigma1_min, sigma1_max), (sigma2_min, sigma2_max)), got {window!r}"
        ) from error
    if not all(np.isfinite(bounds)) or bounds[0] >= bounds[1] or bounds[2] >= bounds[3]:
        raise ValueError(f"window needs finite bounds with min < max on both axes, got {window!r}")
    return (bounds[0], bounds[1]), (bounds[2], bounds[3])


def _derivatives(material: Material, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return g and H at signed singular values (n, 2); NaN where the plain model is undefined."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    gradient = np.full(points.shape, np.nan)
    hessian = np.full((len(points), 2, 2), np.nan)
    defined = np.ones(len(points), dtype=bool)
    if material.positive_only:
        defined = points[:, 0] * points[:, 1] > 0.0
    if defined.any():
        gradient[defined] = material.stress_sigma(points[defined])
        hessian[defined] = material.hessian_sigma(points[defined])
    return gradient, hessian


def _stiff_direction(hessian: np.ndarray) -> np.ndarray:
    """Return the unit eigenvector of the largest-magnitude eigenvalue, (n, 2); NaN where H is."""
    finite = np.isfinite(hessian).all(axis=(1, 2))
    stiff = np.full((len(hessian), 2), np.nan)
    if finite.any():
        values, vectors = np.linalg.eigh(hessian[finite])
        largest = np.argmax(np.abs(values), axis=1)
        stiff[finite] = vectors[np.arange(len(values)), :, largest]
    return stiff


def _field(material: Material, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return v (of arbitrary sign) and v·g at the points."""
    gradient, hessian = _derivatives(material, points)
    stiff = _stiff_direction(hessian)
    return stiff, np.einsum("ni,ni->n", stiff, gradient)


def _aligned(reference: np.ndarray, stiff: np.ndarray) -> np.ndarray:
    """Return the ±1 per row that turns ``stiff`` towards ``reference``."""
    return np.where(np.einsum("ni,ni->n", reference, stiff) < 0.0, -1.0, 1.0)


def contour_residual(material: Material, points: np.ndarray) -> np.ndarray:
    """|v·g| / |g| at signed singular values: 0 on the primary contour, at most 1.

    Parameters
    ----------
    material
        The material (evaluated in 2D, plane strain).
    points
        Signed singular values, shape (n, 2).

    Returns
    -------
    numpy.ndarray
        Shape (n,); 0 where g = 0 (the rest state), NaN where the material is undefined.
    """
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"points must have shape (n, 2), got shape {points.shape}")
    gradient, hessian = _derivatives(material, points)
    along = np.abs(np.einsum("ni,ni->n", _stiff_direction(hessian), gradient))
    norm = np.linalg.norm(gradient, axis=1)
    residual = along / np.where(norm > 0.0, norm, 1.0)
    return np.where(norm > 0.0, residual, np.where(np.isfinite(norm), 0.0, np.nan))


# --- tracing ----------------------------------------------------------------------------------


def _grid(window, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Return the grid axes: σ₁ uniform, σ₂ interior nodes shifted by a fraction of a step.

    The shift keeps nodes off the symmetry lines σ₂ = ±σ₁, where v·g vanishes or jumps by
    symmetry (a node there would carry a rounding-error sign), off the rest state and σ₂ = 0.
    """
    (low_1, high_1), (low_2, high_2) = window
    count_1 = int(np.ceil((high_1 - low_1) / spacing))
    count_2 = int(np.ceil((high_2 - low_2) / spacing))
    step_2 = (high_2 - low_2) / count_2
    interior = low_2 + (np.arange(count_2) + _GRID_SHIFT) * step_2
    return np.linspace(low_1, high_1, count_1 + 1), np.concatenate([[low_2], interior, [high_2]])


def _edge_crossings(stiff, along, start, end):
    """Find the sign changes of v·g along edges, v at the end turned towards v at the start."""
    turn = _aligned(stiff[start], stiff[end])
    value_start = along[start]
    value_end = turn * along[end]
    finite = np.isfinite(value_start) & np.isfinite(value_end)
    return finite & ((value_start > 0.0) != (value_end > 0.0)), value_start, value_end


def _cell_segments(shape, stiff, along):
    """Marching squares for v·g = 0 with the sign of v fixed per edge.

    Edge ids: horizontal edge (j, i)–(j, i+1) is j (nx − 1) + i; vertical edge (j, i)–(j+1, i)
    is ny (nx − 1) + j nx + i (j indexes σ₂, i indexes σ₁; node (j, i) is j nx + i). A cell
    whose edges carry an odd number of crossings holds a point where v turns by a half turn
    around it (repeated eigenvalues) or a jump of v: the contour ends there.

    Returns the edge endpoints (flat node indices), each edge's crossing flag and aligned end
    values, and the segments as pairs of edge ids.
    """
    ny, nx = shape
    nodes = np.arange(ny * nx).reshape(shape)
    start = np.concatenate([nodes[:, :-1].ravel(), nodes[:-1, :].ravel()])
    end = np.concatenate([nodes[:, 1:].ravel(), nodes[1:, :].ravel()])
    crossing, value_start, value_end = _edge_crossings(stiff, along, start, end)
    horizontal = crossing[: ny * (nx - 1)].reshape(ny, nx - 1)
    vertical = crossing[ny * (nx - 1) :].reshape(ny - 1, nx)

    rows, columns = np.meshgrid(np.arange(ny - 1), np.arange(nx - 1), indexing="ij")
    bottom = rows * (nx - 1) + columns
    top = (rows + 1) * (nx - 1) + columns
    left = ny * (nx - 1) + rows * nx + columns
    right = left + 1
    # Counter-clockwise from the bottom edge; corner k sits between edges k − 1 and k.
    ids = np.stack([bottom, right, top, left])
    flags = np.stack([horizontal[:-1], vertical[:, 1:], horizontal[1:], vertical[:, :-1]])
    count = flags.sum(axis=0)

    segments = []
    pairs = count == 2
    if pairs.any():
        order = np.argsort(~flags[:, pairs], axis=0, kind="stable")[:2]
        segments.append(np.take_along_axis(ids[:, pairs], order, axis=0).T)
    saddles = count == 4
    if saddles.any():
        corners = np.stack([nodes[:-1, :-1], nodes[:-1, 1:], nodes[1:, 1:], nodes[1:, :-1]])
        corners = corners[:, saddles]
        reference = stiff[corners[0]]
        values = np.stack(
            [_aligned(reference, stiff[corner]) * along[corner] for corner in corners]
        )
        # The asymptotic decider: the bilinear interpolant's value at its saddle point tells
        # which pair of opposite corners the sign connects. Cut off corners 0 and 2
        # (bottom-left, top-right) when that pair is separated, otherwise corners 1 and 3.
        saddle = (values[0] * values[2] - values[1] * values[3]) / (
            values[0] + values[2] - values[1] - values[3]
        )
        cut_first = (saddle > 0.0) != (values[0] > 0.0)
        cell_ids = ids[:, saddles]
        first = np.where(cut_first, cell_ids[3], cell_ids[0])
        second = np.where(cut_first, cell_ids[0], cell_ids[1])
        third = np.where(cut_first, cell_ids[1], cell_ids[2])
        fourth = np.where(cut_first, cell_ids[2], cell_ids[3])
        segments.append(np.stack([first, second], axis=1))
        segments.append(np.stack([third, fourth], axis=1))
    segments = np.concatenate(segments) if segments else np.empty((0, 2), dtype=np.int64)
    return start, end, crossing, value_start, value_end, segments


def _chain(segments: np.ndarray) -> list[list[int]]:
    """Join segments (pairs of edge ids; each id in at most two) into paths of edge ids."""
    neighbours: dict[int, list[int]] = {}
    for a, b in segments.tolist():
        neighbours.setdefault(a, []).append(b)
        neighbours.setdefault(b, []).append(a)
    visited: set[int] = set()
    paths = []
    ends = [node for node, linked in neighbours.items() if len(linked) == 1]
    for first in ends + list(neighbours):
        if first in visited:
            continue
        path = [first]
        visited.add(first)
        current = first
        while True:
            following = [node for node in neighbours[current] if node not in visited]
            if not following:
                break
            current = following[0]
            visited.add(current)
            path.append(current)
        if len(path) > 2 and first in neighbours[path[-1]]:
            path.append(first)
        paths.append(path)
    return paths


def _refine(material, start, end, stiff_start, value_start, value_end):
    """Find the zeros of v·g (v turned towards v at the start) on segments: Illinois method."""
    low = np.zeros(len(start))
    high = np.ones(len(start))
    f_low = value_start.copy()
    f_high = value_end.copy()
    side = np.zeros(len(start), dtype=np.int8)
    t = f_low / (f_low - f_high)
    active = np.ones(len(start), dtype=bool)
    for _ in range(_REFINE_ITERATIONS):
        if not active.any():
            break
        index = np.flatnonzero(active)
        t_active = (low[index] * f_high[index] - high[index] * f_low[index]) / (
            f_high[index] - f_low[index]
        )
        t[index] = t_active
        points = start[index] + t_active[:, np.newaxis] * (end[index] - start[index])
        stiff, along = _field(material, points)
        value = _aligned(stiff_start[index], stiff) * along
        exact = value == 0.0
        with_high = (value * f_high[index] > 0.0) & ~exact
        with_low = ~with_high & ~exact
        # Replace the endpoint on the same side; halve the other's value if it stuck twice.
        high_index = index[with_high]
        high[high_index], f_high[high_index] = t_active[with_high], value[with_high]
        f_low[high_index] *= np.where(side[high_index] == -1, 0.5, 1.0)
        side[high_index] = -1
        low_index = index[with_low]
        low[low_index], f_low[low_index] = t_active[with_low], value[with_low]
        f_high[low_index] *= np.where(side[low_index] == 1, 0.5, 1.0)
        side[low_index] = 1
        done = exact | (high[index] - low[index] <= 1e-14) | ~np.isfinite(value)
        active[index[done]] = False
    return start + t[:, np.newaxis] * (end - start)


def _wedge_crossing(inside_point: np.ndarray, outside_point: np.ndarray) -> np.ndarray:
    """Find where the chord meets σ₁ = |σ₂| (bisection; the boundary is piecewise linear)."""
    low, high = 0.0, 1.0
    for _ in range(60):
        middle = 0.5 * (low + high)
        point = inside_point + middle * (outside_point - inside_point)
        if point[0] - abs(point[1]) >= 0.0:
            low = middle
        else:
            high = middle
    return inside_point + low * (outside_point - inside_point)


def _split(points: np.ndarray, keep: np.ndarray, inside: np.ndarray, clip: bool):
    """Split into runs of kept points; with ``clip``, cut at the wedge boundary σ₁ = |σ₂|."""
    runs = []
    current: list[np.ndarray] = []
    for index in range(len(points)):
        accepted = keep[index] and (inside[index] or not clip)
        previous_kept = index > 0 and keep[index - 1]
        if accepted:
            if not current and clip and previous_kept and not inside[index - 1]:
                current.append(_wedge_crossing(points[index], points[index - 1]))
            current.append(points[index])
        elif current:
            if clip and keep[index] and not inside[index]:
                current.append(_wedge_crossing(points[index - 1], points[index]))
            runs.append(current)
            current = []
    if current:
        runs.append(current)
    # A run can collapse onto one point (a zero exactly at a grid node on the window's edge).
    runs = [np.array(run) for run in runs if len(run) >= 2]
    return [run for run in runs if np.ptp(run, axis=0).max() > 0.0]


def primary_contour(
    material: Material,
    *,
    window=WINDOW,
    spacing: float = 0.01,
    canonical_only: bool = True,
) -> list[np.ndarray]:
    """Trace the primary contour {σ : v·g = 0} of a material in the 2D singular-value plane.

    Parameters
    ----------
    material
        The material, evaluated in 2D (plane strain) through the batch API.
    window
        ((σ₁ min, σ₁ max), (σ₂ min, σ₂ max)), the region traced.
    spacing
        Grid spacing of the marching squares (the largest one that fits the window evenly).
        Branches closer than about that may be joined or missed, and a branch that ends at a
        point of repeated eigenvalues stops within a cell of it; the vertices themselves are
        refined to round-off.
    canonical_only
        Clip the polylines to the canonical wedge σ₁ ≥ |σ₂| (their end points on its boundary
        are chord interpolations). Otherwise the mirror images outside it are kept too.

    Returns
    -------
    list of numpy.ndarray
        Polylines of shape (k, 2), k ≥ 2, ordered along the curve.
    """
    if not isinstance(material, Material):
        raise TypeError(f"material must be a Material, got {material!r}")
    window = _check_window(window)
    spacing = float(spacing)
    if not (np.isfinite(spacing) and spacing > 0.0):
        raise ValueError(f"spacing must be a finite number > 0, got {spacing!r}")
    axis_1, axis_2 = _grid(window, spacing)
    if len(axis_1) * len(axis_2) > 4_000_000:
        raise ValueError(
            f"spacing {spacing} gives a {len(axis_1)} x {len(axis_2)} grid; use a coarser one"
        )
    grid = np.stack(np.meshgrid(axis_1, axis_2, indexing="xy"), axis=-1).reshape(-1, 2)
    stiff, along = _field(material, grid)
    # A node exactly on the contour (on a symmetry line at the window's edge) has no sign that
    # survives flipping v: move it off by a hair, along its window edge when it is on one.
    zero = np.flatnonzero(along == 0.0)
    if len(zero):
        hair = 1e-7 * spacing
        on_side = (grid[zero, 0] == window[0][0]) | (grid[zero, 0] == window[0][1])
        downward = np.where(grid[zero, 1] == window[1][1], -hair, hair)
        grid[zero, 0] += np.where(on_side, 0.0, hair)
        grid[zero, 1] += np.where(on_side, downward, 0.0)
        stiff[zero], along[zero] = _field(material, grid[zero])
    shape = (len(axis_2), len(axis_1))
    start, end, crossing, value_start, value_end, segments = _cell_segments(shape, stiff, along)
    if not len(segments):
        return []

    edges = np.flatnonzero(crossing)
    vertices = _refine(
        material,
        grid[start[edges]],
        grid[end[edges]],
        stiff[start[edges]],
        value_start[edges],
        value_end[edges],
    )
    # Crossings of a jump of v (not a zero) stay far from v·g = 0 and are dropped here.
    keep = contour_residual(material, vertices) <= PRIMARY_TOLERANCE
    # Crossings refined onto σ₁ = |σ₂| (a symmetry line) must not flicker in and out.
    inside = vertices[:, 0] - np.abs(vertices[:, 1]) >= -1e-9 * spacing

    position = np.full(len(crossing), -1)
    position[edges] = np.arange(len(edges))
    polylines = []
    for path in _chain(segments):
        local = position[np.array(path)]
        polylines.extend(_split(vertices[local], keep[local], inside[local], canonical_only))
    return polylines


def branches_through_rest(polylines: list[np.ndarray], *, spacing: float) -> list[np.ndarray]:
    """Select the polylines that pass within two grid cells of the rest state σ = (1, 1).

    Every primary contour passes through the rest state (g = 0 there); clipped to the wedge,
    the branch ends on its boundary σ₁ = σ₂ next to it. This is the branch a stretched element
    follows.

    Parameters
    ----------
    polylines
        From :func:`primary_contour`.
    spacing
        The spacing they were traced with.

    Returns
    -------
    list of numpy.ndarray
        The polylines through the rest state, in the given order.
    """
    reach = 2.0 * np.sqrt(2.0) * float(spacing)
    return [
        polyline
        for polyline in polylines
        if np.min(np.linalg.norm(polyline - _REST, axis=1)) <= reach
    ]


# --- analytic measures ------------------------------------------------------------------------


def distance_to_unit_volume(points: np.ndarray) -> np.ndarray:
    """Return the Euclidean distance of points (σ₁, σ₂) to the hyperbola σ₁σ₂ = 1, σ₁ > 0.

    Parameters
    ----------
    points
        Shape (n, 2).

    Returns
    -------
    numpy.ndarray
        Shape (n,). The nearest point (t, 1/t) is a positive root of t⁴ − σ₁t³ + σ₂t − 1
        (the distance is stationary there); every root's positive real part is tried, so a
        root that rounding moved off the real axis still counts.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    distances = np.empty(len(points))
    for index, (x, y) in enumerate(points):
        candidates = np.roots([1.0, -x, 0.0, y, -1.0]).real
        candidates = candidates[candidates > 0.0]
        distances[index] = np.min(np.hypot(x - candidates, y - 1.0 / candidates))
    return distances


# --- trajectories -----------------------------------------------------------------------------


def _canonical(sigma: np.ndarray) -> np.ndarray:
    """Return the IFE representative: |σ| sorted down, an odd sign on the last entry."""
    magnitude = np.sort(np.abs(sigma))[::-1]
    if np.prod(sigma) < 0.0:
        magnitude[-1] = -magnitude[-1]
    return magnitude


def _shear_modulus(material: Material) -> float:
    """Return μ from the rest Hessian 2μI + λ11ᵀ, which every model shares."""
    hessian = material.hessian_sigma(_REST)
    return 0.5 * (hessian[0, 0] - hessian[0, 1])


def _projected(hessian: np.ndarray) -> np.ndarray:
    values, vectors = np.linalg.eigh(hessian)
    return (vectors * np.maximum(values, 0.0)) @ vectors.T


def stretch_trajectories(
    material: Material,
    *,
    stretches: np.ndarray | None = None,
    lateral_stiffness: Sequence[float] = LATERAL_STIFFNESS,
) -> np.ndarray:
    """Stretch single elements quasi-statically: σ₁ imposed, σ₂ at equilibrium.

    A stand-in for the elements of a mattress pulled by two sides. For each imposed σ₁, σ₂
    minimises Ψ̂(σ₁, σ₂) + κ/2 (σ₂ − 1)², the spring κ standing for the lateral restraint of
    the surrounding mesh (κ = 0: free sides, uniaxial stress). One-dimensional Newton with an
    energy backtracking line search, continued from the previous stretch.

    Parameters
    ----------
    material
        The material (2D).
    stretches
        Imposed σ₁ per step; default 51 values from 1 to 3.5.
    lateral_stiffness
        κ/μ per element, μ the shear modulus.

    Returns
    -------
    numpy.ndarray
        Shape (elements, steps, 2): canonical signed singular values.
    """
    stretches = np.linspace(1.0, 3.5, 51) if stretches is None else np.asarray(stretches, float)
    if stretches.ndim != 1 or len(stretches) < 2 or not np.isfinite(stretches).all():
        raise ValueError("stretches must be a 1D array of at least two finite values")
    mu = _shear_modulus(material)
    trajectories = np.empty((len(lateral_stiffness), len(stretches), 2))
    for element, factor in enumerate(lateral_stiffness):
        kappa = float(factor) * mu
        if not (np.isfinite(kappa) and kappa >= 0.0):
            raise ValueError(f"lateral_stiffness must be finite and >= 0, got {factor!r}")
        lateral = 1.0
        for step, stretch in enumerate(stretches):
            lateral = _lateral_equilibrium(material, stretch, lateral, kappa, mu)
            trajectories[element, step] = _canonical(np.array([stretch, lateral]))
    return trajectories


def _lateral_equilibrium(material, stretch, lateral, kappa, mu):
    def potential(value):
        return material.energy_sigma(np.array([stretch, value])) + 0.5 * kappa * (value - 1) ** 2

    energy = potential(lateral)
    for _ in range(100):
        point = np.array([stretch, lateral])
        slope = material.stress_sigma(point)[1] + kappa * (lateral - 1.0)
        if abs(slope) <= 1e-11 * mu:
            break
        curvature = max(material.hessian_sigma(point)[1, 1] + kappa, 1e-3 * mu)
        step = -slope / curvature
        length = 1.0
        while length > 1e-12:
            candidate = lateral + length * step
            candidate_energy = potential(candidate)
            if candidate_energy <= energy + 1e-4 * length * slope * step:
                break
            length *= 0.5
        if candidate_energy > energy:
            # No decrease left above the energy's rounding error: converged.
            break
        lateral, energy = candidate, candidate_energy
    return lateral


def relaxation_trajectories(
    material: Material,
    starts: np.ndarray,
    *,
    steps: int = 60,
    first_step: float = 0.01,
    growth: float = 1.08,
) -> np.ndarray:
    """Relax single free elements from given deformations by implicit gradient flow.

    A stand-in for the paper's triangles relaxing from different deformations. With the
    deformation gradient of a free element as the unknown (up to translation and rotation),
    gradient flow keeps U and V and moves σ along −g; each backward-Euler step minimises
    ½‖σ − σₙ‖²/Δt + Ψ̂(σ)/(2μ) by Newton with the SPD-projected Hessian and an energy
    backtracking line search. Δt is in units of the soft (shear) relaxation time, starting at
    ``first_step`` and growing by ``growth``, so both the stiff and the soft mode are resolved.

    Parameters
    ----------
    material
        The material (2D); it needs an energy (not IFE).
    starts
        Initial signed singular values, shape (elements, 2).
    steps
        Number of time steps.
    first_step
        First Δt.
    growth
        Factor between consecutive Δt.

    Returns
    -------
    numpy.ndarray
        Shape (elements, steps + 1, 2): canonical signed singular values, the start first.
    """
    starts = np.asarray(starts, dtype=float)
    if starts.ndim != 2 or starts.shape[1] != 2 or not np.isfinite(starts).all():
        raise ValueError(
            f"starts must be a finite array of shape (elements, 2), got {starts.shape}"
        )
    if int(steps) < 1 or not (first_step > 0.0 and growth >= 1.0):
        raise ValueError("steps must be >= 1, first_step > 0 and growth >= 1")
    scale = 2.0 * _shear_modulus(material)
    trajectories = np.empty((len(starts), int(steps) + 1, 2))
    for element, start in enumerate(starts):
        sigma = _canonical(start)
        trajectories[element, 0] = sigma
        step = float(first_step)
        for index in range(1, int(steps) + 1):
            sigma = _canonical(_backward_euler_step(material, sigma, step, scale))
            trajectories[element, index] = sigma
            step *= growth
    return trajectories


def _backward_euler_step(material, previous, step, scale):
    def potential(sigma):
        return 0.5 * np.sum((sigma - previous) ** 2) / step + material.energy_sigma(sigma) / scale

    def residual_of(sigma):
        inertia = (sigma - previous) / step
        force = material.stress_sigma(sigma) / scale
        return inertia + force, max(np.linalg.norm(inertia) + np.linalg.norm(force), 1.0)

    sigma = previous.copy()
    energy = potential(sigma)
    residual, size = residual_of(sigma)
    for _ in range(50):
        if np.linalg.norm(residual) <= 1e-10 * size:
            break
        system = np.eye(2) / step + _projected(material.hessian_sigma(sigma)) / scale
        direction = -np.linalg.solve(system, residual)
        slope = residual @ direction
        if -slope <= 1e-12 * abs(energy):
            # The decrease is below the energy's rounding error: the residual decides.
            candidate = sigma + direction
            candidate_residual, candidate_size = residual_of(candidate)
            if np.linalg.norm(candidate_residual) >= np.linalg.norm(residual):
                break
            sigma, energy = candidate, potential(candidate)
            residual, size = candidate_residual, candidate_size
            continue
        length = 1.0
        for _ in range(40):
            candidate = sigma + length * direction
            candidate_energy = potential(candidate)
            if candidate_energy <= energy + 1e-4 * length * slope:
                break
            length *= 0.5
        else:
            break
        sigma, energy = candidate, candidate_energy
        residual, size = residual_of(sigma)
    return sigma


# --- figures ----------------------------------------------------------------------------------


def gradient_field(
    material: Material, *, window=WINDOW, count: tuple[int, int] = (19, 17)
) -> tuple[np.ndarray, np.ndarray]:
    """Sample points strictly inside the canonical wedge and the energy gradient g there.

    Parameters
    ----------
    material
        The material (2D).
    window
        The plotted window.
    count
        Grid points along σ₁ and σ₂ before keeping those inside the wedge.

    Returns
    -------
    tuple of numpy.ndarray
        Points (n, 2) and g = ∇Ψ̂ at them (n, 2).
    """
    (low_1, high_1), (low_2, high_2) = _check_window(window)
    margin_1 = 0.5 * (high_1 - low_1) / count[0]
    margin_2 = 0.5 * (high_2 - low_2) / count[1]
    axis_1 = np.linspace(low_1 + margin_1, high_1 - margin_1, count[0])
    axis_2 = np.linspace(low_2 + margin_2, high_2 - margin_2, count[1])
    points = np.stack(np.meshgrid(axis_1, axis_2), axis=-1).reshape(-1, 2)
    points = points[points[:, 0] > np.abs(points[:, 1]) + 0.5 * min(margin_1, margin_2)]
    gradient, _ = _derivatives(material, points)
    defined = np.isfinite(gradient).all(axis=1)
    return points[defined], gradient[defined]


def _shade(axes, window) -> None:
    """Shade σ₁ < |σ₂| (invalid) and tint the inverted half σ₂ < 0 of the wedge."""
    (low_1, high_1), (low_2, high_2) = window
    sigma_1 = np.unique(np.concatenate([np.linspace(low_1, high_1, 400), [0.0]]))
    sigma_1 = sigma_1[(sigma_1 >= low_1) & (sigma_1 <= high_1)]
    wedge = sigma_1 >= 0.0
    upper = np.where(wedge, np.clip(sigma_1, low_2, high_2), low_2)
    lower = np.where(wedge, np.clip(-sigma_1, low_2, high_2), low_2)
    style = {"facecolor": "0.82", "edgecolor": "0.6", "hatch": "//", "linewidth": 0.0}
    axes.fill_between(sigma_1, upper, high_2, label="invalid (σ₁ < |σ₂|)", **style)
    axes.fill_between(sigma_1, low_2, lower, **style)
    inverted_top = np.where(wedge, np.clip(0.0, low_2, high_2), low_2)
    axes.fill_between(
        sigma_1,
        lower,
        np.maximum(lower, inverted_top),
        facecolor="tab:red",
        alpha=0.08,
        linewidth=0.0,
        label="inverted (σ₂ < 0)",
    )
    if low_2 < 0.0 < high_2:
        axes.axhline(0.0, color="tab:red", linewidth=0.6, alpha=0.6)


def _reference_curves(axes, window) -> None:
    """σ₁ + σ₂ = 2 and J = 1 inside the wedge, for reference."""
    (low_1, high_1), (low_2, high_2) = window
    sigma_1 = np.linspace(max(low_1, 1.0), max(high_1, 1.0), 300)
    for values, style, label in (
        (2.0 - sigma_1, "--", "σ₁ + σ₂ = 2"),
        (1.0 / sigma_1, ":", "J = 1"),
    ):
        inside = (values >= low_2) & (values <= high_2)
        axes.plot(
            sigma_1[inside],
            values[inside],
            color="0.35",
            linestyle=style,
            linewidth=0.9,
            label=label,
        )


def _draw_branches(axes, polylines, spacing) -> dict:
    """Draw the branch through the rest state solid, the others dashed."""
    rest = {id(polyline) for polyline in branches_through_rest(polylines, spacing=spacing)}
    lines = {"rest": [], "other": []}
    for polyline in polylines:
        key = "rest" if id(polyline) in rest else "other"
        label = None
        if not lines[key]:
            label = "primary contour through rest" if key == "rest" else "other branches"
        style = (
            {"linewidth": 2.4, "linestyle": "-"}
            if key == "rest"
            else {"linewidth": 1.4, "linestyle": (0, (4, 2))}
        )
        (line,) = axes.plot(
            polyline[:, 0], polyline[:, 1], color="black", label=label, zorder=3, **style
        )
        lines[key].append(line)
    return lines


def plot_contours(
    axes,
    material: Material,
    *,
    window=WINDOW,
    spacing: float = 0.01,
    title: str | None = None,
    contour: list[np.ndarray] | None = None,
    arrows: tuple[int, int] = (19, 17),
    legend: bool = True,
) -> dict:
    """Draw a material's primary contour, the field of −g and the invalid region on ``axes``.

    The arrows show the direction of −g = −∇Ψ̂, the force on an element in σ-space (where it
    moves when it relaxes), all of one length; the shaded region is outside the canonical
    wedge σ₁ ≥ |σ₂|, and the tinted part of the wedge is inverted (σ₂ < 0). The branch of the
    contour through the rest state (star) is solid, other branches dashed; thin grey lines are
    σ₁ + σ₂ = 2 (dashed) and J = 1 (dotted) for reference.

    Parameters
    ----------
    axes
        A matplotlib Axes.
    material
        The material (2D).
    window
        The plotted window.
    spacing
        Tracing grid spacing (also used to find the branch through rest in ``contour``).
    title
        Axes title.
    contour
        Polylines from :func:`primary_contour` traced with ``spacing``, to reuse a trace.
    arrows
        Arrow grid (σ₁, σ₂) before keeping the points inside the wedge.
    legend
        Draw a legend.

    Returns
    -------
    dict
        ``"quiver"``: the Quiver, whose X, Y, U, V are the arrow positions and −g/|g|;
        ``"contour"``: ``{"rest": [...], "other": [...]}``, the Line2D of the branches;
        ``"polylines"``: the traced polylines.
    """
    window = _check_window(window)
    if contour is None:
        contour = primary_contour(material, window=window, spacing=spacing)
    _shade(axes, window)
    _reference_curves(axes, window)
    points, gradient = gradient_field(material, window=window, count=arrows)
    norm = np.linalg.norm(gradient, axis=1, keepdims=True)
    direction = -gradient / np.where(norm > 0.0, norm, 1.0)
    length = 0.6 * min(window[0][1] - window[0][0], window[1][1] - window[1][0]) / max(arrows)
    quiver = axes.quiver(
        points[:, 0],
        points[:, 1],
        direction[:, 0],
        direction[:, 1],
        angles="xy",
        scale_units="xy",
        scale=1.0 / length,
        width=0.0035,
        color="tab:blue",
        alpha=0.55,
    )
    lines = _draw_branches(axes, contour, spacing)
    axes.plot(*_REST, marker="*", color="gold", markeredgecolor="black", markersize=11, zorder=5)
    axes.set_xlim(*window[0])
    axes.set_ylim(*window[1])
    axes.set_aspect("equal")
    axes.set_xlabel("σ₁")
    axes.set_ylabel("σ₂ (signed)")
    if title:
        axes.set_title(title, fontsize=10)
    if legend:
        axes.legend(loc="upper left", fontsize=7, framealpha=0.92)
    return {"quiver": quiver, "contour": lines, "polylines": contour}


def overlay_trajectories(
    axes,
    trajectories: np.ndarray,
    *,
    labels: Sequence[str] | None = None,
    colors: Sequence | None = None,
    tolerance: float = 1e-9,
    linewidth: float = 1.4,
    markers: bool = True,
) -> list:
    """Draw element trajectories in the σ-plane on top of a contour plot.

    Parameters
    ----------
    axes
        A matplotlib Axes, typically one :func:`plot_contours` drew on.
    trajectories
        Shape (elements, steps, 2): each element's signed singular values per step, sorted in
        the IFE convention (σ₁ ≥ |σ₂|, an inversion's sign on σ₂), e.g. from a scene's output.
    labels
        One legend label per element, or None.
    colors
        One matplotlib colour per element, or None for the colour cycle.
    tolerance
        Relative slack on σ₁ ≥ |σ₂| for round-off in the data.
    linewidth
        Line width of the trajectories.
    markers
        Mark each start (circle) and end (square).

    Returns
    -------
    list
        The Line2D of each trajectory, in element order.
    """
    trajectories = np.asarray(trajectories, dtype=float)
    if trajectories.ndim != 3 or trajectories.shape[2] != 2 or trajectories.shape[1] < 1:
        raise ValueError(
            f"trajectories must have shape (elements, steps, 2), got shape {trajectories.shape}"
        )
    bad = np.argwhere(~np.isfinite(trajectories).all(axis=2))
    if len(bad):
        element, step = bad[0]
        raise ValueError(
            f"trajectories has {len(bad)} non-finite points, the first at element {element}, "
            f"step {step}"
        )
    slack = tolerance * np.maximum(1.0, np.abs(trajectories).max(axis=2))
    wrong = np.argwhere(trajectories[..., 0] < np.abs(trajectories[..., 1]) - slack)
    if len(wrong):
        element, step = wrong[0]
        raise ValueError(
            f"trajectories must follow the IFE convention sigma1 >= |sigma2|; {len(wrong)} "
            f"points do not, the first at element {element}, step {step}: "
            f"{trajectories[element, step].tolist()}"
        )
    count = len(trajectories)
    for name, values in (("labels", labels), ("colors", colors)):
        if values is not None and len(values) != count:
            raise ValueError(f"{name} has {len(values)} entries for {count} trajectories")
    lines = []
    for element, path in enumerate(trajectories):
        options = {"linewidth": linewidth, "zorder": 4}
        if colors is not None:
            options["color"] = colors[element]
        if labels is not None:
            options["label"] = labels[element]
        (line,) = axes.plot(path[:, 0], path[:, 1], **options)
        if markers:
            color = line.get_color()
            axes.plot(*path[0], marker="o", color=color, markersize=5, zorder=6)
            axes.plot(
                *path[-1], marker="s", color=color, markeredgecolor="black", markersize=5, zorder=6
            )
        lines.append(line)
    return lines


# --- the report -------------------------------------------------------------------------------


def report_materials(
    *, youngs_modulus: float = YOUNGS_MODULUS, poisson_ratio: float = POISSON_RATIO
) -> dict[str, Material]:
    """Build the four materials of the paper's Figs. 1–2, by display name.

    Parameters
    ----------
    youngs_modulus
        E of every material.
    poisson_ratio
        ν of every material.

    Returns
    -------
    dict
        Neo-Hookean + C1 (ε = 0.4, k = 20E), Neo-Hookean + C2 (ε = 0.9), corotated and fixed
        corotated.
    """
    mu, lam = lame(youngs_modulus, poisson_ratio)
    return {
        "Neo-Hookean + C1": Material(NeoHookean(mu=mu, lam=lam), C1(eps=0.4)),
        "Neo-Hookean + C2": Material(NeoHookean(mu=mu, lam=lam), C2(eps=0.9)),
        "corotated": Material(Corotated(mu=mu, lam=lam)),
        "fixed corotated": Material(FixedCorotated(mu=mu, lam=lam)),
    }


def _new_figure(**options):
    """Make a figure on an Agg canvas outside pyplot: no global backend state to change."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(layout="constrained", **options)
    FigureCanvasAgg(figure)
    return figure


def _panels(materials, contours, spacing, title, trajectories=None, labels=None):
    figure = _new_figure(figsize=(11, 10.2))
    artists = {}
    for axes, (name, material) in zip(
        figure.subplots(2, 2).ravel(), materials.items(), strict=True
    ):
        drawn = plot_contours(
            axes, material, spacing=spacing, contour=contours[name], title=name, legend=False
        )
        if trajectories is not None:
            elements = len(trajectories[name])
            drawn["trajectories"] = overlay_trajectories(
                axes, trajectories[name], labels=labels, colors=_COLORS[:elements]
            )
        axes.legend(loc="upper left", fontsize=7, framealpha=0.92)
        artists[name] = drawn
    figure.suptitle(title, fontsize=11)
    return figure, artists


def _fixed_corotated_figure(branches, distances):
    figure = _new_figure(figsize=(11, 4.6))
    left, right = figure.subplots(1, 2)
    sigma_1 = np.linspace(0.8, 3.2, 200)
    left.plot(sigma_1, 1.0 / sigma_1, color="0.2", linestyle=":", linewidth=1.4, label="J = 1")
    colors = ("tab:red", "tab:orange", "tab:blue", "tab:green", "tab:purple")
    for number, (ratio, polylines) in enumerate(branches.items()):
        color = colors[number % len(colors)]
        for index, polyline in enumerate(polylines):
            first = index == 0
            left.plot(
                polyline[:, 0],
                polyline[:, 1],
                color=color,
                linewidth=1.6,
                label=f"λ/μ = {ratio}" if first else None,
            )
            # The rest state itself is on J = 1: leave it out of the logarithmic plot.
            away = polyline[:, 0] > 1.0 + 1e-3
            right.semilogy(
                polyline[away, 0],
                distance_to_unit_volume(polyline[away]),
                color=color,
                label=f"λ/μ = {ratio}: max {distances[ratio]:.2e}" if first else None,
            )
    for axes in (left, right):
        axes.axvspan(*MEASURED_STRETCH, color="0.5", alpha=0.07, linewidth=0.0)
        axes.set_xlim(0.8, 3.2)
        axes.set_xlabel("σ₁")
        axes.legend(fontsize=8)
    left.set_ylim(0.2, 1.2)
    left.set_ylabel("σ₂")
    left.set_title("branch through rest (σ₂ ≤ σ₁)", fontsize=10)
    right.set_ylabel("distance to J = 1")
    right.set_title(
        f"distance to J = 1; max over {MEASURED_STRETCH[0]:g} ≤ σ₁ ≤ {MEASURED_STRETCH[1]:g} "
        "(shaded)",
        fontsize=10,
    )
    figure.suptitle("Fixed corotated: the primary contour approaches J = 1 as λ/μ grows")
    return figure


def _measured(polylines: list[np.ndarray]) -> np.ndarray:
    """Select the contour points with σ₁ in the measured stretch range."""
    points = np.concatenate(polylines) if polylines else np.empty((0, 2))
    low, high = MEASURED_STRETCH
    return points[(points[:, 0] >= low) & (points[:, 0] <= high)]


def fixed_corotated_distances(
    ratios: Sequence[float] = FIXED_COROTATED_RATIOS, *, spacing: float = 0.01
) -> tuple[dict[str, list[np.ndarray]], dict[str, float]]:
    """Measure the distance of the fixed corotated contour from J = 1 for several λ/μ.

    Parameters
    ----------
    ratios
        The λ/μ values (μ = 1).
    spacing
        Tracing grid spacing.

    Returns
    -------
    tuple of dict
        By λ/μ (formatted ``f"{ratio:g}"``): the branches through the rest state, and the
        largest distance of their points with σ₁ in :data:`MEASURED_STRETCH` from J = 1.
    """
    branches = {}
    distances = {}
    for ratio in ratios:
        material = Material(FixedCorotated(mu=1.0, lam=float(ratio)))
        rest = branches_through_rest(primary_contour(material, spacing=spacing), spacing=spacing)
        measured = _measured(rest)
        if not len(measured):
            raise RuntimeError(f"no fixed corotated contour traced for lambda/mu = {ratio:g}")
        branches[f"{ratio:g}"] = rest
        distances[f"{ratio:g}"] = float(distance_to_unit_volume(measured).max())
    return branches, distances


def _branch_summary(material, polylines, spacing) -> dict:
    rest = branches_through_rest(polylines, spacing=spacing)
    rest_ids = {id(polyline) for polyline in rest}
    points = np.concatenate(polylines)
    interior = np.concatenate([polyline[1:-1] for polyline in polylines])
    rest_points = np.concatenate(rest) if rest else np.empty((0, 2))
    return {
        "branches": len(polylines),
        "branches_through_rest": len(rest),
        "min_sigma2": float(points[:, 1].min()),
        "min_sigma2_through_rest": float(rest_points[:, 1].min()) if len(rest) else None,
        "max_sigma1_through_rest": float(rest_points[:, 0].max()) if len(rest) else None,
        # End points may be chord interpolations on the wedge boundary (near the rest state g
        # nearly vanishes and |v·g|/|g| means little there): the refined vertices are inside.
        "max_residual": float(contour_residual(material, interior).max()),
        "other_branches": [
            {
                "ends": [polyline[0].tolist(), polyline[-1].tolist()],
                "min_sigma2": float(polyline[:, 1].min()),
            }
            for polyline in polylines
            if id(polyline) not in rest_ids
        ],
    }


def _checks(materials, contours, spacing, artists, distances) -> dict:
    checks = {name: _branch_summary(materials[name], contours[name], spacing) for name in materials}

    corotated = checks["corotated"]
    points = np.concatenate(contours["corotated"])
    corotated["max_distance_from_sum_2"] = float(
        np.abs(points.sum(axis=1) - 2.0).max() / np.sqrt(2)
    )
    corotated["crosses_into_inverted"] = bool(corotated["min_sigma2"] < -_INVERTED)

    fixed = checks["fixed corotated"]
    fixed["enters_inverted"] = bool(fixed["min_sigma2"] < -_INVERTED)
    measured = _measured(branches_through_rest(contours["fixed corotated"], spacing=spacing))
    fixed["distance_to_J1"] = float(distance_to_unit_volume(measured).max())
    fixed["distance_to_J1_by_lambda_over_mu"] = distances

    for name in ("Neo-Hookean + C1", "Neo-Hookean + C2"):
        entry = checks[name]
        entry["branch_through_rest_enters_inverted"] = bool(
            entry["min_sigma2_through_rest"] < -_INVERTED
        )
        entry["enters_inverted"] = bool(entry["min_sigma2"] < -_INVERTED)

    deviation = 0.0
    for name, material in materials.items():
        quiver = artists[name]["quiver"]
        gradient = material.stress_sigma(np.column_stack([quiver.X, quiver.Y]))
        expected = -gradient / np.linalg.norm(gradient, axis=1, keepdims=True)
        drawn = np.column_stack([quiver.U, quiver.V])
        deviation = max(deviation, float(np.abs(drawn - expected).max()))
    checks["quiver_max_deviation_from_minus_gradient"] = deviation
    return checks


def _times_mu(factor: float) -> str:
    return "0" if factor == 0 else "μ" if factor == 1 else f"{factor:g}μ"


def _trajectory_summary(trajectories) -> dict:
    return {
        name: {
            "min_sigma2": values[..., 1].min(axis=1).tolist(),
            "final": values[:, -1].tolist(),
        }
        for name, values in trajectories.items()
    }


def load_scene_trajectories(directory) -> tuple[np.ndarray, Material, dict]:
    """Read a scene run's element trajectories and the material it ran with.

    Parameters
    ----------
    directory
        Output directory of a scene that writes ``trajectories.npy`` (``mattress-2d``,
        ``triangles-2d``), with its ``summary.json``.

    Returns
    -------
    (trajectories, material, summary)
        The array (elements × steps × 2, signed singular values in the IFE convention), the
        :class:`~dolfinx_invertible.Material` of the run's parameters and the run's summary.

    Raises
    ------
    ValueError
        A file is missing or the array has the wrong shape.
    """
    from dolfinx_invertible.scenes.parameters import Parameters, make_material

    directory = pathlib.Path(directory)
    path, summary_path = directory / "trajectories.npy", directory / "summary.json"
    for needed in (path, summary_path):
        if not needed.is_file():
            raise ValueError(
                f"{needed} does not exist: give the output directory of a mattress-2d or "
                f"triangles-2d run (python -m dolfinx_invertible run mattress-2d --out {directory})"
            )
    trajectories = np.load(path)
    if trajectories.ndim != 3 or trajectories.shape[2] != 2 or trajectories.shape[1] < 1:
        raise ValueError(
            f"{path} must hold elements × steps × 2 singular values, got shape {trajectories.shape}"
        )
    summary = json.loads(summary_path.read_text())
    material = make_material(Parameters(**summary["parameters"]))
    return trajectories, material, summary


def _scene_label(summary: dict) -> str:
    parameters = summary["parameters"]
    extension = "" if summary["extension"] == "none" else f" + {summary['extension'].upper()}"
    return f"{summary['scene']}: {summary['model']}{extension}, ν = {parameters['nu']:g}"


def _scene_figure(directories, spacing: float, title: str) -> tuple:
    """One panel per scene run: its material's contour and every element's trajectory."""
    runs = [load_scene_trajectories(directory) for directory in directories]
    figure = _new_figure(figsize=(5.6 * len(runs), 5.6))
    axes_list = np.atleast_1d(figure.subplots(1, len(runs)))
    summaries = []
    for axes, directory, (trajectories, material, summary) in zip(
        axes_list, directories, runs, strict=True
    ):
        plot_contours(axes, material, spacing=spacing, title=_scene_label(summary), legend=False)
        elements = len(trajectories)
        if elements <= len(_COLORS):
            overlay_trajectories(
                axes,
                trajectories,
                colors=_COLORS[:elements],
                labels=[f"element {index}" for index in range(elements)],
            )
        else:
            # Many elements: thin lines of one colour, without start and end markers.
            overlay_trajectories(
                axes,
                trajectories,
                colors=["tab:orange"] * elements,
                linewidth=0.5,
                markers=False,
            )
        axes.legend(loc="upper left", fontsize=7, framealpha=0.92)
        summaries.append(
            {
                "directory": str(directory),
                "scene": summary["scene"],
                "material": repr(material),
                "completed": summary.get("completed"),
                "elements": elements,
                "steps": int(trajectories.shape[1]),
                "min_sigma2": float(trajectories[..., 1].min()),
                "inverted_elements": int(np.count_nonzero(trajectories[..., 1].min(axis=1) < 0)),
            }
        )
    import textwrap

    # Wrapped to the figure's width (about 12 characters per inch at this size).
    figure.suptitle(textwrap.fill(title, width=int(12 * 5.6 * len(runs))), fontsize=11)
    return figure, summaries


def run(
    output_directory,
    *,
    quick: bool = False,
    mattress: Sequence | None = None,
    triangles: Sequence | None = None,
) -> dict:
    """Write the report's figures and return a JSON-ready summary with the analytic checks.

    Parameters
    ----------
    output_directory
        Directory for the PNG files (created if missing).
    quick
        A coarser tracing grid (spacing 0.04 instead of 0.01), shorter trajectories and
        figures at 60 instead of 100 dpi.
    mattress, triangles
        Output directories of ``mattress-2d`` or ``triangles-2d`` runs: their trajectories
        replace the computed stand-ins of the stretch (relaxation) figure, one panel per run,
        with the contour of the material it ran with.

    Returns
    -------
    dict
        ``figures`` (file names in ``output_directory``), ``materials``, ``spacing``,
        ``window``, ``checks`` (the analytic facts as numbers), ``stretch`` and ``relaxation``
        (per material and element: the smallest σ₂ and the end state; with scene data,
        ``scene_runs``: per run its material, element and step counts, smallest σ₂ and how many
        elements inverted) and ``seconds``.
    """
    begin = time.perf_counter()
    directory = pathlib.Path(output_directory)
    directory.mkdir(parents=True, exist_ok=True)
    spacing = 0.04 if quick else 0.01
    stretches = np.linspace(1.0, 3.5, 26 if quick else 101)
    steps, growth = (40, 1.12) if quick else (60, 1.08)
    # Drawing dominates the quick run.
    dpi = 60 if quick else 100

    materials = report_materials()
    contours = {name: primary_contour(m, spacing=spacing) for name, m in materials.items()}
    stretch = {name: stretch_trajectories(m, stretches=stretches) for name, m in materials.items()}
    relaxation = {
        name: relaxation_trajectories(m, RELAXATION_STARTS, steps=steps, growth=growth)
        for name, m in materials.items()
    }
    ratio_branches, distances = fixed_corotated_distances(spacing=spacing)

    figures = {
        "contours": "contours.png",
        "stretch": "contours_stretch.png",
        "relaxation": "contours_relaxation.png",
        "fixed_corotated": "contours_fixed_corotated.png",
    }
    figure, artists = _panels(
        materials,
        contours,
        spacing,
        f"Primary contours v·g = 0 in the singular-value plane, plane strain, ν = {POISSON_RATIO}"
        "\narrows: direction of −∇Ψ (unit length)",
    )
    figure.savefig(directory / figures["contours"], dpi=dpi)
    scene_runs = {}
    if mattress:
        figure, scene_runs["stretch"] = _scene_figure(
            list(mattress),
            spacing,
            "Mattress scene: every element's singular values over the "
            "load steps, on the primary contour of the run's material",
        )
    else:
        figure, _ = _panels(
            materials,
            contours,
            spacing,
            "Computed stand-in for the stretched mattress: single elements, σ₁ imposed 1 → 3.5,"
            "\nσ₂ at equilibrium with a lateral spring κ (κ = 0: free sides)",
            trajectories=stretch,
            labels=[f"stretch, κ = {_times_mu(factor)}" for factor in LATERAL_STIFFNESS],
        )
    figure.savefig(directory / figures["stretch"], dpi=dpi)
    if triangles:
        figure, scene_runs["relaxation"] = _scene_figure(
            list(triangles),
            spacing,
            "Triangles scene: the three triangles' singular values "
            "over time, on the primary contour of the run's material",
        )
    else:
        figure, _ = _panels(
            materials,
            contours,
            spacing,
            "Computed stand-in for the relaxing triangles: single free elements, implicit "
            "gradient flow\n(projected Newton per step) from three deformations",
            trajectories=relaxation,
            labels=[
                f"from ({start[0]:g}, {start[1]:g}){', inverted' if start[1] < 0 else ''}"
                for start in RELAXATION_STARTS
            ],
        )
    figure.savefig(directory / figures["relaxation"], dpi=dpi)
    _fixed_corotated_figure(ratio_branches, distances).savefig(
        directory / figures["fixed_corotated"], dpi=dpi
    )

    return {
        "figures": figures,
        "materials": {name: repr(material) for name, material in materials.items()},
        "spacing": spacing,
        "window": [list(WINDOW[0]), list(WINDOW[1])],
        "checks": _checks(materials, contours, spacing, artists, distances),
        "stretch": {"lateral_stiffness_over_mu": list(LATERAL_STIFFNESS)}
        | _trajectory_summary(stretch)
        | ({"scene_runs": scene_runs["stretch"]} if "stretch" in scene_runs else {}),
        "relaxation": {"starts": RELAXATION_STARTS.tolist()}
        | _trajectory_summary(relaxation)
        | ({"scene_runs": scene_runs["relaxation"]} if "relaxation" in scene_runs else {}),
        "seconds": time.perf_counter() - begin,
    }


# --- command line -------------------------------------------------------------------------------


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``report contours``."""
    add_output_arguments(
        parser,
        DEFAULT_OUTPUT,
        "coarser tracing grid, shorter trajectories, lower resolution (what the tests run)",
    )
    parser.add_argument(
        "--mattress",
        type=pathlib.Path,
        action="append",
        metavar="DIR",
        help="output directory of a mattress-2d run (with trajectories.npy): "
        "its element trajectories replace the stand-ins of the stretch figure "
        "(repeatable: one panel per run)",
    )
    parser.add_argument(
        "--triangles",
        type=pathlib.Path,
        action="append",
        metavar="DIR",
        help="output directory of a triangles-2d run: its trajectories replace "
        "the stand-ins of the relaxation figure (repeatable)",
    )


def command(arguments: argparse.Namespace) -> int:
    """Run ``report contours``; print the figures written."""
    try:
        result = run(
            arguments.out,
            quick=arguments.quick,
            mattress=arguments.mattress,
            triangles=arguments.triangles,
        )
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    for kind in ("stretch", "relaxation"):
        for entry in result[kind].get("scene_runs", []):
            print(
                f"{kind}: {entry['elements']} elements × {entry['steps']} steps from "
                f"{entry['directory']} ({entry['inverted_elements']} inverted on the way)"
            )
    print(
        f"wrote {arguments.out}/ ({', '.join(result['figures'].values())}) in "
        f"{result['seconds']:.1f} s"
    )
    return 0
