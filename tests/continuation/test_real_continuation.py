"""Continuations on the shared TrafficMonitoring recordings (issue 22's must-show items).

stadtmitte_12_audi_geradeaus_03's cyclist_60 (the primary threat) is first seen 31 s into
the recording, in the middle of the scene, moving at 4.4 m/s: its run-in must join its
first recorded samples within the recorded noise, keep its replayed samples
byte-identical, and bring it in from beyond the car's reach.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from tests.experiments.test_real_criticality import SCENARIOS_WITH_RIDER
from vei.config import ContinuationConfig, SimConfig, case_preset
from vei.continuation import with_continuations
from vei.continuation.path import lateral_accel
from vei.types import CONTINUATION_COLUMN


@pytest.fixture(scope="module")
def scenarios(trafficmonitoring_root, tmp_path_factory):
    """{name: Scenario} of the seven shared recordings with a rider (1 FPS, as the paper)."""
    from vei.datasets.trafficmonitoring import import_scenario
    from vei.io.interaction import read_interaction
    from vei.io.scenario import read_scenario, write_scenario
    from vei.recon.pipeline import reconstruct

    base = tmp_path_factory.mktemp("continued")
    out = {}
    for name in SCENARIOS_WITH_RIDER:
        import_scenario(trafficmonitoring_root, name, base / name / "interaction", rate_hz=1.0)
        write_scenario(
            reconstruct(read_interaction(base / name / "interaction")), base / name / "s"
        )
        out[name] = read_scenario(base / name / "s")
    return out


def test_mid_scene_rider_joins_its_recording(scenarios) -> None:
    scen = scenarios["stadtmitte_12_audi_geradeaus_03"]
    assert scen.primary_threat == "cyclist_60"
    rec = scen.track("cyclist_60")
    assert rec.t_s.iloc[0] == pytest.approx(31.0)  # first seen mid-scene
    cont = with_continuations(scen)
    tr = cont.track("cyclist_60")
    c = tr[CONTINUATION_COLUMN].to_numpy()
    # the replayed samples: byte-identical
    pd.testing.assert_frame_equal(
        tr[~c].drop(columns=CONTINUATION_COLUMN).reset_index(drop=True), rec, check_exact=True
    )
    i0 = int(np.flatnonzero(~c)[0])  # the first recorded sample
    assert i0 > 0 and c[:i0].all()
    # the noise of the recorded first second
    w = rec[rec.t_s <= rec.t_s.iloc[0] + 1.0]
    step = np.hypot(np.diff(w.x_m), np.diff(w.y_m))
    yaw_noise = np.abs(np.diff(np.unwrap(w.yaw_rad))).max()
    sp_noise = np.abs(np.diff(w.speed_mps)).max()
    # position: the join's step is v dt at the recorded first speed, as far from the
    # recorded first step as the recorded steps vary among themselves
    join = float(
        np.hypot(tr.x_m.iloc[i0] - tr.x_m.iloc[i0 - 1], tr.y_m.iloc[i0] - tr.y_m.iloc[i0 - 1])
    )
    assert join == pytest.approx(rec.speed_mps.iloc[0] * 0.05, rel=1e-5)  # chord of an arc
    assert abs(join - step[0]) <= np.ptp(step) + 1e-9
    # heading: no yaw step at the join or in the run-in beyond the recorded noise
    yaw = np.unwrap(tr.yaw_rad.to_numpy()[: i0 + 1])
    assert np.abs(np.diff(yaw)).max() <= yaw_noise + 1e-9
    # speed: the run-in rides at the recorded first speed
    assert tr.speed_mps.iloc[i0 - 1] == rec.speed_mps.iloc[0]
    assert abs(tr.speed_mps.iloc[i0] - tr.speed_mps.iloc[i0 - 1]) <= sp_noise + 1e-9
    rep = cont.extra["continuation"]
    d = rep["reach_m"]
    assert d == pytest.approx(ContinuationConfig().reach_m(rep["settings"]["ego_speed_mps"]))
    assert rep["agents"]["cyclist_60"]["run_in"]["length_m"] >= d - 0.25


@pytest.mark.slow
def test_mid_scene_rider_enters_from_beyond_reach(scenarios) -> None:
    """Replay runs over every time shift in which the rider *enters* during the run (its
    run-in starts after t = 0): at its first present step the box gap to the car is more
    than the car's reaction-plus-stopping distance D; without continuations the same
    shifts bring it in much closer (appearing mid-scene)."""
    from vei.sim.engine import simulate_metrics
    from vei.sim.state import VariantParams, prepare_scenario

    scen = scenarios["stadtmitte_12_audi_geradeaus_03"]
    names = ("collision", "impact_speed_mps", "first_seen_gap_m", "seen_too_late")
    gaps = {}
    for on in (True, False):
        sim = SimConfig(continuation=ContinuationConfig(enabled=on))
        arr = prepare_scenario(scen, sim)
        tr = arr.rider_track
        shifts = np.arange(arr.t_s[0] - tr.t0_s + 0.05, arr.t_s[-1] - tr.t_end_s, 0.25)
        p = VariantParams.from_case(case_preset("replay"), arr, shifts.size, time_shift_s=shifts)
        m = simulate_metrics(arr, p, names=names)
        gaps[on] = m["first_seen_gap_m"].to_numpy()
        hit = m["collision"].to_numpy()
        no_approach = hit & ~np.isfinite(m["impact_speed_mps"].to_numpy())
        assert not (no_approach & ~m["seen_too_late"].to_numpy()).any()
        if on:
            d = with_continuations(scen).extra["continuation"]["reach_m"]
            assert np.nanmin(gaps[on]) > d
            assert not m["seen_too_late"].any()
    assert np.nanmin(gaps[False]) < np.nanmin(gaps[True])


@pytest.mark.parametrize("name", SCENARIOS_WITH_RIDER)
def test_every_continuation_is_plausible(scenarios, name) -> None:
    """Every road user of every shared recording: no yaw step in a continuation beyond the
    largest of its own recording, lateral acceleration within 4 m/s^2 (away from the
    joins, where the recording's own curvature may be larger), no speed step beyond the
    recording's own or the 2 m/s^2 stop."""
    cont = with_continuations(scenarios[name])
    for aid in cont.extra["continuation"]["agents"]:
        tr = cont.track(aid)
        c = tr[CONTINUATION_COLUMN].to_numpy()
        yaw = np.unwrap(tr.yaw_rad.to_numpy())
        step = np.abs(np.diff(yaw))
        in_cont = c[1:] | c[:-1]
        rec_max = step[~in_cont].max() if (~in_cont).any() else 0.0
        assert step[in_cont].max() <= max(rec_max, 5e-3) + 1e-9, aid
        lat = lateral_accel(tr.x_m.to_numpy(), tr.y_m.to_numpy(), tr.t_s.to_numpy())
        inner = c.copy()
        rec_idx = np.flatnonzero(~c)
        for k in (rec_idx[0] - 1, rec_idx[-1] + 1, rec_idx[0] - 2, rec_idx[-1] + 2):
            if 0 <= k < inner.size:
                inner[k] = False
        assert lat[inner].max(initial=0.0) <= 4.0 + 0.1, aid
        sp = tr.speed_mps.to_numpy()
        dsp = np.abs(np.diff(sp))
        rec_dsp = dsp[~in_cont].max() if (~in_cont).any() else 0.0
        assert dsp[in_cont].max() <= max(rec_dsp, 2.0 * 0.05) + 1e-9, aid
