"""Primary contours of a material in the 2D singular-value plane (Stomakhin et al. 2012, §3.2).

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
canonical wedge elsewhere; by default the polylines are clipped to the wedge.

The primary-contour report (:mod:`dolfinx_invertible.reports.contours`) draws them for the
paper's Figs. 1–2.
"""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.constitutive.material import Material

__all__ = [
    "PRIMARY_TOLERANCE",
    "REST",
    "WINDOW",
    "branches_through_rest",
    "check_window",
    "contour_residual",
    "distance_to_unit_volume",
    "energy_derivatives",
    "primary_contour",
]

#: Default window ((σ₁ min, σ₁ max), (σ₂ min, σ₂ max)): the canonical wedge σ₁ ≥ |σ₂| up to a
#: stretch of 4, with its apex and part of the invalid region.
WINDOW = ((-0.5, 4.0), (-1.5, 2.5))

#: |v·g| / |g| at or below which a refined crossing is on the primary contour.
PRIMARY_TOLERANCE = 1e-6

#: The rest state σ = (1, 1), through which every primary contour passes.
REST = np.array([1.0, 1.0])

_REFINE_ITERATIONS = 60
# 1 − 1/golden ratio: far from every simple fraction.
_GRID_SHIFT = 0.3819660112501051


# --- evaluation -------------------------------------------------------------------------------


def check_window(window) -> tuple[tuple[float, float], tuple[float, float]]:
    """Return a window ((σ₁ min, σ₁ max), (σ₂ min, σ₂ max)) as floats, or raise ValueError."""
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


def energy_derivatives(material: Material, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
    gradient, hessian = energy_derivatives(material, points)
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
    gradient, hessian = energy_derivatives(material, points)
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
    window = check_window(window)
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
        if np.min(np.linalg.norm(polyline - REST, axis=1)) <= reach
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
