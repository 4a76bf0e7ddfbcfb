"""VAM generation rules (ETSI TS 103 300-3 clause 6.4.1) on scripted rider motions,
against schedules computed by hand; GNSS error statistics; equipped riders."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from vei.config.v2x import V2XConfig
from vei.policy.v2x import vam


def schedule(x, y, speed, heading, dt: float, cfg: V2XConfig | None = None, present=None):
    """Generation times [s] of one rider's VAMs over a scripted motion (no GNSS error)."""
    cfg = cfg or V2XConfig(enabled=True, position_error_std_m=0.0)
    rules = vam.VamRules.of(cfg)
    n = len(x)
    st = vam.init_senders(0, np.array([1]), np.array([0]), np.array([1.0]))
    zero = np.zeros((1, 1))
    times = []
    for k in range(n):
        pres = np.array([[True if present is None else present[k]]])
        gen, st = vam.generate(
            rules, st, k * dt, pres, np.array([[x[k]]]), np.array([[y[k]]]),
            np.array([[speed[k]]]), np.array([[heading[k]]]), zero, zero,
        )  # fmt: skip
        if gen.sent[0, 0]:
            times.append(round(k * dt, 9))
    return times


@pytest.mark.parametrize("dt", [0.05, 0.1])
def test_constant_speed_sends_when_the_position_moved_more_than_4_m(dt):
    # 5 m/s: the position change since the last VAM exceeds 4 m after 0.8 s; the checks are
    # every 0.1 s from the first VAM, and at 0.8 s the change is exactly 4 m (not more):
    # VAMs at 0 (service start), 0.9, 1.8, 2.7.
    t = np.arange(round(3.0 / dt) + 1) * dt
    x = 5.0 * t
    assert schedule(x, 0 * t, np.full_like(t, 5.0), 0 * t, dt) == [0.0, 0.9, 1.8, 2.7]


def test_a_turn_sends_each_time_the_heading_changed_more_than_4_deg():
    # 2 m/s; straight for 1 s, then a 90 deg left turn at 30 deg/s (1.0 .. 4.0 s), then
    # straight on. In the turn the heading changes 3 deg per check: more than 4 deg after two
    # checks (6 deg) -> 1.2, 1.4, ..., 4.0. Then straight: the position moved more than 4 m
    # from the 4.0 s VAM after 2.0 s; exactly 4 m at 6.0 -> 6.1.
    dt = 0.05
    t = np.arange(round(7.0 / dt) + 1) * dt
    rate = math.radians(30.0)
    heading = np.clip(t - 1.0, 0.0, 3.0) * rate
    speed = np.full_like(t, 2.0)
    x = np.zeros_like(t)
    y = np.zeros_like(t)
    for k in range(1, t.size):  # exact integration of the piecewise motion
        x[k] = x[k - 1] + _arc(speed[k], heading[k - 1], heading[k], dt, "x")
        y[k] = y[k - 1] + _arc(speed[k], heading[k - 1], heading[k], dt, "y")
    turn = [round(1.2 + 0.2 * i, 9) for i in range(15)]
    assert turn[-1] == 4.0
    assert schedule(x, y, speed, heading, dt) == [0.0, *turn, 6.1]


def _arc(v: float, h0: float, h1: float, dt: float, axis: str) -> float:
    if h1 == h0:
        return v * dt * (math.cos(h0) if axis == "x" else math.sin(h0))
    r = v * dt / (h1 - h0)
    return r * (math.sin(h1) - math.sin(h0)) if axis == "x" else -r * (math.cos(h1) - math.cos(h0))


def test_a_stop_sends_on_speed_changes_then_every_5_1_s():
    # v = 4 - 2 t until it stands at 2 s. The speed changes 0.2 m/s per check: more than
    # 0.5 m/s after three checks -> 0.3, 0.6, ..., 1.8 (v = 0.4). Stopping from 0.4 m/s is a
    # 0.4 m/s change over 0.04 m: no trigger. Standing: only T_GenVamMax; "exceeds" 5 s ->
    # 1.8 + 5.1 = 6.9, then 12.0.
    dt = 0.05
    t = np.arange(round(12.0 / dt) + 1) * dt
    v = np.maximum(0.0, 4.0 - 2.0 * t)
    x = np.where(t < 2.0, 4.0 * t - t**2, 4.0)
    assert schedule(x, 0 * t, v, 0 * t, dt) == [0.0, 0.3, 0.6, 0.9, 1.2, 1.5, 1.8, 6.9, 12.0]


def test_the_first_vam_is_sent_when_the_rider_enters_and_again_after_it_returns():
    dt = 0.05
    t = np.arange(81) * dt
    present = (t >= 0.5) & ~((t >= 2.0) & (t < 3.0))
    z = np.zeros_like(t)
    # Standing (no trigger but the first VAM): VAMs when the service starts, at 0.5 and 3.0.
    assert schedule(z, z, z, z, dt, present=present) == [0.5, 3.0]


def test_an_unequipped_rider_never_sends():
    st = vam.init_senders(0, np.array([1]), np.array([0]), np.array([0.0]))
    assert not st.equipped.any()
    gen, _ = vam.generate(vam.VamRules(), st, 0.0, np.ones((1, 1), bool), *(np.zeros((1, 1)),) * 6)
    assert not gen.sent.any()


def test_equipped_share_is_the_penetration_rate_and_grows_with_it():
    keys = np.arange(10_000)
    p = 0.3
    eq = vam.equipped_riders(7, keys, np.array([0]), np.full(keys.size, p))[:, 0]
    sigma = math.sqrt(p * (1 - p) / keys.size)
    assert abs(eq.mean() - p) < 4 * sigma
    more = vam.equipped_riders(7, keys, np.array([0]), np.full(keys.size, 0.6))[:, 0]
    assert np.all(more[eq])  # the same riders and more


def test_gnss_error_is_stationary_gauss_markov_from_fix_to_fix():
    b, n = 4000, 40
    std, tau, period = 3.0, 2.0, 0.1
    st = vam.init_senders(0, np.arange(b), np.array([0]), np.ones(b))
    xs = []
    for k in range(n):  # engine steps of 0.05 s: a new fix every second step
        ex, ey, m = vam.gnss_error(st, 3, np.arange(b), np.array([0]), k * 0.05, period,
                                   np.full(b, std), tau)  # fmt: skip
        assert m == k // 2
        if k % 2:  # between fixes the error holds
            np.testing.assert_array_equal(ex, xs[-1][:, None])
        st = replace(st, err_x_m=ex, err_y_m=ey, fix_index=np.array(m))
        xs.append(ex[:, 0])
    fixes = np.array(xs[::2])
    # Stationary: the standard deviation at the first and last fix is std (4 sigma of the
    # sample std: std / sqrt(2 b)).
    tol = 4 * std / math.sqrt(2 * b)
    assert abs(fixes[0].std() - std) < tol
    assert abs(fixes[-1].std() - std) < tol
    # Lag-1 correlation between fixes exp(-period / tau).
    phi = math.exp(-period / tau)
    r = np.corrcoef(fixes[10], fixes[11])[0, 1]
    assert abs(r - phi) < 4 * (1 - phi**2) / math.sqrt(b)
