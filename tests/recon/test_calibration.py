"""vei.recon.calibration: the std factor that calibrates the 95 % region, by hand and on
draws from a known distribution; the factor's effect on the smoother's std and samples."""

import numpy as np
import pytest

from vei.recon.calibration import CHI2_2DOF_95, coverage, fit_inflation, leave_one_out
from vei.recon.smoother import KalmanInterpolant, NoiseEstimate, posterior, sample_tracks


def test_fit_inflation_and_coverage_by_hand():
    # d2 = 0, 1, ..., 99: the 0.95 quantile (linear) is 94.05, so c^2 = 94.05 / 5.991.
    d2 = np.arange(100.0)
    c = fit_inflation(d2)
    assert c == pytest.approx(np.sqrt(94.05 / CHI2_2DOF_95))
    assert coverage(d2, c) == pytest.approx(0.95)  # 0..94 inside
    assert coverage([1.0, 5.0, 7.0]) == pytest.approx(2 / 3)  # 7 > 5.991
    with pytest.raises(ValueError):
        fit_inflation([])


def test_factor_recovers_a_known_underestimate():
    # The truth spreads twice as wide as the model says: d2 = |e|^2 / s^2 with e ~ N(0, (2 s)^2 I).
    rng = np.random.default_rng(3)
    d2 = np.sum((2.0 * rng.standard_normal((20000, 2))) ** 2, axis=1)
    assert coverage(d2) == pytest.approx(1 - np.exp(-CHI2_2DOF_95 / 8), abs=0.01)  # 0.527
    assert fit_inflation(d2) == pytest.approx(2.0, rel=0.03)
    # Two groups from the same law: each held-out group is covered 95 % +- binomial 4 sigma.
    loo = leave_one_out({"a": d2[:10000], "b": d2[10000:]})
    for fold in loo["folds"]:
        assert abs(fold["coverage_held_out"] - 0.95) < 4 * np.sqrt(0.95 * 0.05 / 10000)
    assert loo["factor_all"] == pytest.approx(fit_inflation(d2))
    with pytest.raises(ValueError):
        leave_one_out({"a": d2})


def test_std_inflation_scales_the_band_and_the_samples_not_the_mean():
    tk = np.arange(0.0, 8.0)
    xyk = np.column_stack([1.5 * tk, 0.1 * tk**2])
    t = np.linspace(0.0, 7.0, 141)
    base = posterior([(tk, xyk)], [t], 0.2, 0.5)[0]
    wide = posterior([(tk, xyk)], [t], 0.2, 0.5, std_scale=1.5)[0]
    assert wide.xy_m == pytest.approx(base.xy_m)
    assert wide.std_m == pytest.approx(1.5 * base.std_m)
    interp = KalmanInterpolant(tk, xyk, NoiseEstimate(0.2, 0.5, std_inflation=1.5))
    assert interp.std(t) == pytest.approx(wide.std_m)
    assert interp.position(t) == pytest.approx(base.xy_m)
    xy, _ = sample_tracks(tk, xyk, t, 0.2, 0.5, 4000, seed=1, std_scale=1.5)
    assert xy.std(axis=0).mean(axis=1) == pytest.approx(wide.std_m, rel=0.06)
    assert np.abs(xy.mean(axis=0) - base.xy_m).max() < 4 * wide.std_m.max() / np.sqrt(4000)
    with pytest.raises(ValueError):
        NoiseEstimate(0.2, 0.5, std_inflation=0.0)


def test_sample_share_map_draws_the_staircase_between_mostly_and_rarely_colliding_cells():
    from vei.report.uncertainty import share_edges

    # 2 x 3 grid, centres x = 0, 1, 2 and y = 10, 20; share without collision:
    # row y=10: 0.0 0.2 0.9 -> one vertical edge at x = 1.5 from y = 5 to 15;
    # row y=20: 0.0 0.8 0.9 -> one vertical edge at x = 0.5 from y = 15 to 25;
    # column x=1: 0.2 below 0.8 -> one horizontal edge at y = 15 from x = 0.5 to 1.5.
    v = np.array([[0.0, 0.2, 0.9], [0.0, 0.8, 0.9]])
    segs = share_edges(np.array([0.0, 1.0, 2.0]), np.array([10.0, 20.0]), v)
    got = sorted(tuple(map(tuple, s.round(9))) for s in segs)
    assert got == sorted(
        [((1.5, 5.0), (1.5, 15.0)), ((0.5, 15.0), (0.5, 25.0)), ((0.5, 15.0), (1.5, 15.0))]
    )
    assert share_edges(np.array([0.0]), np.array([0.0]), np.array([[np.nan]])).shape == (0, 2, 2)
