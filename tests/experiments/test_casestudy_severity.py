"""Case study on the demo: every numeric metric within its physical bounds, severity
columns and verdicts against the no-avoidance run."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from vei.config import EgoConfig, case_preset
from vei.experiments.casestudy import add_verdicts, is_no_avoidance, run_casestudy
from vei.experiments.demo_data import demo_interaction
from vei.metrics import SCALAR_METRICS, MetricsConfig
from vei.recon.pipeline import reconstruct

CFG = MetricsConfig()
#: the DRAC ceiling of these runs: their ego.max_decel_mps2 (the car's full brake)
CEILING = EgoConfig().max_decel_mps2


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
    assert ((drac >= 0) & (drac <= CEILING)).all(), drac
    assert (s["max_drac_mps2"][s["drac_unavoidable"]] == CEILING).all()
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
    # the demo's collisions are real impacts: before this work their DRAC was 273 m/s^2;
    # at >= 0.5 s before contact braking at < 1 m/s^2 would have avoided them (1.31 m/s^2
    # since issue 22: the rider, arriving slowly along its run-in, is on the car's course
    # earlier)
    s = res.summary.set_index("name")
    assert not s["drac_unavoidable"].any() and (s["max_drac_mps2"] < 1.5).all()
    # impact speed of 'normal' by hand from the time series: |v_ego - v_rider| on the
    # step before the first contact, v = speed (cos yaw, sin yaw) (~0.83 m/s)
    f = res.frame[res.frame["config"] == "normal"]
    ego = f[f["agent_id"] == "ego"].reset_index(drop=True)
    rid = f[f["agent_id"] == sc.primary_threat].reset_index(drop=True)
    k = int(np.argmax(rid["collided"].to_numpy(bool)))
    assert k > 0

    def vel(row):
        return row["speed_mps"] * np.array([np.cos(row["yaw_rad"]), np.sin(row["yaw_rad"])])

    v_rel = np.linalg.norm(vel(ego.iloc[k - 1]) - vel(rid.iloc[k - 1]))
    # 0.80 m/s (0.83 before issue 22: the rider's recorded velocity at its first sample is
    # now a central difference with its run-in, no longer a one-sided one)
    assert 0.77 < v_rel < 0.86
    assert s.loc["normal", "impact_speed_mps"] == pytest.approx(v_rel, rel=1e-9)
    m_c, m_r = CFG.car_mass_kg, case_preset("normal").sfm.mass_kg
    assert s.loc["normal", "delta_v_rider_mps"] == pytest.approx(m_c / (m_c + m_r) * v_rel)


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
    # a no-avoidance run is the reference, not a verdict against itself
    assert s.loc["normal", "verdict"] == "reference"
    assert s.loc["replay", "verdict"] == "reference"
    assert s.loc["normal-cap", "verdict"] == "avoided"


def test_add_verdicts_mitigated_by_hand():
    cases = [case_preset("normal"), case_preset("normal-cap"), case_preset("aggressive-cap")]
    summary = pd.DataFrame(
        {
            "name": ["normal", "normal-cap", "aggressive-cap"],
            "collision": [True, True, True],
            "impact_speed_mps": [5.0, 3.9, 4.5],
        }
    )
    # aggressive-cap's reference would be 'aggressive' (another SFM): missing -> no verdict,
    # not a silent comparison with 'normal' or with row 0
    out = add_verdicts(summary, cases, MetricsConfig(mitigation_share=0.2))
    assert list(out["reference"]) == ["normal", "normal", ""]
    assert list(out["verdict"]) == ["reference", "mitigated", ""]
    out = add_verdicts(summary.iloc[:2], cases[:2], MetricsConfig(mitigation_share=0.2))
    assert list(out["reference"]) == ["normal", "normal"]
    assert list(out["verdict"]) == ["reference", "mitigated"]
    # another cruise speed is another scenario: its 'none' run is not the reference
    fast = replace(cases[1], name="fast-cap", ego=replace(cases[1].ego, cruise_speed_mps=15.0))
    frame = pd.DataFrame(
        {"name": ["normal", "fast-cap"], "collision": [True, True], "impact_speed_mps": [5.0, 1.0]}
    )
    out = add_verdicts(frame, [cases[0], fast])
    assert list(out["reference"]) == ["normal", ""] and out["verdict"].iloc[1] == ""
    fast_none = replace(fast, name="fast", ego=replace(fast.ego, policy="none"))
    frame = pd.DataFrame(
        {
            "name": ["normal", "fast-cap", "fast"],
            "collision": [True, True, True],
            "impact_speed_mps": [5.0, 4.5, 5.0],
        }
    )
    out = add_verdicts(frame, [cases[0], fast, fast_none])
    assert list(out["reference"]) == ["normal", "fast", "fast"]
    assert list(out["verdict"]) == ["reference", "not-mitigated", "reference"]
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
    assert s.loc["replay", "max_drac_mps2"] == CEILING
    assert 8.0 < s.loc["replay", "impact_speed_mps"] < 12.0
    assert s.loc["replay", "striking"] == "car-hits-rider"
