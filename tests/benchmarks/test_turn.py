"""The coordinated-turn smoother (benchmarks.recon_research.turn) against known answers: the arc it
propagates, its Jacobian, the constant-velocity limit, and on synthetic 1 Hz tracks with
noise: better than the constant-velocity smoother on a constant turn, no worse on a line,
and its noise estimate finds a turn-rate noise near zero on straight tracks."""

import math

import numpy as np
import pytest
from benchmarks.recon_research import turn

from vei.recon.smoother import posterior

SIGMA_M = 0.25


def test_propagate_quarter_circle():
    # 5 m/s on a circle of radius 10 m (omega = 0.5 rad/s): a quarter turn takes pi s and
    # ends 10 m ahead and 10 m to the left, heading +y.
    s = np.array([0.0, 5.0, 0.0, 0.0, 0.5])
    end = turn.propagate(s, math.pi / 2 / 0.5)
    assert end == pytest.approx([10.0, 0.0, 10.0, 5.0, 0.5], abs=1e-9)
    straight = turn.propagate(np.array([1.0, 2.0, 3.0, -1.0, 0.0]), 2.0)
    assert straight == pytest.approx([5.0, 2.0, 1.0, -1.0, 0.0], abs=1e-9)


@pytest.mark.parametrize("omega", [0.0, 1e-8, 0.3, -0.7])
def test_jacobian_matches_finite_differences(omega):
    s = np.array([1.0, 4.0, -2.0, 1.5, omega])
    j = turn.jacobian(s, 0.8)
    num = np.zeros((5, 5))
    for k in range(5):
        d = np.zeros(5)
        d[k] = 1e-6
        num[:, k] = (turn.propagate(s + d, 0.8) - turn.propagate(s - d, 0.8)) / 2e-6
    assert j == pytest.approx(num, abs=1e-6)


def test_no_turn_noise_no_turn_is_the_constant_velocity_smoother():
    # turn_psd -> 0 and a tight prior on omega = 0: the CV model; the RTS means agree.
    rng = np.random.default_rng(3)
    t = np.arange(12.0)
    xy = np.column_stack([3.0 * t, 0.2 * t**1.5]) + rng.normal(0, SIGMA_M, (12, 2))
    tq = np.linspace(0.0, 11.0, 111)
    cv = posterior([(t, xy)], [tq], SIGMA_M, 0.5)[0]
    old = turn.PRIOR_TURN_VAR
    try:
        turn.PRIOR_TURN_VAR = 1e-14
        ct = turn.smooth_turn(t, xy, turn.TurnNoise(SIGMA_M, 0.5, 0.0), tq)
    finally:
        turn.PRIOR_TURN_VAR = old
    # The CV smoother's prior on the velocity is wider (1e4 vs 1e2 m^2/s^2): millimetres.
    assert ct.xy_m == pytest.approx(cv.xy_m, abs=5e-3)
    assert ct.std_m == pytest.approx(cv.std_m, rel=0.02)


def _noisy(rng, t, truth):
    return truth + rng.normal(0.0, SIGMA_M, truth.shape)


def _rmse(a, b):
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def test_constant_turn_beats_constant_velocity_and_line_is_no_worse():
    # 1 Hz keyframes with 0.25 m noise, scored at 10 Hz against the noise-free path. The
    # turn model with a small noise (near the truth of both paths) against the
    # constant-velocity smoother with its best q in hindsight.
    rng = np.random.default_rng(11)
    t = np.arange(0.0, 15.0)
    tq = np.linspace(0.0, 14.0, 141)
    r, w = 8.0, 0.5  # 4 m/s on an 8 m circle (a tight cyclist turn)

    def circle(tt):
        return np.column_stack([r * np.sin(w * tt), r * (1.0 - np.cos(w * tt))])

    def line(tt):
        return np.column_stack([4.0 * tt, 0.5 * tt])

    noise = turn.TurnNoise(SIGMA_M, 0.02, 1e-4)
    res = {}
    for name, path in (("circle", circle), ("line", line)):
        ys = [_noisy(rng, t, path(t)) for _ in range(10)]
        e_cv = min(
            np.mean([_rmse(posterior([(t, y)], [tq], SIGMA_M, q)[0].xy_m, path(tq)) for y in ys])
            for q in (0.02, 0.1, 0.3, 1.0, 3.0)
        )
        e_ct = np.mean([_rmse(turn.smooth_turn(t, y, noise, tq).xy_m, path(tq)) for y in ys])
        res[name] = (e_cv, e_ct)
    cv_c, ct_c = res["circle"]
    cv_l, ct_l = res["line"]
    assert ct_c < 0.8 * cv_c, res
    assert ct_l <= 1.05 * cv_l, res


