"""Critical-boundary search against oracles whose boundary is known analytically."""

from __future__ import annotations

import numpy as np
import pytest

from vei.errors import ConfigError
from vei.experiments.boundary import (
    adaptive_boundary,
    binned_risk,
    lattice_segments,
    share_boundary,
)

A, C = 0.7, 0.3  # collision iff y > A x + C


def line_oracle(points):
    x, y = points[:, 0], points[:, 1]
    return {"collision": y > A * x + C, "margin": y - (A * x + C)}


def _dist_to_line(p):
    return np.abs(p[:, 1] - A * p[:, 0] - C) / np.hypot(A, 1.0)


def test_recovers_a_line_with_far_fewer_evaluations_than_the_grid():
    res = adaptive_boundary(line_oracle, (-3.0, 3.0), (-4.0, 4.0), coarse=(9, 9), levels=4)
    dx = res.x_values[1] - res.x_values[0]
    dy = res.y_values[1] - res.y_values[0]
    assert len(res.x_values) == 8 * 16 + 1 and len(res.y_values) == 129
    assert res.grid_evaluations == 129 * 129
    # every crossing lies within half a finest cell of the true line
    assert len(res.crossings) > 100
    assert _dist_to_line(res.crossings).max() <= 0.5 * max(dx, dy) + 1e-12
    # the segments cover the line across the box: x from one side to the other
    seg = res.segments.reshape(-1, 2)
    assert _dist_to_line(seg).max() <= 0.5 * max(dx, dy) + 1e-12
    inside = (A * res.x_values + C > -4.0) & (A * res.x_values + C < 4.0)
    assert seg[:, 0].min() <= res.x_values[inside].min() + dx
    assert seg[:, 0].max() >= res.x_values[inside].max() - dx
    # adaptive: an order of magnitude fewer evaluations than the same-resolution grid
    assert res.n_evaluations == len(res.samples)
    assert res.n_evaluations < res.grid_evaluations / 10
    # no lattice point is evaluated twice; labels are the oracle's
    assert not res.samples[["i", "j"]].duplicated().any()
    assert (res.samples["collision"] == (res.samples["margin"] > 0)).all()
    assert set(res.samples["level"]) == {0, 1, 2, 3, 4}


def test_each_crossing_sits_between_a_colliding_and_a_safe_sample():
    res = adaptive_boundary(line_oracle, (-1.0, 1.0), (-1.0, 1.5), coarse=(5, 5), levels=3)
    s = res.samples
    pts = s[["x", "y"]].to_numpy()
    hx = res.x_values[1] - res.x_values[0]
    hy = res.y_values[1] - res.y_values[0]
    for p in res.crossings:
        d = np.abs(pts - p)
        # lattice neighbours of the crossing: its edge's two end points
        near = (d[:, 0] <= hx / 2 + 1e-9) & (d[:, 1] <= hy / 2 + 1e-9)
        assert near.sum() == 2
        assert set(s["collision"][near]) == {True, False}


def test_levels_zero_is_the_coarse_grid_and_refinement_improves_accuracy():
    errs = []
    for levels in (0, 2, 4):
        res = adaptive_boundary(line_oracle, (-3.0, 3.0), (-4.0, 4.0), coarse=(5, 5), levels=levels)
        if levels == 0:
            assert res.n_evaluations == 25 == res.grid_evaluations
        errs.append(_dist_to_line(res.crossings).max())
    assert errs[0] > errs[1] > errs[2]


def test_circle_boundary_closed_curve():
    r0 = 1.2

    def disc(p):
        return {"collision": np.hypot(p[:, 0], p[:, 1]) < r0}

    res = adaptive_boundary(disc, (-2.0, 2.0), (-2.0, 2.0), coarse=(9, 9), levels=4)
    h = res.x_values[1] - res.x_values[0]
    r = np.hypot(res.crossings[:, 0], res.crossings[:, 1])
    assert np.abs(r - r0).max() <= h / 2 + 1e-9
    # the boundary is closed: every segment end point is shared by exactly two segments
    ends = np.round(res.segments.reshape(-1, 2), 9)
    _, counts = np.unique(ends, axis=0, return_counts=True)
    assert (counts == 2).all()
    assert res.n_evaluations < res.grid_evaluations / 5


