"""The default time-shift window (issue 31.4): narrowed to the offsets at which the
recorded rider meets the car's path, by hand and on a shared recording whose paths meet
(most collisions then happen on recorded behaviour); paths that never meet are said to
give a continuation-driven risk."""

from __future__ import annotations

import pytest

from vei.config.distributions import parse_distribution
from vei.risk.window import CONTINUATION_DRIVEN, narrow_time_shift
from vei.sim.timeshift import TimeShiftResult

UNIFORM = parse_distribution({"dist": "uniform", "min": -2.0, "max": 2.0}, "t")


def _shift(miss_m=0.27, span=(1.0, 5.95)):
    # audi_08_klinikum_rechtsabbiegen_02's automatic shift: the rider meets the car's
    # front at recording time 5.6975 - 4.6975 = 1.0 s, its first recorded sample
    return TimeShiftResult(4.6975, miss_m, 5.6975, 0.0, 0.0, 7.4, -9.9, 10.25, 1.225, "c",
                           span)  # fmt: skip


def test_recorded_window_by_hand():
    s = _shift()
    assert s.recorded_window_s() == pytest.approx((1.0 - 5.95, 0.0))
    d = s.as_dict()
    assert d["risk_basis"] == "recorded behaviour" and d["recorded_window_s"][1] == pytest.approx(0)
    dist, note = narrow_time_shift(UNIFORM, s, "recorded")
    assert (dist.low, dist.high) == (
        -2.0,
        0.0,
    ) and "narrowed from [-2, 2] to [-2.00, +0.00]" in note
    assert narrow_time_shift(UNIFORM, s, "full") == (UNIFORM, "")
    assert narrow_time_shift(UNIFORM, None, "recorded") == (UNIFORM, "")  # reference zero


def test_paths_that_never_meet_say_continuation_driven():
    far = _shift(miss_m=3.8)
    assert far.as_dict()["risk_basis"] == "continuations"
    assert narrow_time_shift(UNIFORM, far, "recorded") == (UNIFORM, CONTINUATION_DRIVEN)
    # a recorded span that meets the path only outside the window: kept whole, said so
    late = _shift(span=(-10.0, -2.3))  # offsets [3.3, 11] s
    dist, note = narrow_time_shift(UNIFORM, late, "recorded")
    assert dist == UNIFORM and "[+3.30, +11.00] s" in note and "continuation-driven" in note


def test_spec_key_is_checked_and_round_trips():
    from vei.errors import ConfigError
    from vei.risk.variation import parse_variation

    with pytest.raises(ConfigError, match="time_shift_window must be recorded or full"):
        parse_variation({"time_shift_window": "half"}, "risk.yaml")
    m = parse_variation({"time_shift_window": "full"})
    assert parse_variation(m.to_dict()) == m and m.time_shift_window == "full"
    assert parse_variation({}).time_shift_window == "recorded"


@pytest.mark.slow
def test_on_a_recording_whose_paths_meet_most_collisions_are_recorded(
    tmp_path, trafficmonitoring_root
):
    """audi_08_klinikum_rechtsabbiegen_02 (the cyclist turning beside the car), no
    avoidance, 2,000 samples of the default variation: with the default window most
    collisions happen on the rider's recorded track (measured 93 % of 665 in 4,000), with
    the full [-2, 2] s window most happen on its run-in (31 % recorded)."""
    import numpy as np

    from vei.cli.main import main
    from vei.risk.problem import RiskProblem
    from vei.risk.variation import parse_variation

    inter, scen = tmp_path / "inter", tmp_path / "scen"
    name = "audi_08_klinikum_rechtsabbiegen_02"
    assert main(["import", "trafficmonitoring", "--root", str(trafficmonitoring_root),
                 "--scenario", name, "--out", str(inter)]) == 0  # fmt: skip
    assert main(["reconstruct", str(inter), "--out", str(scen), "--no-figure"]) == 0
    share = {}
    for window in ("recorded", "full"):
        prob = RiskProblem.prepare(scen, parse_variation({"time_shift_window": window}), ("none",))
        u = np.random.default_rng(0).standard_normal((2000, prob.space.dimension))
        df = prob.evaluate(u)
        hit = df["collision"].to_numpy(bool)
        assert hit.sum() > 100
        share[window] = float((df.loc[hit, "contact_where"] == "recorded").mean())
        if window == "recorded":
            assert any("narrowed from [-2, 2] to [-2.00, +0.00] s" in n for n in prob.space.notes)
    assert share["recorded"] > 0.85 and share["full"] < 0.5


@pytest.mark.slow
def test_reconstruction_samples_run_on_their_posterior_sample(tmp_path, trafficmonitoring_root):
    """reconstruction: {samples: N} on a shared recording: each sample runs on its
    posterior reconstruction (the same u with another sample gives another outcome on
    some samples; with N = 1 ... the sample's own trajectory, not the mean)."""
    import numpy as np

    from vei.cli.main import main
    from vei.risk.problem import RECON_NOTE, RiskProblem
    from vei.risk.variation import parse_variation
    from vei.sweep.spec import SAMPLE_COLUMN

    inter, scen = tmp_path / "inter", tmp_path / "scen"
    name = "audi_08_klinikum_rechtsabbiegen_02"
    assert main(["import", "trafficmonitoring", "--root", str(trafficmonitoring_root),
                 "--scenario", name, "--out", str(inter)]) == 0  # fmt: skip
    assert main(["reconstruct", str(inter), "--out", str(scen), "--no-figure"]) == 0
    prob = RiskProblem.prepare(scen, parse_variation({"reconstruction": {"samples": 8}}), ("none",))
    assert RECON_NOTE in prob.space.notes and len(prob.prepared.sample_arrays) == 8
    u = np.random.default_rng(0).standard_normal((600, prob.space.dimension))
    u[:300, -1] = -5.0  # all on sample 0
    u[300:, -1] = 5.0  # the same samples on sample 7
    u[300:, :-1] = u[:300, :-1]
    df = prob.evaluate(u)
    assert set(df[SAMPLE_COLUMN][:300]) == {0} and set(df[SAMPLE_COLUMN][300:]) == {7}
    gap0, gap7 = df["min_gap_m"].to_numpy()[:300], df["min_gap_m"].to_numpy()[300:]
    assert not np.allclose(gap0, gap7)  # another posterior trajectory, other outcomes
    assert df["variant_id"].nunique() == 600
