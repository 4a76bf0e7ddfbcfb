"""Rider profiles: the shipped profile, populations, sampling, recorded-rider rule, presets."""

from __future__ import annotations

import json

import numpy as np
import pytest

from vei.calibrate import profile as P
from vei.calibrate.fit import TrackFit
from vei.calibrate.population import population_cases, sample_riders
from vei.config import (
    CALIBRATED_SFM,
    PAPER_SFM,
    SFM_PRESETS,
    RiderPopulationConfig,
    RunConfig,
    case_preset,
    load_config,
)
from vei.errors import ConfigError, InputError


@pytest.fixture(scope="module")
def shipped() -> dict:
    return P.load_profile("calibrated")


def test_shipped_profile_is_valid_and_from_the_shared_data(shipped) -> None:
    assert shipped["format"] == P.PROFILE_FORMAT
    assert P.shipped_profile_path().name == "riders_trafficmonitoring.json"
    assert len(shipped["source"]["scenarios"]) == 9
    assert shipped["populations"]["all"]["n_tracks"] == len(shipped["tracks"]) >= 10
    cats = {t["category"] for t in shipped["tracks"]}
    assert cats == {"escooter", "cyclist"}
    for t in shipped["tracks"]:
        lo_hi = P.SAMPLE_BOUNDS
        for name in P.POP_PARAMETERS:
            assert lo_hi[name][0] <= t[name] <= lo_hi[name][1], (t["key"], name)
    # Too few close encounters in the shared data: A and b are the paper's, flagged.
    rep = shipped["vehicle_repulsion"]
    assert rep["identified"] is False and (rep["a_veh_n"], rep["b_veh_per_m"]) == (100.0, 3.5)


def test_calibrated_preset_matches_the_shipped_profile(shipped) -> None:
    med = shipped["populations"]["all"]["median"]
    c = SFM_PRESETS["calibrated"]
    assert c is CALIBRATED_SFM
    assert c.k_des_nspm == pytest.approx(c.mass_kg / med["tau_s"], rel=0.01)
    assert c.lookahead_m == pytest.approx(med["lookahead_m"], rel=0.01)
    assert c.max_accel_mps2 == pytest.approx(med["max_accel_mps2"], rel=0.01)
    assert c.v0_mps == pytest.approx(med["v0_mps"], rel=0.01)
    assert c.max_speed_mps == pytest.approx(med["max_speed_mps"], rel=0.01)
    assert c.speed_from_recording
    assert (c.a_veh_n, c.b_veh_per_m) == (100.0, 3.5)
    # The paper's values stay available as 'paper'.
    p = SFM_PRESETS["paper"]
    assert p is PAPER_SFM
    assert (p.k_des_nspm, p.a_veh_n, p.b_veh_per_m, p.v0_mps) == (100.0, 100.0, 3.5, 5.0)
    assert not SFM_PRESETS["calibrated-aggressive"].use_vehicle_force
    assert SFM_PRESETS["calibrated-aggressive"].k_des_factor == 2.0


def _fit(key: str, cat: str, **vals: float) -> TrackFit:
    base = dict(v0_mps=3.0, tau_s=0.5, lookahead_m=1.5, max_speed_mps=4.0, max_accel_mps2=5.0)
    base.update(vals)
    return TrackFit(
        key,
        cat,
        k_des_nspm=95 / base["tau_s"],
        median_moving_speed_mps=2.0,
        duration_s=5.0,
        n_windows=3,
        ade_fit_m=0.3,
        near_vehicle=False,
        **base,
    )


def test_population_statistics_by_hand() -> None:
    fits = [
        _fit("s/1", "cyclist", v0_mps=2.0),
        _fit("s/2", "cyclist", v0_mps=8.0),
        _fit("s/3", "escooter"),
    ]
    pops = P.populations(fits)
    assert pops["all"]["n_tracks"] == 3
    # log-mean of v0 over the cyclists: (ln 2 + ln 8) / 2 = ln 4.
    assert pops["cyclist"]["log_mean"][0] == pytest.approx(np.log(4.0))
    assert pops["cyclist"]["median"]["v0_mps"] == pytest.approx(5.0)
    # Fewer than 10 tracks: the category borrows the covariance of all riders.
    assert pops["cyclist"]["covariance_from"] == "all"
    np.testing.assert_allclose(pops["cyclist"]["log_cov"], pops["all"]["log_cov"])
    v = np.log([2.0, 8.0, 3.0])
    assert pops["all"]["log_cov"][0][0] == pytest.approx(np.var(v, ddof=1))


