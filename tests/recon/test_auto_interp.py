"""interp='auto' (vei.recon.auto_interp): cubic for sparse keyframes, smoothing for dense
ones, and the warning about implausible rider speeds.

The synthetic rider rides a 15 m radius curve at a known 4 m/s; its keyframes carry
Gaussian noise of 0.2 m per axis (the camera tracks of the shared recordings jitter by
0.1-0.3 m). At 30 Hz the cubic spline through them differentiates the jitter (speed RMSE
~11 m/s, benchmarks.recon_research.dense); the smoothing spline stays near 0.1 m/s.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from tests.helpers_interaction import CURVE_SPEED_MPS, make_curve_interaction
from vei.errors import ConfigError
from vei.recon import auto_interp
from vei.recon.auto_interp import ImplausibleSpeedWarning, choose_method
from vei.recon.pipeline import ReconstructionConfig, reconstruct

SPEED_MPS = CURVE_SPEED_MPS


def _speed_rmse(scenario) -> float:
    v = scenario.track("cyclist_7")["speed_mps"].to_numpy()
    return float(np.sqrt(np.mean((v - SPEED_MPS) ** 2)))


@pytest.fixture(scope="module")
def dense(tmp_path_factory):
    return make_curve_interaction(tmp_path_factory.mktemp("dense") / "i", 30.0)


@pytest.fixture(scope="module")
def sparse(tmp_path_factory):
    return make_curve_interaction(tmp_path_factory.mktemp("sparse") / "i", 1.0)


def test_rule_by_median_keyframe_spacing():
    assert choose_method(np.arange(30) / 30.0) == ("smoothing", pytest.approx(1 / 30))
    assert choose_method(np.arange(10) / 10.0)[0] == "smoothing"  # Argoverse 2
    assert choose_method(np.arange(10.0)) == ("cubic", pytest.approx(1.0))  # the paper's
    # 2 Hz picked from camera frames: 0.5 s up to the rounding of the frame times.
    assert choose_method(np.arange(10) * (0.5 - 1e-9))[0] == "cubic"
    assert choose_method(np.arange(10) * 0.45)[0] == "smoothing"
    # The median, not the mean: a dense track with one long tracking gap stays dense,
    # a 1 FPS track with one extra close annotation stays sparse.
    assert choose_method(np.r_[np.arange(30) / 30.0, 5.0 + np.arange(30) / 30.0])[0] == "smoothing"
    assert choose_method([0.0, 1.0, 1.1, 2.0, 3.0, 4.0])[0] == "cubic"
    assert choose_method([3.0]) == ("cubic", None)
    assert choose_method(np.arange(10) * 0.3, dense_spacing_s=0.25)[0] == "cubic"
    with pytest.raises(ConfigError, match="auto_dense_spacing_s"):
        ReconstructionConfig(auto_dense_spacing_s=0.0)
    assert ReconstructionConfig().interp == "auto"


def test_dense_noisy_track_is_smoothed_and_its_speed_is_right(dense):
    with warnings.catch_warnings():
        warnings.simplefilter("error", ImplausibleSpeedWarning)  # auto raises no warning
        sc = reconstruct(dense)
    rec = sc.extra["reconstruction"]
    (track,) = rec["tracks"]
    assert track["method"] == "smoothing"
    assert track["median_keyframe_spacing_s"] == pytest.approx(1 / 30, abs=1e-6)
    assert rec["auto_interp"]["smoothing"] == ["cyclist_7"] and rec["auto_interp"]["cubic"] == []
    assert rec["config"]["interp"] == "auto" and rec["speed_warnings"] == []
    # Against the known truth (4 m/s): noise-aware ~0.1 m/s, the interpolating cubic
    # spline through the same keyframes tens of times worse.
    assert _speed_rmse(sc) < 0.3
    with pytest.warns(ImplausibleSpeedWarning):
        cubic = reconstruct(dense, ReconstructionConfig(interp="cubic"))
    assert _speed_rmse(cubic) > 3.0
    # 'auto' on a dense track is exactly explicit 'smoothing'.
    smooth = reconstruct(dense, ReconstructionConfig(interp="smoothing"))
    pd.testing.assert_frame_equal(sc.trajectories, smooth.trajectories, check_exact=True)


def test_sparse_track_keeps_the_papers_cubic_bit_for_bit(sparse):
    sc = reconstruct(sparse)
    cubic = reconstruct(sparse, ReconstructionConfig(interp="cubic"))
    assert sc.extra["reconstruction"]["tracks"][0]["method"] == "cubic"
    assert sc.extra["reconstruction"]["auto_interp"]["cubic"] == ["cyclist_7"]
    pd.testing.assert_frame_equal(sc.trajectories, cubic.trajectories, check_exact=True)
    pd.testing.assert_frame_equal(sc.keyframes, cubic.keyframes, check_exact=True)
    assert sc.agents == cubic.agents and sc.primary_threat == cubic.primary_threat
    assert cubic.extra["reconstruction"]["auto_interp"] is None


def test_implausible_speed_warns_names_the_track_and_the_way_out(dense):
    with pytest.warns(ImplausibleSpeedWarning) as caught:
        sc = reconstruct(dense, ReconstructionConfig(interp="cubic"))
    (w,) = sc.extra["reconstruction"]["speed_warnings"]
    v = sc.track("cyclist_7")["speed_mps"].to_numpy()
    assert w["agent_id"] == "cyclist_7" and w["method"] == "cubic"
    assert w["max_speed_mps"] == pytest.approx(v.max()) and v.max() > 12.0
    assert w["limit_mps"] == 12.0
    msg = str(caught[0].message)
    assert msg == w["message"]
    assert "cyclist_7" in msg and f"{v.max():.1f} m/s" in msg and "--interp auto" in msg
    # The limit is the configured rider limit; below it nothing is reported.
    with warnings.catch_warnings():
        warnings.simplefilter("error", ImplausibleSpeedWarning)
        high = reconstruct(dense, ReconstructionConfig(interp="cubic", max_speed_mps=1e3))
    assert high.extra["reconstruction"]["speed_warnings"] == []


def test_speed_check_is_per_rider_category():
    traj = pd.DataFrame(
        {
            "agent_id": ["cyclist_1"] * 3 + ["vehicle_2"] * 3,
            "t_s": [0.0, 0.05, 0.1] * 2,
            "speed_mps": [3.0, 13.0, 4.0, 20.0, 20.0, 20.0],
        }
    )
    tracks = [
        {"agent_id": "cyclist_1", "category": "cyclist", "method": "linear"},
        {"agent_id": "vehicle_2", "category": "vehicle", "method": "cubic"},
    ]
    (w,) = auto_interp.implausible_speeds(traj, tracks, 12.0)
    assert (w.agent_id, w.max_speed_mps, w.t_s, w.median_spacing_s) == (
        "cyclist_1",
        13.0,
        0.05,
        None,
    )


def test_the_way_out_depends_on_the_method():
    w = auto_interp.SpeedWarning("escooter_3", "escooter", "smoothing", 14.0, 2.0, 12.0, 0.04)
    assert "--noise-m" in w.message() and "--interp auto" not in w.message()
    assert "keyframes 0.04 s apart" in w.message()
    w = auto_interp.SpeedWarning("escooter_3", "escooter", "linear", 14.0, 2.0, 12.0, None)
    assert "--interp auto" in w.message() and "apart" not in w.message()
