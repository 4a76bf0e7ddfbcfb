"""Case study on the demo: every numeric metric within its physical bounds, severity
columns and verdicts against the no-avoidance run."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from vei.config import case_preset
from vei.experiments.casestudy import add_verdicts, is_no_avoidance, run_casestudy
from vei.experiments.demo_data import demo_interaction
from vei.metrics import SCALAR_METRICS, MetricsConfig
from vei.recon.pipeline import reconstruct

CFG = MetricsConfig()


@pytest.fixture(scope="module")
def demo():
    sc = reconstruct(demo_interaction())
    return sc, run_casestudy(sc)


def _policy(base: str, spec: str):
    c = case_preset(base)
    return replace(c, name=f"{base}/{spec}", ego=replace(c.ego, policy=spec))


def assert_bounded(summary: pd.DataFrame, span_s: float, max_speed_mps: float) -> None:
    """Every numeric scalar metric lies in its physical range (NaN allowed where the
    metric is undefined, inf only where documented). ``span_s``: the run's length, T
    steps x dt (a duration counts steps, so it reaches T dt)."""
    s = summary
    nonneg_le_span = [
        "collision_time_s",
        "t_safe_s",
        "t_attention_s",
        "t_alert_s",
        "t_collision_s",
        "t_interaction_s",
        "pet_s",
    ]
    for col in nonneg_le_span:
        v = s[col].to_numpy(float)
        v = v[np.isfinite(v)]
        assert ((v >= 0) & (v <= span_s + 1e-9)).all(), (col, v)
    si = s["safety_index"].to_numpy(float)
    assert ((si >= 0) & (si <= 1)).all()
    for col in ("min_gap_m", "min_ttc_s", "min_ttc_rel_s"):  # inf = never on course
        v = s[col].to_numpy(float)
        assert (v[~np.isnan(v)] >= 0).all(), col
    drac = s["max_drac_mps2"].to_numpy(float)
    drac = drac[np.isfinite(drac)]
    assert ((drac >= 0) & (drac <= CFG.drac_ceiling_mps2)).all(), drac
    assert (s["max_drac_mps2"][s["drac_unavoidable"]] == CFG.drac_ceiling_mps2).all()
    for col in ("impact_speed_mps", "delta_v_rider_mps", "delta_v_car_mps"):
        v = s[col].to_numpy(float)
        v = v[np.isfinite(v)]
        assert ((v >= 0) & (v <= max_speed_mps)).all(), (col, v)
    risk = s["injury_risk"].to_numpy(float)
    risk = risk[np.isfinite(risk)]
    assert ((risk >= 0) & (risk <= 1)).all()
    assert (s.loc[~s["collision"], "injury_risk"] == 0).all()
    assert s.loc[~s["collision"], "impact_speed_mps"].isna().all()
    assert set(s["impact_side"]) <= {"", "front", "rear", "left", "right"}
    assert set(s["striking"]) <= {"", "car-hits-rider", "rider-hits-car"}
    assert (s["peak_decel_mps2"] >= 0).all() and (s["peak_decel_mps2"] <= 9.81 + 1e-9).all()
    for col in ("ego_speed_std_mps", "ego_speed_mean_mps", "ego_speed_min_mps"):
        v = s[col].to_numpy(float)
        assert ((v >= 0) & (v <= max_speed_mps)).all(), col
    for col in ("ego_max_yaw_step_rad", "ego_max_yaw_rate_radps", "ego_max_lat_accel_mps2"):
        v = s[col].to_numpy(float)
        assert (np.isfinite(v) & (v >= 0)).all(), col
    assert (s["ego_max_lat_accel_mps2"] <= 9.81).all()  # tyre limit ~1 g


def test_every_metric_is_bounded_on_the_demo(demo):
    sc, res = demo
    numeric = [c for c in SCALAR_METRICS if c not in ("impact_side", "striking", "collision")]
    assert set(numeric) <= set(res.summary.columns)
    span = len(res.t_s) * float(res.t_s[1] - res.t_s[0])
    # the ego cruises at ~5.6 m/s, the rider at most its max speed: 20 m/s is generous
    assert_bounded(res.summary, span, 20.0)
    # the demo's collisions are real impacts: before this work their DRAC was 273 m/s^2
    hit = res.summary["collision"].to_numpy(bool)
    assert hit.any() and (res.summary.loc[hit, "impact_speed_mps"] > 0).all()


def test_paper_configurations_verdicts(demo):
    _, res = demo
    s = res.summary.set_index("name")
    assert s.loc["normal-cap", "reference"] == "normal"
    assert s.loc["aggressive-cap", "reference"] == "aggressive"
    assert s.loc["normal", "reference"] == "normal"  # its own reference
    assert s.loc["replay", "reference"] == "replay"
    for name in s.index:
        expected = "avoided" if not s.loc[name, "collision"] else None
        if expected:
            assert s.loc[name, "verdict"] == expected
    assert s.loc["normal", "verdict"] == "not-mitigated"  # a no-avoidance crash


def test_add_verdicts_mitigated_by_hand():
    cases = [case_preset("normal"), case_preset("normal-cap"), case_preset("aggressive-cap")]
    summary = pd.DataFrame(
        {
            "name": ["normal", "normal-cap", "aggressive-cap"],
            "collision": [True, True, True],
            "impact_speed_mps": [5.0, 3.9, 4.5],
        }
    )
    out = add_verdicts(summary, cases, MetricsConfig(mitigation_share=0.2))
    assert list(out["reference"]) == ["normal", "normal", ""]  # no aggressive reference
    assert list(out["verdict"]) == ["not-mitigated", "mitigated", ""]
    assert is_no_avoidance(_policy("normal-cap", "none"))
    assert not is_no_avoidance(_policy("normal", "aeb"))


def test_policies_on_the_demo_are_scored_against_none():
    sc = reconstruct(demo_interaction())
    cases = [_policy("normal", p) for p in ("none", "paper-cap", "aeb")]
    res = run_casestudy(sc, cases=cases)
    s = res.summary.set_index("name")
    assert (s["reference"] == "normal/none").all()
    assert bool(s.loc["normal/none", "collision"])  # the demo rider is hit without avoidance
    assert s.loc["normal/none", "impact_speed_mps"] > 0
    for name in ("normal/paper-cap", "normal/aeb"):
        assert s.loc[name, "verdict"] in ("avoided", "mitigated"), name
    assert_bounded(res.summary, len(res.t_s) * float(res.t_s[1] - res.t_s[0]), 20.0)


def test_every_metric_is_bounded_on_a_real_recording(trafficmonitoring_root, tmp_path):
    """stadtmitte_12: the replayed cyclist is hit at ~10 m/s (the old DRAC said 190 m/s^2
    on the step before contact); every other configuration passes it."""
    from vei.datasets.trafficmonitoring import import_scenario
    from vei.io.interaction import read_interaction

    import_scenario(
        trafficmonitoring_root, "stadtmitte_12_audi_geradeaus_03", tmp_path / "i", rate_hz=1.0
    )
    res = run_casestudy(reconstruct(read_interaction(tmp_path / "i")))
    assert_bounded(res.summary, len(res.t_s) * float(res.t_s[1] - res.t_s[0]), 25.0)
    s = res.summary.set_index("name")
    assert bool(s.loc["replay", "collision"]) and bool(s.loc["replay", "drac_unavoidable"])
    assert s.loc["replay", "max_drac_mps2"] == CFG.drac_ceiling_mps2
    assert 8.0 < s.loc["replay", "impact_speed_mps"] < 12.0
    assert s.loc["replay", "striking"] == "car-hits-rider"
