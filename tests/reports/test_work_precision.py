"""The work-precision helpers on made-up rows: errors, orders, cheapest runs, CSV. No DOLFINx."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from dolfinx_invertible.reports.error_vs_time import work_precision


def test_relative_errors_by_hand():
    reference = np.array([[3.0, 4.0], [0.0, 0.0]])
    values = np.array([[3.0, 4.0], [0.0, 1.0]])
    l2, largest = work_precision.relative_errors(values, reference)
    assert l2 == pytest.approx(1.0 / 5.0)
    # The largest point error (1) over the largest reference magnitude (5).
    assert largest == pytest.approx(1.0 / 5.0)
    values = np.array([[6.0, 8.0], [0.0, 0.0]])
    assert work_precision.relative_errors(values, reference) == pytest.approx((1.0, 1.0))
    with pytest.raises(ValueError, match="shape"):
        work_precision.relative_errors(values[:1], reference)
    with pytest.raises(ValueError, match="all zero"):
        work_precision.relative_errors(values, np.zeros_like(reference))


@pytest.mark.parametrize("order", [0.5, 1.0, 2.0, 3.0])
def test_observed_order_of_an_exact_power_law(order):
    sizes = [0.1 / 2**k for k in range(5)]
    errors = [7.0 * size**order for size in sizes]
    fit = work_precision.observed_order(sizes, errors)
    assert fit["order"] == pytest.approx(order, rel=1e-12)
    assert fit["finest_pair"] == pytest.approx(order, rel=1e-12)
    assert fit["points"] == 5
    assert fit["sizes"] == pytest.approx([sizes[-1], sizes[0]])


def test_observed_order_leaves_out_unusable_points():
    sizes = [0.4, 0.2, 0.1, 0.05, 0.025]
    errors = [0.16, None, math.nan, 0.0025, 0.0]
    fit = work_precision.observed_order(sizes, errors)
    assert fit["points"] == 2
    assert fit["order"] == pytest.approx(2.0)
    assert math.isnan(work_precision.observed_order([0.1], [0.01])["order"])
    assert math.isnan(work_precision.observed_order([0.1, 0.1], [0.01, 0.02])["order"])


def test_cheapest_takes_the_fastest_run_within_the_target():
    rows = [
        {"name": "a", "completed": True, "error": 0.02, "wall_time_s": 1.0},
        {"name": "b", "completed": True, "error": 0.009, "wall_time_s": 5.0},
        {"name": "c", "completed": True, "error": 0.0005, "wall_time_s": 3.0},
        {"name": "d", "completed": False, "error": 0.0001, "wall_time_s": 0.1},
        {"name": "e", "completed": True, "error": None, "wall_time_s": 0.1},
        {"name": "f", "completed": True, "error": math.nan, "wall_time_s": 0.1},
    ]
    assert work_precision.cheapest(rows, 1e-2)["name"] == "c"
    assert work_precision.cheapest(rows, 1e-3)["name"] == "c"
    assert work_precision.cheapest(rows, 1e-4) is None
    rows[1]["time_error"] = 1e-6
    assert work_precision.cheapest(rows, 1e-5, error="time_error")["name"] == "b"


def test_csv_keeps_the_columns_and_leaves_missing_values_empty(tmp_path):
    path = tmp_path / "rows.csv"
    rows = [{"a": 1.234567891, "b": None, "c": "x"}, {"a": math.inf, "c": "y", "extra": 3}]
    work_precision.write_csv(path, rows, ["a", "b", "c"])
    with open(path) as stream:
        read = list(csv.DictReader(stream))
    assert read == [{"a": "1.23457", "b": "", "c": "x"}, {"a": "", "b": "", "c": "y"}]


def test_plot_draws_one_line_per_curve_in_sweep_order(tmp_path, monkeypatch):
    drawn = []
    from matplotlib.axes import Axes

    original = Axes.loglog

    def record(self, *args, **kwargs):
        drawn.append((kwargs.get("label"), list(args[0]), list(args[1])))
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Axes, "loglog", record)
    rows = [
        {"curve": "A", "sweep": "resolution", "resolution": r, "h": 1 / r, "completed": True,
         "error": 1.0 / r**2, "wall_time_s": t}
        for r, t in ((2, 0.3), (4, 0.2), (8, 0.9))
    ] + [{"curve": "B", "sweep": "resolution", "resolution": 2, "h": 0.5, "completed": False,
          "error": 0.1, "wall_time_s": 0.1}]  # fmt: skip
    panels = [
        {"x": "wall_time_s", "error": "error", "xlabel": "t", "ylabel": "e", "title": "w"},
        {"x": "h", "error": "error", "xlabel": "h", "ylabel": "e", "title": "s", "slopes": True},
    ]
    work_precision.plot_study(tmp_path / "f.png", rows, title="t", panels=panels, dpi=40)
    assert (tmp_path / "f.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # The failed curve B is not drawn; A follows its resolutions, not its wall times.
    assert [entry[0] for entry in drawn] == ["A", "A (order 2.00)"]
    assert drawn[0][1] == [0.3, 0.2, 0.9]
    assert drawn[1][1] == [0.5, 0.25, 0.125]
