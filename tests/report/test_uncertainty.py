import numpy as np
import pytest

from vei.report.uncertainty import Z95, band_polygon, plot_uncertainty


def test_band_polygon_of_a_straight_path_is_a_strip():
    xy = np.column_stack([np.linspace(0, 10, 11), np.zeros(11)])
    std = np.full(11, 0.5)
    poly = band_polygon(xy, std)
    assert poly.shape == (22, 2)
    assert poly[:11, 1] == pytest.approx(np.full(11, Z95 * 0.5))  # left edge (north)
    assert poly[11:, 1] == pytest.approx(np.full(11, -Z95 * 0.5))  # right edge, backwards
    assert poly[11:, 0] == pytest.approx(xy[::-1, 0])
    # A standing rider gets the normal of the nearest moving step, never NaN.
    xy2 = np.vstack([xy[:1], xy])
    assert np.isfinite(band_polygon(xy2, np.full(12, 0.5))).all()


def test_uncertainty_figure_has_labelled_band_and_paths(tmp_path):
    t = np.linspace(0, 5, 51)
    mean = np.column_stack([2 * t, np.zeros_like(t)])
    std = 0.1 + 0.05 * np.sin(t) ** 2
    rng = np.random.default_rng(0)
    samples = mean[None] + rng.normal(0, 0.1, (5, 51, 2))
    fig = plot_uncertainty(
        agent_id="escooter_1",
        t_s=t,
        mean_xy_m=mean,
        std_m=std,
        ego_xy_m=np.column_stack([np.full(20, 5.0), np.linspace(-30, 30, 20)]),
        samples_xy_m=samples,
        keyframes_xy_m=mean[::10],
    )
    ax = fig.axes[0]
    labels = {a.get_label() for a in [*ax.lines, *ax.patches]}
    assert {
        "escooter_1 95 % band",
        "escooter_1 mean",
        "escooter_1 samples",
        "escooter_1 keyframes",
        "ego",
    } <= labels
    band = next(p for p in ax.patches if p.get_label() == "escooter_1 95 % band")
    ys = band.get_xy()[:, 1]
    assert ys.max() == pytest.approx(Z95 * std.max(), rel=1e-6)
    from vei.report.birdseye import save_figure

    assert save_figure(fig, tmp_path / "u.png").stat().st_size > 10_000


def test_zoom_inset_magnifies_the_chosen_point():
    t = np.linspace(0, 5, 51)
    mean = np.column_stack([10 * t, np.zeros_like(t)])
    fig = plot_uncertainty(
        agent_id="r", t_s=t, mean_xy_m=mean, std_m=np.full(51, 0.2), zoom_xy_m=[25.0, 0.0]
    )
    ax = fig.axes[0]
    zoom = [c for c in ax.child_axes if c.get_gid() == "zoom"]
    assert len(zoom) == 1
    assert zoom[0].get_xlim() == pytest.approx((21.0, 29.0))
