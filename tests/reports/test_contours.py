"""The primary-contour report: the analytic facts of the paper's §3.2 and the figures.

The references are independent of the tracer: closed-form contours (corotated σ₁ + σ₂ = 2,
fixed corotated's first-order offset from J = 1), closed-form equilibria of the stretched
corotated element and the closed-form corotated gradient. No DOLFINx.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from dolfinx_invertible.constitutive import (
    C2,
    Corotated,
    FixedCorotated,
    Material,
    NeoHookean,
    contours,
    lame,
)
from dolfinx_invertible.reports import contours as report

SPACING = 0.02


def _new_axes():
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure()
    FigureCanvasAgg(figure)
    return figure, figure.subplots()


def _largest_gap(polyline):
    return np.linalg.norm(np.diff(polyline, axis=0), axis=1).max()


def _neo_hookean_c2():
    mu, lam = lame(1.0e5, 0.45)
    return Material(NeoHookean(mu=mu, lam=lam), C2(eps=0.9))


# --- corotated: σ₁ + σ₂ = 2, through inversion ------------------------------------------------


@pytest.mark.parametrize("ratio", [1.0, 9.0, 50.0])
def test_corotated_contour_is_the_line_sum_two_and_crosses_into_inversion(ratio):
    material = Material(Corotated(mu=1.0, lam=ratio))
    polylines = contours.primary_contour(material, spacing=SPACING)
    assert len(polylines) == 1
    (line,) = polylines
    # v = (1, 1)/√2 everywhere and g is affine, so v·g is affine along every grid edge: the
    # crossings, refined or not, are on the line to round-off.
    distance = np.abs(line.sum(axis=1) - 2.0) / np.sqrt(2.0)
    assert distance.max() <= 1e-12
    # No gaps: consecutive vertices lie on edges of one grid cell.
    assert _largest_gap(line) <= np.sqrt(2.0) * SPACING * (1 + 1e-9)
    # It runs from the rest state to the window's lower edge, deep in the inverted half.
    ends = line[[0, -1]]
    assert np.min(np.linalg.norm(ends - 1.0, axis=1)) <= 2 * SPACING
    lowest = line[np.argmin(line[:, 1])]
    np.testing.assert_allclose(lowest, [3.5, -1.5], atol=1e-9)
    # It crosses σ₂ = 0 at σ₁ = 2, inside the canonical wedge.
    crossing = line[np.argmin(np.abs(line[:, 1]))]
    assert abs(crossing[1]) <= SPACING and abs(crossing[0] - 2.0) <= SPACING
    assert np.all(line[:, 0] >= np.abs(line[:, 1]) - 1e-12)


def test_corotated_kink_at_sum_zero_is_not_traced_as_a_contour():
    # Outside the wedge the canonical energy is Ψ̂(−σ): g jumps across σ₁ + σ₂ = 0, and so does
    # the sign of v·g (v = (1, 1)/√2 on both sides). The whole window's contour must still be
    # σ₁ + σ₂ = 2 alone (its mirror image σ₁ + σ₂ = −2 only touches the window's corner).
    material = Material(Corotated(mu=1.0, lam=9.0))
    polylines = contours.primary_contour(material, spacing=SPACING, canonical_only=False)
    assert len(polylines) == 1
    (line,) = polylines
    assert np.abs(line.sum(axis=1) - 2.0).max() <= 1e-9
    # Both mirror halves: from the upper window edge to the lower one.
    assert line[:, 1].max() == pytest.approx(2.5) and line[:, 1].min() == pytest.approx(-1.5)


# --- fixed corotated: J = 1 in the limit, never inverted --------------------------------------


def test_fixed_corotated_contour_stays_out_of_the_inverted_region_and_approaches_unit_volume():
    ratios = (1.0, 10.0, 100.0)
    branches, distances = report.fixed_corotated_distances(ratios, spacing=SPACING)
    values = [distances[f"{ratio:g}"] for ratio in ratios]
    # Decreasing towards 0, roughly like μ/λ.
    assert values[0] > 0.03
    assert values[1] < values[0] / 3 and values[2] < values[1] / 3
    assert values[2] < 2e-3
    for ratio in ratios:
        material = Material(FixedCorotated(mu=1.0, lam=ratio))
        polylines = contours.primary_contour(material, spacing=SPACING)
        # Every branch (the one through rest, and the diagonal σ₁ = σ₂ < 1/√2 where (1, −1) is
        # the stiffest direction) keeps σ₂ ≥ 0; the one through rest keeps J > 0.
        assert min(polyline[:, 1].min() for polyline in polylines) >= -1e-12
        (rest,) = branches[f"{ratio:g}"]
        assert rest[:, 1].min() > 0.2
        assert rest[:, 0].max() == pytest.approx(contours.WINDOW[0][1])


def test_fixed_corotated_offset_from_unit_volume_matches_first_order_theory():
    # On J = 1 + δ, v·g = 0 gives δ ≈ 2μ(σ₁ + σ₂ − 2) / (λ |σ|²) to first order in μ/λ.
    ratio = 100.0
    material = Material(FixedCorotated(mu=1.0, lam=ratio))
    (rest,) = contours.branches_through_rest(
        contours.primary_contour(material, spacing=SPACING), spacing=SPACING
    )
    points = rest[(rest[:, 0] >= 1.2) & (rest[:, 0] <= 3.0)]
    offset = points.prod(axis=1) - 1.0
    predicted = 2.0 * (points.sum(axis=1) - 2.0) / (ratio * (points**2).sum(axis=1))
    assert np.abs(offset - predicted).max() <= 0.03 * np.abs(predicted).max()


def test_fixed_corotated_diagonal_branch_ends_where_the_stiff_direction_switches():
    # On σ₁ = σ₂ = s the eigenvalues are 2μ + λ(1 − s²) along (1, −1) and 2μ + λ(3s² − 1)
    # along (1, 1); g lies along (1, 1), so the diagonal is primary exactly where the first is
    # larger: s < 1/√2.
    material = Material(FixedCorotated(mu=1.0, lam=9.0))
    polylines = contours.primary_contour(material, spacing=SPACING)
    diagonal = [p for p in polylines if np.abs(p[:, 0] - p[:, 1]).max() <= 1e-9]
    assert len(diagonal) == 1
    assert diagonal[0][:, 0].max() == pytest.approx(1 / np.sqrt(2), abs=SPACING)
    assert diagonal[0][:, 0].min() <= SPACING


def test_distance_to_unit_volume_against_dense_sampling():
    points = np.array([[1.0, 1.0], [2.0, 0.5], [0.0, 0.0], [2.0, 2.0], [3.0, 0.4], [1.5, -0.5]])
    t = np.geomspace(1e-3, 1e3, 2_000_001)
    dense = np.min(np.hypot(points[:, :1] - t, points[:, 1:] - 1.0 / t), axis=1)
    computed = contours.distance_to_unit_volume(points)
    # The sampling resolves the distance to about 1e-5.
    np.testing.assert_allclose(computed, dense, atol=2e-5)
    np.testing.assert_allclose(computed[[0, 1]], 0.0, atol=1e-12)
    assert computed[2] == pytest.approx(np.sqrt(2.0))


# --- the tracer itself ------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["Neo-Hookean + C1", "Neo-Hookean + C2", "fixed corotated"])
def test_tracing_does_not_depend_on_the_sign_of_the_eigenvectors(monkeypatch, name):
    material = report.report_materials()[name]
    reference = contours.primary_contour(material, spacing=SPACING)
    stiff_direction = contours._stiff_direction
    rng = np.random.default_rng(7)

    def random_signs(hessian):
        stiff = stiff_direction(hessian)
        return stiff * rng.choice([-1.0, 1.0], size=(len(stiff), 1))

    monkeypatch.setattr(contours, "_stiff_direction", random_signs)
    flipped = contours.primary_contour(material, spacing=SPACING)
    assert len(flipped) == len(reference)
    for a, b in zip(reference, flipped, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-12)


@pytest.mark.parametrize("offset", [1e-4, -1e-4])
def test_saddle_cells_connect_the_branches_of_the_same_hyperbola(monkeypatch, offset):
    # A synthetic field: H = diag(2, 1), so v = (1, 0), and g = (p, 1) with the bilinear
    # p = (σ₁ − a)(σ₂ − b) + offset. Its zero set is a hyperbola around the saddle (a, b), in
    # the quadrants where (σ₁ − a)(σ₂ − b) has the sign of −offset. In the grid cell that
    # holds the saddle the four corners alternate in sign, and the mean of the corners has the
    # wrong sign for offset < 0: only the interpolant's value at the saddle tells which
    # corners the branches cut off.
    a, b = 1.03, 0.97

    def derivatives(material, points):
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        p = (points[:, 0] - a) * (points[:, 1] - b) + offset
        gradient = np.column_stack([p, np.ones(len(points))])
        return gradient, np.tile(np.diag([2.0, 1.0]), (len(points), 1, 1))

    monkeypatch.setattr(contours, "energy_derivatives", derivatives)
    material = Material(Corotated(mu=1.0, lam=1.0))  # not evaluated
    polylines = contours.primary_contour(
        material, window=((0.0, 2.0), (0.0, 2.0)), spacing=0.1, canonical_only=False
    )
    assert len(polylines) == 2
    for polyline in polylines:
        product = (polyline[:, 0] - a) * (polyline[:, 1] - b)
        np.testing.assert_allclose(product, -offset, atol=1e-12)
        # Each branch stays in its quadrant.
        assert np.all(np.sign(polyline[:, 0] - a) == np.sign(polyline[0, 0] - a))


def test_stiffest_direction_is_by_eigenvalue_magnitude():
    # Neo-Hookean on the diagonal σ = (s, s): g lies along (1, 1) and the eigenvalues are
    # μ + (μ + 2λ − 2λ ln s)/s² along (1, 1) and μ + (μ − 2λ ln s)/s² along (1, −1). The
    # second turns negative and exceeds the first in magnitude past ln s = (μs² + μ + λ)/(2λ):
    # from there on the diagonal is primary.
    mu, lam = lame(1.0e5, 0.45)
    low, high = 1.5, 4.0
    for _ in range(100):
        middle = 0.5 * (low + high)
        if np.log(middle) < (mu * middle**2 + mu + lam) / (2 * lam):
            low = middle
        else:
            high = middle
    window = ((-0.5, 3.5), (-1.5, 3.5))
    polylines = contours.primary_contour(_neo_hookean_c2(), window=window, spacing=SPACING)
    diagonal = [p for p in polylines if np.abs(p[:, 0] - p[:, 1]).max() <= 1e-9]
    assert len(diagonal) == 1
    assert diagonal[0][:, 0].min() == pytest.approx(low, abs=SPACING)
    assert diagonal[0][:, 0].max() == pytest.approx(3.5)


# --- Neo-Hookean + C2 -------------------------------------------------------------------------


def test_neo_hookean_c2_contour_through_rest_never_enters_the_inverted_region():
    material = _neo_hookean_c2()
    window = ((-0.5, 8.0), (-1.5, 2.5))
    polylines = contours.primary_contour(material, window=window, spacing=0.04)
    rest = contours.branches_through_rest(polylines, spacing=0.04)
    assert len(rest) == 1
    (branch,) = rest
    # Traced all the way to σ₁ = 8 without a gap, staying at J > 0.
    assert branch[:, 0].max() == pytest.approx(8.0)
    assert _largest_gap(branch) <= np.sqrt(2.0) * 0.04 * (1 + 1e-9)
    assert branch[:, 1].min() > 0.0
    assert np.all(branch.prod(axis=1) > 0.0)


def test_neo_hookean_c2_inverted_branch_is_separate_and_starts_at_repeated_eigenvalues():
    # The zero set of v·g also has a branch inside the inverted region that does not reach
    # the rest state: it starts where the two eigenvalues of H cross (v turns by 90° there).
    material = _neo_hookean_c2()
    polylines = contours.primary_contour(material, spacing=0.01)
    inverted = [p for p in polylines if p[:, 1].max() < 0.0]
    assert len(inverted) == 1
    (branch,) = inverted
    start = branch[np.argmax(branch[:, 1])]
    values = np.linalg.eigvalsh(material.hessian_sigma(start))
    assert abs(values[1] - values[0]) <= 0.01 * abs(values[1])
    far = branch[np.argmin(branch[:, 1])]
    values = np.linalg.eigvalsh(material.hessian_sigma(far))
    assert abs(values[1] - values[0]) >= 0.3 * abs(values[1])
    assert np.all(contours.contour_residual(material, branch) <= contours.PRIMARY_TOLERANCE)


# --- trajectories -----------------------------------------------------------------------------


def test_stretched_corotated_element_matches_closed_form_equilibrium():
    mu, lam = 1.0, 9.0
    material = Material(Corotated(mu=mu, lam=lam))
    stretches = np.linspace(1.0, 3.5, 11)
    trajectories = report.stretch_trajectories(
        material, stretches=stretches, lateral_stiffness=(0.0, 4.0)
    )
    assert trajectories.shape == (2, 11, 2)
    for element, kappa in enumerate((0.0, 4.0 * mu)):
        # ∂/∂σ₂ [μ Σ(σᵢ − 1)² + λ/2 (σ₁ + σ₂ − 2)² + κ/2 (σ₂ − 1)²] = 0.
        lateral = (2 * mu + 2 * lam + kappa - lam * stretches) / (2 * mu + lam + kappa)
        np.testing.assert_allclose(trajectories[element, :, 0], stretches, atol=1e-12)
        np.testing.assert_allclose(trajectories[element, :, 1], lateral, atol=1e-9)
    assert trajectories[0, -1, 1] < 0.0  # stretched corotated elements invert


def test_relaxing_elements_reach_the_contour_first_then_rest():
    # The stiff mode relaxes first: a stretched corotated element reaches σ₁ + σ₂ = 2 long
    # before it reaches the rest state, then slides along the line.
    material = Material(Corotated(mu=1.0, lam=9.0))
    trajectories = report.relaxation_trajectories(material, np.array([[2.6, -0.9], [3.4, 1.7]]))
    assert trajectories.shape == (2, 61, 2)
    assert np.all(trajectories[..., 0] >= np.abs(trajectories[..., 1]))
    for path in trajectories:
        off_line = np.abs(path.sum(axis=1) - 2.0)
        from_rest = np.linalg.norm(path - 1.0, axis=1)
        settled = np.argmax(off_line < 0.02 * off_line[0])
        assert 0 < settled and from_rest[settled] > 0.3 * from_rest[0]
        np.testing.assert_allclose(path[-1], [1.0, 1.0], atol=1e-3)
    # The inverted start comes back through σ₂ = 0.
    assert trajectories[0, 0, 1] < 0.0 < trajectories[0, -1, 1]


# --- figures ----------------------------------------------------------------------------------


def test_quiver_arrows_are_minus_the_gradient():
    mu, lam = 2.0, 7.0
    corotated = Material(Corotated(mu=mu, lam=lam))
    for material in (corotated, _neo_hookean_c2()):
        figure, axes = _new_axes()
        drawn = report.plot_contours(axes, material, spacing=0.05)
        quiver = drawn["quiver"]
        points = np.column_stack([quiver.X, quiver.Y])
        assert len(points) > 50
        assert np.all(points[:, 0] > np.abs(points[:, 1]))
        gradient = material.stress_sigma(points)
        if material is corotated:
            # Closed form: g = 2μ(σ − 1) + λ(σ₁ + σ₂ − 2).
            closed = 2 * mu * (points - 1.0) + lam * (points.sum(axis=1, keepdims=True) - 2.0)
            np.testing.assert_allclose(gradient, closed, rtol=1e-12, atol=1e-12)
        expected = -gradient / np.linalg.norm(gradient, axis=1, keepdims=True)
        np.testing.assert_allclose(np.column_stack([quiver.U, quiver.V]), expected, atol=1e-12)
        assert drawn["contour"]["rest"]


def test_overlay_draws_each_trajectory_and_validates_its_input():
    figure, axes = _new_axes()
    trajectories = np.array(
        [[[1.0, 1.0], [2.0, 0.5], [3.0, -0.2]], [[1.2, 0.9], [1.1, 0.95], [1.0, 1.0]]]
    )
    lines = report.overlay_trajectories(axes, trajectories, labels=["a", "b"])
    assert len(lines) == 2
    np.testing.assert_array_equal(np.column_stack(lines[0].get_data()), trajectories[0])
    assert [line.get_label() for line in lines] == ["a", "b"]
    with pytest.raises(ValueError, match="shape"):
        report.overlay_trajectories(axes, trajectories[0])
    with pytest.raises(ValueError, match="IFE convention"):
        report.overlay_trajectories(axes, trajectories[:, :, ::-1])
    with pytest.raises(ValueError, match="non-finite"):
        report.overlay_trajectories(axes, np.where(trajectories > 2.5, np.nan, trajectories))
    with pytest.raises(ValueError, match="labels"):
        report.overlay_trajectories(axes, trajectories, labels=["a"])


def test_bad_tracing_input_is_rejected():
    material = Material(Corotated(mu=1.0, lam=1.0))
    with pytest.raises(ValueError, match="window"):
        contours.primary_contour(material, window=((1.0, 0.0), (0.0, 1.0)))
    with pytest.raises(ValueError, match="window"):
        contours.primary_contour(material, window=(0.0, 1.0))
    with pytest.raises(ValueError, match="spacing"):
        contours.primary_contour(material, spacing=0.0)
    with pytest.raises(ValueError, match="coarser"):
        contours.primary_contour(material, spacing=1e-4)


def test_run_writes_the_figures_and_a_json_summary(tmp_path):
    summary = report.run(tmp_path, quick=True)
    json.dumps(summary)
    assert set(summary["figures"]) == {"contours", "stretch", "relaxation", "fixed_corotated"}
    for name in summary["figures"].values():
        data = (tmp_path / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
    checks = summary["checks"]
    assert checks["corotated"]["crosses_into_inverted"]
    assert checks["corotated"]["max_distance_from_sum_2"] <= 1e-9
    assert not checks["fixed corotated"]["enters_inverted"]
    assert not checks["Neo-Hookean + C2"]["branch_through_rest_enters_inverted"]
    distances = list(checks["fixed corotated"]["distance_to_J1_by_lambda_over_mu"].values())
    assert distances == sorted(distances, reverse=True)
    assert checks["quiver_max_deviation_from_minus_gradient"] <= 1e-12
    # The stretched corotated element inverts; the others do not.
    assert min(summary["stretch"]["corotated"]["min_sigma2"]) < 0.0
    assert min(summary["stretch"]["fixed corotated"]["min_sigma2"]) > 0.0