def test_lattice_segments_hand_case_and_score_interpolation():
    # 2 x 2 lattice, only the top-right corner collides
    label = np.array([[0, 0], [0, 1]], dtype=np.int8)  # [j, i]
    seg, crs = lattice_segments(label, np.array([0.0, 1.0]), np.array([0.0, 2.0]))
    assert seg.shape == (1, 2, 2)
    assert sorted(map(tuple, crs)) == [(0.5, 2.0), (1.0, 1.0)]
    score = np.array([[0.0, 0.0], [0.0, 1.0]])
    seg2, crs2 = lattice_segments(
        label, np.array([0.0, 1.0]), np.array([0.0, 2.0]), score=score, threshold=0.25
    )
    assert sorted(map(tuple, crs2)) == [(0.25, 2.0), (1.0, 0.5)]
    # an unevaluated corner: no segment
    seg3, _ = lattice_segments(
        np.array([[0, -1], [0, 1]], dtype=np.int8), np.arange(2.0), np.arange(2.0)
    )
    assert seg3.shape == (0, 2, 2)


def test_binned_risk_and_share_boundary():
    x = np.array([0.1, 0.2, 0.6, 0.7, 0.1, 0.9])
    y = np.array([0.1, 0.2, 0.1, 0.3, 0.8, 0.9])
    col = np.array([False, True, True, True, False, True])
    val = np.array([1.0, 0.0, 0.0, 0.0, 0.8, 0.0])
    b = binned_risk(x, y, col, val, np.array([0.0, 0.5, 1.0]), np.array([0.0, 0.5, 1.0]))
    assert b["count"].tolist() == [[2, 2], [1, 1]]
    assert b["collision_share"][0].tolist() == pytest.approx([0.5, 1.0])
    assert b["collision_share"][1].tolist() == pytest.approx([0.0, 1.0])
    assert b["value"][0].tolist() == pytest.approx([0.5, 0.0])
    seg, crs = share_boundary(b)
    # labels (share >= 0.5): [[1, 1], [0, 1]] -> one segment through the lower-left cell
    assert seg.shape == (1, 2, 2)
    # crossing on the left edge: share 0.5 at y=0.25, 0.0 at y=0.75 -> exactly at y=0.25
    assert (0.25, 0.25) in set(map(tuple, np.round(crs, 12)))


def test_bad_arguments():
    with pytest.raises(ConfigError, match="coarse"):
        adaptive_boundary(line_oracle, (0, 1), (0, 1), coarse=(1, 5))
    with pytest.raises(ConfigError, match="min < max"):
        adaptive_boundary(line_oracle, (1, 0), (0, 1))
    with pytest.raises(ConfigError, match="collision"):
        adaptive_boundary(lambda p: {"x": p[:, 0]}, (0, 1), (0, 1), coarse=(2, 2), levels=0)


# ----------------------------------------------------------------------------- engine


@pytest.fixture(scope="module")
def demo_scenario(tmp_path_factory):
    """The synthetic demo interaction, reconstructed into a scenario folder."""
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


