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
    assert len(fig.axes) == 3  # two panels + the time colour bar
    assert fig.axes[2].get_ylabel() == "time [s]"
    by_panel = [{ln.get_label(): ln for ln in ax.get_lines()} for ax in fig.axes[:2]]
    # time-coded: a dot at each whole second of the rider's span widened to whole seconds
    # ([0.5, 1.5] -> [0, 2]): ego at t = 0 (x 0) and 1 s (x 5.6); the rider (present from
    # 0.5 s) at t = 1 s (y -1)
    dots = fig.axes[0].collections
    assert [c.get_offsets().tolist() for c in dots] == [[[0.0, 0.0], [5.6, 0.0]], [[20.0, -1.0]]]
    assert [c.get_array().tolist() for c in dots] == [[0.0, 1.0], [1.0]]
    assert dots[0].get_clim() == (0.0, 2.0)
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
        assert p.with_suffix(".pdf").read_bytes()[:5] == b"%PDF-"  # a vector copy
    assert not list(tmp_path.glob(".*tmp"))


def test_speed_profiles_show_rider_speed_and_cap_band_zoomed():
    frame = _frame()
    on = (frame["config"] == "normal-cap") & (frame["agent_id"] == "ego")
    frame.loc[on, "cap_state"] = ["CRUISE", "BRAKE", "BRAKE", "RECOVER"]
    fig = plot_speed_profiles(frame, other_id="s1", window_s=(0.5, 1.5))
    ego_ax, rider_ax, cap_ax = fig.axes
    assert {ln.get_label(): ln.get_ydata().tolist() for ln in ego_ax.get_lines()}["replay"] == [
        5.6, 5.6, 0.0, 0.0
    ]  # fmt: skip
    rider = {ln.get_label(): ln.get_ydata() for ln in rider_ax.get_lines()}
    # NaN before the rider appears (inactive at t = 0), then its speed 4 m/s
    np.testing.assert_array_equal(rider["normal-cap"], [np.nan, 4.0, 4.0, 4.0])
    assert ego_ax.get_xlim() == (0.5, 1.5)
    # CAP band: one row (the CAP configuration); BRAKE from t = 0.5 s for 1.0 s
    assert [t.get_text() for t in cap_ax.get_yticklabels()] == ["normal-cap"]
    bars = {c.get_label(): c for c in cap_ax.collections}
    assert set(bars) == {"CRUISE", "BRAKE", "RECOVER"}
    (x0, y0), (x1, y1) = bars["BRAKE"].get_paths()[0].vertices[[0, 2]]
    assert (min(x0, x1), abs(x1 - x0)) == pytest.approx((0.5, 1.0))
    # the two rider curves are identical: the note says so
    texts = [" ".join(t.get_text().split()) for t in rider_ax.texts]  # wrapped lines
    assert any("replay = normal-cap" in t for t in texts)


def test_identical_groups_and_interaction_window():
    from vei.report.casestudy_figures import identical_groups, interaction_window

    a = np.array([1.0, np.nan, 2.0])
    assert identical_groups({"x": a, "y": a.copy(), "z": a + 1}) == [["x", "y"]]
    assert identical_groups({"x": a, "z": a + 1}) == []
    # rider active from t = 0.5 s, within 30 m of the ego from then on; replay collides at
    # 1.0 s, normal-cap never: near span [0.5, 1.5]; 2 s margins clipped to the run [0, 1.5]
    assert interaction_window(_frame(), "s1") == (0.0, 1.5)
    assert interaction_window(_frame(), "s1", margin_s=0.25) == (0.25, 1.5)
    # centre distances (hand-computed): t 0.5 -> 17.46 m (both); t 1.0 -> replay 14.43
    # (its collision step), normal-cap 15.23; t 1.5 -> replay 14.43 (after its collision:
    # not counted), normal-cap 13.74. Under 15 m: replay at 1.0 s, normal-cap at 1.5 s.
    assert interaction_window(_frame(), "s1", margin_s=0.0, near_m=15.0) == (1.0, 1.5)
    assert interaction_window(_frame(), "nobody") is None


def test_run_figures_are_titled_as_a_run(tmp_path):
    from vei.report.casestudy_figures import figure_title

    one = _summary().iloc[:1]
    assert figure_title(one) == "Run replay"
    assert figure_title(_summary(), "scen") == "Case study: scen"
    frame = _frame()
    paths = write_casestudy_figures(
        tmp_path, frame=frame[frame["config"] == "replay"], summary=one, other_id="s1",
        ttc_t_s=np.array([0.0, 0.5, 1.0, 1.5]), ttc_s=np.ones((1, 4)), formats=(),
    )  # fmt: skip
    assert not list(tmp_path.glob("*.pdf"))
    assert len(paths) == len(FIGURE_FILES)


def test_cap_band_has_a_legend_of_every_state_and_the_note_stays_in_its_panel():
    """The CAP band's colours are named (CRUISE / BRAKE / RECOVER, even a state that does
    not occur); the 'identical curves' note is wrapped inside its own axes instead of
    running into the next panel."""
    frame = _frame()
    on = (frame["config"] == "normal-cap") & (frame["agent_id"] == "ego")
    frame.loc[on, "cap_state"] = ["CRUISE", "CRUISE", "CRUISE", "CRUISE"]
    # five more configurations with the same rider curve: a long note
    extra = []
    for name in ("normal", "aggressive", "aggressive-cap", "paper-normal", "paper-normal-cap"):
        extra.append(frame[frame["config"] == "normal-cap"].assign(config=name))
    frame = pd.concat([frame, *extra], ignore_index=True)
    fig = plot_speed_profiles(frame, other_id="s1")
    ego_ax, rider_ax, cap_ax = fig.axes[:3]
    legend = cap_ax.get_legend()
    assert legend is not None
    assert [t.get_text() for t in legend.get_texts()] == ["CRUISE", "BRAKE", "RECOVER"]
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    for ax in (ego_ax, rider_ax):
        notes = [t for t in ax.texts if t.get_text().startswith("identical curves")]
        assert notes, "the note is drawn"
        box = notes[0].get_window_extent(renderer)
        frame_box = ax.get_window_extent(renderer)
        assert box.x0 >= frame_box.x0 - 1 and box.x1 <= frame_box.x1 + 1, (box, frame_box)


def test_birdseye_shades_the_run_in_and_run_out():
    """Issue 22: the rider's continuation samples (column ``continuation``) are drawn as a
    shaded band under its path (gid 'continuation'), NaN between run-in and run-out."""
    frame = _frame()
    rider = frame["agent_id"] == "s1"
    frame["continuation"] = rider & (frame["t_s"] <= 0.5)  # the first active step: run-in
    fig = plot_birdseye_configs(frame, other_id="s1")
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    band = lines["run-in / run-out"]
    assert band.get_gid() == "continuation" and band.get_alpha() == 0.25
    ys = band.get_ydata()
    assert ys[0] == -3.0 and np.isnan(ys[1:]).all()  # active rider steps: 0.5 (run-in), 1, 1.5
    no = plot_birdseye_configs(_frame(), other_id="s1")
    assert "run-in / run-out" not in {ln.get_label() for ln in no.axes[0].get_lines()}
