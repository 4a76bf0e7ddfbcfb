import numpy as np
import pandas as pd
import pytest
from matplotlib.colors import to_rgba

from tests.helpers_interaction import make_interaction
from vei.io.interaction import read_interaction
from vei.recon.pipeline import reconstruct
from vei.report.birdseye import PRIMARY_COLOUR, plot_birdseye, save_figure


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    return reconstruct(read_interaction(make_interaction(tmp_path_factory.mktemp("b"))))


def _lines(fig):
    return {line.get_label(): line for line in fig.axes[0].get_lines()}


def test_paths_keyframes_and_primary_threat_are_drawn(scenario):
    fig = plot_birdseye(scenario)
    lines = _lines(fig)
    ego = scenario.track("ego")
    assert lines["ego"].get_xdata() == pytest.approx(ego["x_m"].to_numpy())
    assert lines["ego"].get_ydata() == pytest.approx(ego["y_m"].to_numpy())
    # The primary threat is labelled, red and thicker than the other rider.
    primary = lines["escooter_1 (primary threat)"]
    assert to_rgba(primary.get_color()) == to_rgba(PRIMARY_COLOUR)
    assert primary.get_linewidth() > lines["cyclist_2"].get_linewidth()
    assert primary.get_xdata() == pytest.approx(scenario.track("escooter_1")["x_m"].to_numpy())
    # Keyframes as markers: 7 per rider (0..6 s at 1 Hz), at the keyframe positions.
    kf = scenario.keyframes
    for agent in ("escooter_1", "cyclist_2"):
        marks = lines[f"{agent} keyframes"]
        assert marks.get_linestyle() == "None" and marks.get_marker() == "x"
        assert marks.get_xdata() == pytest.approx(kf[kf["agent_id"] == agent]["x_m"].to_numpy())
        start = lines[f"{agent} start"]
        assert start.get_xdata() == pytest.approx([scenario.track(agent)["x_m"].iloc[0]])
    assert "ego start" in lines
    ax = fig.axes[0]
    assert ax.get_aspect() == 1.0
    assert ax.get_title() == scenario.id
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend == ["ego", "cyclist_2", "escooter_1 (primary threat)"]


def test_roads_hook_draws_underneath_and_sim_tracks_on_top(scenario):
    calls = []

    def roads(ax):
        calls.append(ax)
        ax.plot([-100, 100], [0, 0], color="0.8", label="_road")

    sim = pd.DataFrame(
        {"agent_id": "escooter_1", "t_s": [0.0, 1.0], "x_m": [1.0, 2.0], "y_m": [3.0, 4.0]}
    )
    fig = plot_birdseye(scenario, sim_tracks=sim, roads=roads, title="T")
    ax = fig.axes[0]
    assert calls == [ax]
    assert ax.get_lines()[0].get_label() == "_road"  # drawn first, below the paths
    sim_line = _lines(fig)["escooter_1 (sim)"]
    assert sim_line.get_linestyle() == "--"
    assert sim_line.get_ydata() == pytest.approx([3.0, 4.0])
    assert ax.get_title() == "T"


def test_draws_into_given_axes_and_saves_atomically(scenario, tmp_path):
    from matplotlib.figure import Figure

    fig = Figure()
    ax = fig.add_subplot()
    assert plot_birdseye(scenario, ax=ax) is fig
    path = save_figure(fig, tmp_path / "out" / "b.png")
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in path.parent.iterdir()] == ["b.png"]
    assert np.isfinite(ax.get_xlim()).all()


def test_paths_are_time_coded_every_second(scenario):
    fig = plot_birdseye(scenario)
    ax = fig.axes[0]
    dots = {c.get_label(): c for c in ax.collections}
    ego = scenario.track("ego")
    whole = np.isclose(ego["t_s"] % 1.0, 0.0, atol=1e-6) | np.isclose(
        ego["t_s"] % 1.0, 1.0, atol=1e-6
    )
    e = dots["_ego seconds"]
    np.testing.assert_allclose(e.get_offsets()[:, 0], ego["x_m"].to_numpy()[whole])
    assert e.get_array().tolist() == pytest.approx(ego["t_s"].to_numpy()[whole])  # 0..6 s
    assert e.get_array().tolist() == pytest.approx([0, 1, 2, 3, 4, 5, 6])
    assert "_escooter_1 seconds" in dots  # the primary threat
    assert fig.axes[1].get_ylabel().startswith("time [s]")  # the colour bar
    assert len(plot_birdseye(scenario, time_dots=False).axes) == 1


def test_save_figure_writes_vector_copies(scenario, tmp_path):
    fig = plot_birdseye(scenario)
    save_figure(fig, tmp_path / "b.png", also=("pdf", "svg"))
    assert (tmp_path / "b.pdf").read_bytes()[:5] == b"%PDF-"
    assert b"<svg" in (tmp_path / "b.svg").read_bytes()[:400]