@pytest.mark.slow
def test_search_boundary_on_the_demo_scenario(demo_scenario, tmp_path):
    import json

    import pandas as pd

    from vei.config import RunConfig, load_config
    from vei.experiments.boundary import search_boundary
    from vei.io.scenario import read_scenario
    from vei.metrics import summarize
    from vei.sim.engine import simulate
    from vei.sim.state import VariantParams, prepare_scenario
    from vei.sweep.spec import spec_from_dict

    spec = spec_from_dict(
        {
            "design": "grid",
            "base": "normal",
            "parameters": {
                "time_shift_s": {"min": -3.0, "max": 3.0, "num": 5},
                "ego.cruise_speed_mps": {"min": 3.0, "max": 9.0, "num": 5},
                "ego.policy": "none",
            },
        }
    )
    out = tmp_path / "b"
    res = search_boundary(
        demo_scenario,
        spec,
        "time_shift_s",
        "ego.cruise_speed_mps",
        out,
        coarse=(5, 5),
        levels=2,
        k_critical=6,
        progress=False,
    )
    s = res.samples
    assert res.grid_evaluations == 17 * 17
    assert res.n_evaluations < res.grid_evaluations
    assert 0 < s["collision"].sum() < len(s)
    assert (s["time_shift_s"] == s["x"]).all() and (s["ego.cruise_speed_mps"] == s["y"]).all()
    assert (s["ego.policy"] == "none").all()
    # every crossing sits on a lattice edge between a colliding and a safe sample
    key = {
        (int(i), int(j)): bool(c) for i, j, c in zip(s["i"], s["j"], s["collision"], strict=True)
    }
    hx = res.x_values[1] - res.x_values[0]
    hy = res.y_values[1] - res.y_values[0]
    assert len(res.crossings) > 5
    for px, py in res.crossings:
        fi = (px - res.x_values[0]) / hx
        fj = (py - res.y_values[0]) / hy
        if abs(fi - round(fi)) < 1e-6:  # vertical edge
            i, j = round(fi), int(np.floor(fj))
            assert key[(i, j)] != key[(i, j + 1)]
        else:
            i, j = int(np.floor(fi)), round(fj)
            assert key[(i, j)] != key[(i + 1, j)]
    doc = json.loads((out / "boundary.json").read_text())
    assert doc["n_evaluations"] == res.n_evaluations and len(doc["segments"]) == len(res.segments)
    crit = pd.read_csv(out / "critical.csv")
    assert len(crit) == 6 and list(crit.columns[:4]) == [
        "variant_id",
        "scenario_id",
        "variant_index",
        "seed",
    ]
    assert (out / "riskmap.png").stat().st_size > 10_000
    # each critical variant's config file reproduces its outcome
    arrays = prepare_scenario(read_scenario(demo_scenario))
    for vid in crit["variant_id"][:3]:
        cfg = load_config(out / "configs" / f"{vid}.yaml", RunConfig)
        row = s[s["variant_id"] == vid].iloc[0]
        p = VariantParams.from_case(cfg.case, arrays, 1, time_shift_s=cfg.time_shift)
        again = summarize(simulate(arrays, p).to_trace())
        assert bool(again["collision"][0]) == bool(row["collision"])
        assert again["safety_index"][0] == pytest.approx(row["safety_index"], abs=1e-12)


def test_search_boundary_rejects_a_varying_third_parameter(demo_scenario, tmp_path):
    from vei.experiments.boundary import search_boundary
    from vei.sweep.spec import spec_from_dict

    spec = spec_from_dict(
        {
            "design": "grid",
            "parameters": {
                "time_shift_s": {"min": -1.0, "max": 1.0, "num": 2},
                "rider_model": {"choices": ["normal", "aggressive"]},
            },
        }
    )
    with pytest.raises(ConfigError, match="rider_model"):
        search_boundary(
            demo_scenario,
            spec,
            "time_shift_s",
            "ego.cruise_speed_mps",
            tmp_path,
            y_range=(3.0, 9.0),
        )
    with pytest.raises(ConfigError, match="float parameter"):
        search_boundary(demo_scenario, spec, "time_shift_s", "rider_model", tmp_path)
    with pytest.raises(ConfigError, match="needs a range"):
        search_boundary(
            demo_scenario,
            spec_from_dict({"design": "grid", "parameters": {"time_shift_s": 0.0}}),
            "time_shift_s",
            "ego.cruise_speed_mps",
            tmp_path,
        )
