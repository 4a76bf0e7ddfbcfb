"""Risk map figure: what is drawn (heatmap values, boundary segments, sample markers)."""

from __future__ import annotations

import numpy as np
import pytest

from vei.experiments.boundary import adaptive_boundary, lattice_heatmap
from vei.report.riskmap import _edges, risk_map_figure, write_risk_map


def _artist(ax, gid):
    found = [a for a in ax.get_children() if a.get_gid() == gid]
    assert len(found) == 1, gid
    return found[0]


def test_figure_content_matches_inputs():
    xc = np.array([0.0, 1.0, 2.0])
    yc = np.array([10.0, 20.0])
    value = np.array([[1.0, 0.5, 0.0], [np.nan, 0.25, 0.75]])
    seg = np.array([[[0.5, 10.0], [1.5, 20.0]], [[1.5, 20.0], [2.0, 25.0]]])
    fig = risk_map_figure(
        x_centres=xc,
        y_centres=yc,
        value=value,
        segments=seg,
        sample_x=np.array([0.0, 1.0, 2.0]),
        sample_y=np.array([10.0, 10.0, 20.0]),
        sample_collided=np.array([True, False, True]),
        x_label="time_shift_s",
        y_label="ego.cruise_speed_mps",
    )
    ax = fig.axes[0]
    mesh = _artist(ax, "heatmap")
    arr = mesh.get_array()
    assert arr.shape == value.shape or arr.size == value.size
    assert np.ma.getmaskarray(arr).reshape(2, 3)[1, 0]  # NaN drawn blank
    assert np.asarray(arr).reshape(2, 3)[0].tolist() == pytest.approx([1.0, 0.5, 0.0])
    lc = _artist(ax, "boundary")
    drawn = np.array([np.asarray(p) for p in lc.get_segments()])
    assert drawn == pytest.approx(seg)
    assert _artist(ax, "collided").get_offsets().tolist() == [[0.0, 10.0], [2.0, 20.0]]
    assert _artist(ax, "safe").get_offsets().tolist() == [[1.0, 10.0]]
    assert ax.get_xlabel() == "time_shift_s" and ax.get_ylabel() == "ego.cruise_speed_mps"
    assert ax.get_xlim() == pytest.approx((-0.5, 2.5))
    assert ax.get_ylim() == pytest.approx((5.0, 25.0))


def test_edges_of_centres():
    assert _edges(np.array([0.0, 1.0, 3.0])).tolist() == pytest.approx([-0.5, 0.5, 2.0, 4.0])
    assert _edges(np.array([2.0])).tolist() == [1.5, 2.5]


def test_written_png_of_a_boundary_search(tmp_path):
    def oracle(p):
        x, y = p[:, 0], p[:, 1]
        gap = y - (0.5 * x + 0.2)
        return {"collision": gap > 0, "safety_index": np.clip(-gap, 0.0, 1.0)}

    res = adaptive_boundary(oracle, (-2.0, 2.0), (-2.0, 2.0), coarse=(5, 5), levels=3)
    heat = lattice_heatmap(res)
    assert heat["value"].shape == (len(res.y_values), len(res.x_values))
    # interpolated values stay within the sampled range and match at sample points
    assert np.nanmin(heat["value"]) >= 0.0 and np.nanmax(heat["value"]) <= 1.0
    s = res.samples.iloc[0]
    assert heat["value"][int(s["j"]), int(s["i"])] == pytest.approx(s["safety_index"])
    out = write_risk_map(
        tmp_path / "riskmap.png",
        x_centres=heat["x_centres"],
        y_centres=heat["y_centres"],
        value=heat["value"],
        segments=res.segments,
        sample_x=res.samples["x"],
        sample_y=res.samples["y"],
        sample_collided=res.samples["collision"],
    )
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    assert not list(tmp_path.glob(".*.tmp"))
