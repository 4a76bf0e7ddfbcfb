import matplotlib

matplotlib.use("Agg")

import numpy as np
import pandas as pd
import pytest

from vei.report.casestudy_figures import (
    FIGURE_FILES,
    plot_birdseye_configs,
    plot_safety_index,
    plot_speed_profiles,
    plot_speed_std,
    plot_ttc_zones,
    write_casestudy_figures,
)
from vei.types import TIMESERIES_COLUMNS

NAMES = ["replay", "normal-cap"]


def _frame():
    t = np.arange(0.0, 2.0, 0.5)
    rows = []
    for name, speeds, hit in (
        ("replay", [5.6, 5.6, 0.0, 0.0], 2),
        ("normal-cap", [5.6, 4.0, 3.0, 5.0], None),
    ):
        x = 0.0
        for k, tk in enumerate(t):
            collided = hit is not None and k >= hit
            rows.append(
                (name, 0, tk, "ego", "ego", x, 0.0, 0.0, speeds[k], 0.0, True, collided, "")
            )
            rows.append(
                (
                    name,
                    0,
                    tk,
                    "s1",
                    "escooter",
                    20.0,
                    -5.0 + 2.0 * k,
                    np.pi / 2,
                    4.0,
                    0.0,
                    k >= 1,
                    collided,
                    "",
                )
            )
            x += speeds[k] * 0.5
    return pd.DataFrame(rows, columns=list(TIMESERIES_COLUMNS))


def _summary():
    return pd.DataFrame(
        {
            "name": NAMES,
            "collision": [True, False],
            "safety_index": [0.0, 1.0],
            "ego_speed_std_mps": [2.8, 0.95],
        }
    )


def test_speed_profiles_lines_hold_each_configs_ego_speed():
    fig = plot_speed_profiles(_frame())
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    assert set(lines) == set(NAMES)
    assert lines["replay"].get_ydata().tolist() == [5.6, 5.6, 0.0, 0.0]
    assert lines["normal-cap"].get_xdata().tolist() == [0.0, 0.5, 1.0, 1.5]
    assert lines["normal-cap"].get_ydata().tolist() == [5.6, 4.0, 3.0, 5.0]


def test_bar_heights_are_the_summary_values():
    std = plot_speed_std(_summary())
    heights = [p.get_height() for p in std.axes[0].patches]
    assert heights == pytest.approx([2.8, 0.95])
    si = plot_safety_index(_summary())
    assert [p.get_height() for p in si.axes[0].patches] == [0.0, 1.0]
    assert [p.get_gid() for p in si.axes[0].patches] == NAMES
    texts = [t.get_text() for t in si.axes[0].texts]
    assert texts.count("collision") == 1


def test_birdseye_panels_paths_and_collision_star():
    kf = pd.DataFrame(
        {"t_s": [1.0, 2.0], "agent_id": ["s1", "s1"], "x_m": [20.1, 19.9], "y_m": [-3.0, -1.0]}
    )
    fig = plot_birdseye_configs(_frame(), other_id="s1", keyframes=kf)
    assert len(fig.axes) == 2
    by_panel = [{ln.get_label(): ln for ln in ax.get_lines()} for ax in fig.axes]
    replay, cap = by_panel
    assert replay["ego"].get_color() == "red"
    assert replay["ego"].get_xdata().tolist() == [0.0, 2.8, 5.6, 5.6]
    assert replay["keyframes"].get_linestyle() == "--"
    assert replay["keyframes"].get_ydata().tolist() == [-3.0, -1.0]
    assert replay["s1 (sim)"].get_color() == "tab:green"
    assert replay["s1 (sim)"].get_ydata().tolist() == [-3.0, -1.0, 1.0]  # active steps only
    assert replay["collision"].get_xdata().tolist() == [
        5.6
    ]  # ego position at the first collided step
    assert "collision" not in cap


def test_ttc_zone_figure_clips_inf_and_shades_three_zones():
    t = np.array([0.0, 0.5, 1.0])
    ttc = np.array([[np.inf, 1.5, 0.5], [np.nan, 3.0, 2.5]])
    fig = plot_ttc_zones(t, ttc, NAMES, ymax_s=6.0)
    ax = fig.axes[0]
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    assert lines["replay"].get_ydata().tolist() == [6.0, 1.5, 0.5]
    assert len(ax.patches) == 3  # safe / attention / alert bands


def test_write_casestudy_figures_writes_every_png(tmp_path):
    paths = write_casestudy_figures(
        tmp_path,
        frame=_frame(),
        summary=_summary(),
        other_id="s1",
        ttc_t_s=np.array([0.0, 0.5, 1.0, 1.5]),
        ttc_s=np.ones((2, 4)),
    )
    assert set(paths) == set(FIGURE_FILES)
    for p in paths.values():
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(tmp_path.glob(".*tmp"))