def test_turn_coverage_on_a_noisy_circle():
    # The model's 95 % region (2-D, chi2_2 = 5.991) covers the true arc about 95 % of the time.
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 12.0)
    tq = np.linspace(0.0, 11.0, 56)
    truth = np.column_stack([6.0 * np.sin(0.4 * tq), 6.0 * (1 - np.cos(0.4 * tq))])
    hits = []
    for _ in range(30):
        y = _noisy(rng, t, np.column_stack([6.0 * np.sin(0.4 * t), 6.0 * (1 - np.cos(0.4 * t))]))
        ct = turn.smooth_turn(t, y, turn.TurnNoise(SIGMA_M, 0.05, 1e-4), tq)
        hits.append(np.sum((ct.xy_m - truth) ** 2, axis=1) / ct.std_m**2 <= 5.991)
    cov = float(np.mean(hits))
    assert 0.88 <= cov <= 0.995, cov


def test_estimate_noise_on_straight_tracks():
    # Straight constant-speed tracks with sigma = 0.3 m: the estimate finds sigma near 0.3,
    # little acceleration and a turn-rate noise at the bottom of its range.
    rng = np.random.default_rng(2)
    tracks = []
    for _ in range(4):
        t = np.arange(0.0, 10.0)
        v = rng.normal(0, 3.0, 2)
        tracks.append((t, np.outer(t, v) + rng.normal(0, 0.3, (10, 2))))
    est = turn.estimate_turn_noise(tracks)
    assert 0.22 <= est.noise_m <= 0.38, est
    assert est.accel_psd_m2ps3 < 0.05, est
    assert est.turn_psd_rad2ps3 < 1e-3, est
    assert math.isfinite(est.loglik)
    with pytest.raises(ValueError, match="enough keyframes"):
        turn.estimate_turn_noise([(np.arange(2.0), np.zeros((2, 2)))])
    with pytest.raises(ValueError, match="noise_m"):
        turn.TurnNoise(0.0, 1.0, 0.0)


def test_best_mix_by_hand():
    from benchmarks.recon_research.turn_compare import _best_mix_sq

    e1 = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.3, 0.4]])
    e2 = np.array([[-1.0, 0.0], [2.0, 0.0], [1.0, 0.0], [0.3, 0.4]])
    # opposite errors cancel (a = 1/2); same direction: the smaller (a = 1); orthogonal unit
    # errors: (1 - a, a) at a = 1/2 -> 0.5; equal errors: that error (0.25).
    assert _best_mix_sq(e1, e2) == pytest.approx([0.0, 1.0, 0.5, 0.25], abs=1e-12)


SMALL = ("audi_08_klinikum_rechtsabbiegen", "audi_08_stadtmitte_geradeaus")


def test_turn_table_on_two_real_recordings(trafficmonitoring_root, tmp_path):
    # Each recording scored with the turn noise fitted on the other one's keyframes. Measured
    # ('kalman' = the benchmark's numbers): cyclist_9 kalman 0.097 m, cyclist_4 0.134 m.
    from benchmarks.recon_research.turn_compare import turn_table

    from vei.datasets.trafficmonitoring import import_scenario
    from vei.io.interaction import read_interaction
    from vei.recon.pipeline import ReconstructionConfig, reconstruct

    inters = {
        n: read_interaction(import_scenario(trafficmonitoring_root, n, tmp_path / n)) for n in SMALL
    }
    scs = {n: reconstruct(i, ReconstructionConfig(interp="kalman")) for n, i in inters.items()}
    per_track, summary, noise = turn_table(scs, inters)
    assert list(per_track["agent_id"]) == ["cyclist_9", "cyclist_4"]
    assert per_track["kalman_rmse_sg_m"].to_numpy() == pytest.approx([0.097, 0.134], abs=2e-3)
    assert (per_track["turn_rmse_sg_m"] < 0.2).all()  # the keyframes are 0.06-0.09 m off
    lo = np.minimum(per_track["kalman_rmse_sg_m"], per_track["turn_rmse_sg_m"])
    assert (per_track["best_of_both_sg_m"] <= lo + 1e-12).all()
    assert (per_track["best_mix_sg_m"] <= per_track["best_of_both_sg_m"] + 1e-12).all()
    assert set(noise) == set(SMALL)
    assert all(0.02 <= nz.noise_m <= 3.0 for nz in noise.values())
    turn_row = summary.set_index("method").loc["turn"]
    assert 0.0 < turn_row["coverage_held_out"] <= 1.0