def test_sampling_follows_the_population(shipped) -> None:
    n = 20_000
    s = P.sample_population(shipped, n, category="all", seed=3)
    pop = shipped["populations"]["all"]
    logs = np.log(np.column_stack([s[name] for name in P.POP_PARAMETERS]))
    # Clipping at the physical bounds moves tails only (several riders sit at the 0.5 m
    # look-ahead bound): the medians of the logs are the population's log-means.
    np.testing.assert_allclose(np.median(logs, axis=0), pop["log_mean"], atol=0.03)
    # Away from the bounds mean and covariance are the population's.
    inner = json.loads(json.dumps(shipped))
    inner["populations"]["all"]["log_cov"] = (0.2 * np.asarray(pop["log_cov"])).tolist()
    inner["populations"]["all"]["log_mean"] = np.log([3.0, 0.6, 2.0, 4.0, 3.0]).tolist()
    si = P.sample_population(inner, n, category="all", seed=3)
    li = np.log(np.column_stack([si[name] for name in P.POP_PARAMETERS]))
    np.testing.assert_allclose(li.mean(axis=0), inner["populations"]["all"]["log_mean"], atol=0.01)
    np.testing.assert_allclose(
        np.cov(li, rowvar=False), inner["populations"]["all"]["log_cov"], atol=0.01
    )
    for name in P.POP_PARAMETERS:
        lo, hi = P.SAMPLE_BOUNDS[name]
        assert s[name].min() >= lo and s[name].max() <= hi
    np.testing.assert_allclose(s["k_des_nspm"], 95.0 / s["tau_s"])
    assert np.all(s["a_veh_n"] == 100.0) and np.all(s["b_veh_per_m"] == 3.5)
    # Same seed -> same riders; another seed -> others.
    again = P.sample_population(shipped, n, category="all", seed=3)
    assert all(np.array_equal(s[k], again[k]) for k in s)
    other = P.sample_population(shipped, n, category="all", seed=4)
    assert not np.array_equal(s["v0_mps"], other["v0_mps"])


def test_recorded_rider_rule(shipped) -> None:
    p = P.params_for_recorded_rider(shipped, "escooter", 1.5, 2.2)
    la = shipped["populations"]["escooter"]["median"]["lookahead_m"]
    # The cruise speed v0 L / sqrt(L^2 + 1) equals the recorded median moving speed.
    assert p["v0_mps"] * la / np.hypot(la, 1.0) == pytest.approx(1.5)
    assert p["max_speed_mps"] == 2.2
    assert p["lookahead_m"] == la


def test_malformed_profiles_name_the_field(tmp_path, shipped) -> None:
    bad = json.loads(json.dumps(shipped))
    bad["populations"]["all"]["log_cov"][0][1] = 5.0  # not symmetric
    f = tmp_path / "p.json"
    f.write_text(json.dumps(bad))
    with pytest.raises(InputError, match=r"populations\.all\.log_cov"):
        P.load_profile(f)
    with pytest.raises(InputError, match="not found"):
        P.load_profile(tmp_path / "missing.json")
    f.write_text('{"format": "other"}')
    with pytest.raises(InputError, match="format"):
        P.load_profile(f)


def test_population_in_run_configs_and_cases(tmp_path, shipped) -> None:
    run = load_config(
        {"case": "normal-cap", "rider": {"profile": "calibrated", "sample": 50, "seed": 1}},
        RunConfig,
    )
    assert run.rider == RiderPopulationConfig("calibrated", 50, "escooter", 1)
    cases = population_cases(run.case, run.rider)
    assert [c.name for c in cases[:2]] == ["normal-cap#0", "normal-cap#1"]
    s = sample_riders(run.rider)
    assert [c.sfm.v0_mps for c in cases] == pytest.approx(list(s["v0_mps"]))
    assert all(not c.sfm.speed_from_recording and c.ego_mode == "cap" for c in cases)
    agg = population_cases(case_preset("aggressive"), run.rider)
    # the aggressive rider keeps its amplification over each sampled k_des
    np.testing.assert_allclose([c.sfm.k_des_effective_nspm for c in agg], 2.0 * s["k_des_nspm"])
    with pytest.raises(ConfigError, match="rider 'sfm'"):
        population_cases(case_preset("replay"), run.rider)
    # A profile file works as well as the name.
    f = tmp_path / "mine.json"
    f.write_text(json.dumps(shipped))
    s2 = sample_riders(RiderPopulationConfig(str(f), 50, "escooter", 1))
    np.testing.assert_array_equal(s2["v0_mps"], s["v0_mps"])
