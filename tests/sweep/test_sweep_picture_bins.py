"""Sweep pictures at any size (issue 35.0): at most 400 binned cells whatever the variants."""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
import pytest

from vei.sweep.riskmap import (
    MAX_BINS_PER_AXIS,
    grid_edges,
    sweep_probability_map,
    sweep_risk_map,
    sweep_severity_maps,
    wilson_interval,
    wilson_intervals,
)
from vei.sweep.spec import spec_from_dict


def test_grid_edges_one_cell_per_value_up_to_the_cap_then_equal_cells_by_hand():
    # 5 values 0, 1, 2, 3, 4: one cell each, edges half a step beyond the ends
    np.testing.assert_allclose(grid_edges(np.arange(5.0)), [-0.5, 0.5, 1.5, 2.5, 3.5, 4.5])
    # 100 values 0..99 (step 1): 20 cells over [-0.5, 99.5], 5 values each
    e = grid_edges(np.arange(100.0))
    assert len(e) == MAX_BINS_PER_AXIS + 1 == 21
    np.testing.assert_allclose(e, -0.5 + 5.0 * np.arange(21))
    counts, _ = np.histogram(np.arange(100.0), bins=e)
    assert counts.tolist() == [5] * 20


def test_wilson_intervals_equal_the_scalar_form():
    p = np.array([0.0, 0.1, 0.5, 1.0, 0.33, 0.2])
    n = np.array([1.0, 10.0, 100.0, 7.0, 12.4, 0.3])
    lo, hi = wilson_intervals(p, n)
    for i in range(len(p)):
        k = max(1, int(round(n[i])))
        assert (lo[i], hi[i]) == pytest.approx(wilson_interval(int(round(p[i] * k)), k))
    # by hand: 0 of 10 -> [0, z^2 / (10 + z^2)] = [0, 0.2775]
    lo, hi = wilson_intervals(np.array([0.0]), np.array([10.0]))
    assert lo[0] == 0.0 and hi[0] == pytest.approx(1.959964**2 / (10 + 1.959964**2), rel=1e-5)


def _grid(n_t: int, n_v: int) -> tuple[pd.DataFrame, object]:
    spec = spec_from_dict(
        {
            "design": "grid",
            "parameters": {
                "time_shift_s": {"min": -3.0, "max": 3.0, "num": n_t},
                "ego.cruise_speed_mps": {"min": 3.0, "max": 9.0, "num": n_v},
            },
        }
    )
    t, v = np.meshgrid(np.linspace(-3, 3, n_t), np.linspace(3, 9, n_v), indexing="ij")
    t, v = t.ravel(), v.ravel()
    collision = v > 6.0 + 0.5 * t  # a known boundary
    df = pd.DataFrame({
        "variant_id": np.arange(t.size).astype(str), "scenario_id": "s",
        "time_shift_s": t, "ego.cruise_speed_mps": v, "collision": collision,
        "safety_index": np.where(collision, 0.0, 1.0), "injury_risk": np.where(collision, 0.3, 0.0),
        "impact_speed_mps": np.where(collision, 5.0, np.nan), "seen_too_late": False,
    })  # fmt: skip
    return df, spec


def test_a_large_grid_is_drawn_from_at_most_400_cells_of_whole_grid_values(tmp_path):
    # 2,000 time shifts x 40 speeds = 80,000 variants: 20 cells of 100 time shifts x 20
    # cells of 2 speeds, 200 variants in every cell (by hand)
    df, spec = _grid(2000, 40)
    t0 = time.perf_counter()
    risk = sweep_risk_map(df, spec, tmp_path / "riskmap.png")
    prob = sweep_probability_map(df, spec, tmp_path / "probability_map.png")
    maps = sweep_severity_maps(df, spec, tmp_path)
    took = time.perf_counter() - t0
    assert risk["binned"]["count"].shape == (20, 20)
    assert (risk["binned"]["count"] == 200).all()
    g = prob["grid"]
    assert g["p"].shape == (20, 20) and np.allclose(g["n"], 200)
    # the cells' centres: the middle of their 100 time shifts / 2 speeds
    dt = 6.0 / 1999
    np.testing.assert_allclose(g["x_centres"][0], -3.0 + 49.5 * dt)
    np.testing.assert_allclose(g["y_centres"][0], 3.0 + 0.5 * 6.0 / 39)
    # a cell's P is its variants' collision share: far from the boundary 0 or 1, known
    assert g["p"][0, -1] == 0.0 and g["known"][0, -1]  # slow ego, late rider: no collision
    assert g["p"][-1, 0] == 1.0 and g["known"][-1, 0]
    assert list(maps) == [""] and (tmp_path / "severity_map.png").stat().st_size > 10_000
    # the known P = 0 cells are drawn green (ZERO_COLOUR), not a near-white red or grey
    from PIL import Image

    from vei.report.riskmap import ZERO_COLOUR

    img = np.asarray(Image.open(tmp_path / "probability_map.png").convert("RGB"), dtype=int)
    green = np.array([int(ZERO_COLOUR[k : k + 2], 16) for k in (1, 3, 5)])
    n_zero_cells = int((g["known"] & (g["p"] == 0)).sum())
    assert n_zero_cells > 50
    assert (np.abs(img - green).sum(axis=2) < 10).sum() > 50 * n_zero_cells  # pixels of them
    assert took < 60  # drawn from 400 cells (before issue 35: one hatched cell per value)


def test_share_map_bins_many_design_points(tmp_path):
    from vei.report.uncertainty import MAX_CELLS_PER_AXIS, _binned_share

    # 100 x 3 design points: x is binned into 20 cells of 5, y keeps its 3 values
    x, y = np.meshgrid(np.arange(100.0), [1.0, 2.0, 3.0], indexing="ij")
    share = (x.ravel() >= 50).astype(float)
    pp = pd.DataFrame({"a": x.ravel(), "b": y.ravel(), "collision_share": share})
    xc, yc, mean = _binned_share(pp, "a", "b")
    assert len(xc) == MAX_CELLS_PER_AXIS and yc.tolist() == [1.0, 2.0, 3.0]
    # edges linspace(0, 99, 21): the cell [49.5, 54.45) holds 50..54 -> share 1; [44.55, 49.5)
    # holds 45..49 -> 0
    assert mean.shape == (3, 20) and mean[:, 10].tolist() == [1.0] * 3
    assert mean[:, 9].tolist() == [0.0] * 3
