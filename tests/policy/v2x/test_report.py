"""What V2X did in a run (vei.policy.v2x.report): the log's rules by hand (braking, known
from V2X alone while in the scene, stale tracks) and the one-line note."""

from __future__ import annotations

import numpy as np
import pytest

from vei.policy.observation import SOURCE_BOTH, SOURCE_NONE, SOURCE_SENSOR, SOURCE_V2X
from vei.policy.v2x import report


def test_braking_is_a_real_deceleration():
    assert report.braking(np.array([-0.6, -0.4, 0.3]), None).tolist() == [True, False, False]
    # a command u brakes at u x the full brake: -0.1 x 8 = -0.8 m/s^2 is braking, a PID's
    # -0.05 x 8 = -0.4 m/s^2 correction is not
    got = report.braking(None, np.array([-0.1, -0.05, 0.2]), np.array([8.0, 8.0, 8.0]))
    assert got.tolist() == [True, False, False]


def test_the_log_tells_hidden_riders_from_stale_tracks():
    log = report.V2XLog.start(3)
    # variant 0: a rider known from V2X alone, in the scene, the car brakes; variant 1: a
    # V2X-only track of a rider that has left; variant 2: seen by both
    src = np.array(
        [[SOURCE_V2X, SOURCE_NONE], [SOURCE_V2X, SOURCE_SENSOR], [SOURCE_BOTH, SOURCE_NONE]]
    )
    valid = src != SOURCE_NONE
    present = np.array([[True, False], [False, True], [True, False]])
    log.update(1.0, src, valid, present, np.array([True, True, True]))
    log.update(1.05, src, valid, present, np.array([False, False, False]))
    assert log.first_v2x_only_s.tolist()[0] == 1.0 and np.isnan(log.first_v2x_only_s[1:]).all()
    assert log.acted_s[0] == 1.0 and np.isnan(log.acted_s[1:]).all()
    assert log.v2x_only_steps.tolist() == [2, 0, 0] and log.stale_steps.tolist() == [0, 2, 0]
    out = report.finish(log, None, 0.05)
    assert out["v2x_only_s"] == pytest.approx([0.1, 0.0, 0.0])
    assert out["v2x_stale_s"] == pytest.approx([0.0, 0.1, 0.0])
    assert np.isnan(out["v2x_sent"]).all()  # no V2X state: nothing to count


def test_the_note_says_what_v2x_did():
    base = {"v2x_sent": 12.0, "v2x_delivered": 11.0, "v2x_first_track_s": 0.05,
            "v2x_only_first_s": float("nan"), "v2x_only_s": 0.0, "v2x_stale_s": 0.0,
            "v2x_acted_s": float("nan")}  # fmt: skip
    assert report.note(base) == (
        "11 of 12 messages delivered, first V2X track at 0.05 s; V2X changed nothing: the "
        "sensor saw every rider V2X reported while it was in the scene"
    )
    assert "V2X only refined positions" in report.note(base, sensor_noise_m=0.3)
    hidden = {**base, "v2x_only_first_s": 0.05, "v2x_only_s": 4.0, "v2x_acted_s": 3.2}
    assert report.note(hidden).endswith(
        "known from V2X alone from 0.05 s (4.00 s); the car braked on V2X alone at 3.20 s"
    )
    assert report.note({**base, "v2x_delivered": 0.0, "v2x_first_track_s": float("nan")}) == (
        "0 of 12 messages delivered; V2X changed nothing: the car received no message"
    )
    assert report.note({**base, "v2x_sent": 0.0}).startswith("V2X changed nothing: no equipped")
    assert report.note({**base, "v2x_sent": float("nan")}) == ""
