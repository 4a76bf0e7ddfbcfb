"""The variation model: distributions against scipy.stats, the spec's checks (every bad
input a ConfigError naming the key), the standard space and the rider population."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from vei.config.distributions import Distribution, parse_distribution
from vei.errors import ConfigError
from vei.risk.defaults import CRUISE_SPEED_CV, DEFAULTS, defaults_table
from vei.risk.variation import parse_variation, resolve_space

P = np.array([1e-9, 1e-4, 0.1, 0.5, 0.9, 0.9999, 1 - 1e-9])


def test_quantiles_equal_scipy():
    d = parse_distribution({"dist": "normal", "mean": 2.0, "std": 0.5, "min": 1.5, "max": 4.0}, "x")
    ref = stats.truncnorm((1.5 - 2) / 0.5, (4 - 2) / 0.5, loc=2, scale=0.5)
    assert d.ppf(P) == pytest.approx(ref.ppf(P), rel=1e-9, abs=1e-12)
    assert d.cdf(d.ppf(P)) == pytest.approx(P, rel=1e-7, abs=1e-12)
    ln = parse_distribution({"dist": "lognormal", "median": 3.0, "sigma_log": 0.4}, "x")
    assert ln.ppf(P) == pytest.approx(stats.lognorm(0.4, scale=3.0).ppf(P), rel=1e-9)
    un = parse_distribution({"dist": "uniform", "min": -2, "max": 2}, "x")
    assert un.ppf(P) == pytest.approx(stats.uniform(-2, 4).ppf(P), rel=1e-12)
    # standard normal u -> x: the same as ppf(Phi(u)), with far tails kept
    u = np.array([-8.0, -1.0, 0.0, 1.0, 8.0])
    assert un.from_standard(u) == pytest.approx(un.ppf(stats.norm.cdf(u)), abs=1e-12)
    assert d.from_standard(np.array([8.0]))[0] < 4.0
    assert d.from_standard(np.array([8.0]))[0] == pytest.approx(
        ref.ppf(stats.norm.cdf(8.0)), abs=1e-9
    )
    mid = np.linspace(-5.0, 5.0, 41)
    assert d.from_standard(mid) == pytest.approx(ref.ppf(stats.norm.cdf(mid)), rel=1e-9)
    # a cross-entropy stage reaches u = 10 and beyond: still inside the window, finite,
    # increasing (was Phi(10) rounded to 1: a cruise speed of inf m/s); an untruncated
    # upper tail follows mean + std u (hand value: 5.6 + 1.232 x 10 m/s; the window's
    # 1e-4 of probability below 1 m/s moves it by 1e-5 m/s)
    far = np.array([-40.0, -10.0, -8.3, 8.3, 10.0, 40.0])
    cruise = parse_distribution({"dist": "normal", "mean": 5.6, "std": 1.232, "min": 1.0}, "v")
    x = cruise.from_standard(far)
    assert np.isfinite(x).all() and (np.diff(x) >= 0).all() and x[0] == pytest.approx(1.0)
    assert x[4] == pytest.approx(5.6 + 1.232 * 10.0, abs=1e-4)
    boxed = d.from_standard(far)
    assert np.isfinite(boxed).all() and 1.5 <= boxed.min() and boxed.max() <= 4.0
    cut = parse_distribution({"dist": "lognormal", "median": 3.0, "sigma_log": 0.4,
                              "min": 1.0}, "x")  # fmt: skip
    assert np.isfinite(cut.from_standard(far)).all()
    assert cut.from_standard(np.array([10.0]))[0] == pytest.approx(3.0 * np.exp(4.0), rel=1e-3)


def test_recorded_mean_resolves_per_scenario():
    d = parse_distribution({"dist": "normal", "mean": "recorded", "cv": 0.22, "min": 1.0},
                           "v", allow_recorded=True)  # fmt: skip
    assert not d.resolved
    r = d.resolve(6.0)
    assert (r.mean, r.std, r.low) == (6.0, pytest.approx(1.32), 1.0)
    with pytest.raises(ConfigError, match="only known for ego.cruise_speed_mps"):
        parse_distribution({"dist": "normal", "mean": "recorded", "cv": 0.2}, "v")


@pytest.mark.parametrize(
    ("raw", "message"),
    [
        ({"dist": "normal", "mean": 1.0, "std": -1.0}, "std must be > 0"),
        ({"dist": "normal", "mean": 0.0, "std": 1.0, "min": 50.0}, "impossible parameters"),
        ({"dist": "uniform", "min": 2.0, "max": 1.0}, "min < max"),
        ({"dist": "lognormal", "median": -1.0, "sigma_log": 0.3}, "median must be > 0"),
        ({"dist": "normal", "mean": 1.0}, "exactly one of 'std' and 'cv'"),
        ({"dist": "beta", "a": 1}, "dist must be one of"),
        ({"dist": "uniform", "min": 0, "max": 1, "mean": 3}, "unknown key"),
        ({"dist": "normal", "mean": float("nan"), "std": 1}, "finite"),
    ],
)
def test_impossible_distributions_are_refused(raw, message):
    with pytest.raises(ConfigError, match=message) as info:
        parse_distribution(raw, "spec.yaml: variation.time_shift_s")
    assert "spec.yaml: variation.time_shift_s" in str(info.value)


@pytest.mark.parametrize(
    ("raw", "message"),
    [
        ({"variation": {}}, "variation is empty"),
        ({"variation": None}, "variation is empty"),
        ({"variation": {"rider": None}}, "the variation is empty"),
        ({"varation": {}}, "unknown key"),
        (
            {"variation": {"cap.t_safe": {"dist": "uniform", "min": 1, "max": 2}}},
            "renamed|not a varied",
        ),
        (
            {"variation": {"cap.a_min_mps2": {"dist": "normal", "mean": -6, "std": 1}}},
            "must be < 0",
        ),
        ({"variation": {"ego.policy": {"dist": "uniform", "min": 0, "max": 1}}}, "--policy"),
        ({"base": "replay"}, "replays the rider"),
        ({"seed": -1}, "seed"),
        ({"injury_relevant_speed_mps": 0}, "injury_relevant_speed_mps"),
        ({"time_shift_reference": "recording"}, "auto or zero"),
    ],
)
def test_bad_specs_are_refused(raw, message):
    with pytest.raises(ConfigError, match=message):
        parse_variation(raw, "risk.yaml")


def test_defaults_and_round_trip():
    m = parse_variation({})
    assert m.dimension_names[:2] == ("time_shift_s", "ego.cruise_speed_mps")
    # + the recorded rider's speed and the population's tau, look-ahead, acceleration limit
    assert m.dimension_names[2:] == (
        "rider.speed",
        "rider.tau_s",
        "rider.lookahead_m",
        "rider.max_accel_mps2",
    )
    again = parse_variation(m.to_dict())
    assert again == m and again.digest() == m.digest()
    names = {d.name for d in DEFAULTS}
    assert names == {"time_shift_s", "ego.cruise_speed_mps", "rider"}
    assert f"cv {CRUISE_SPEED_CV}" in defaults_table() or "cv" in defaults_table()


def test_docs_show_todays_defaults_table():
    from pathlib import Path

    from vei.risk.defaults import TABLE_BEGIN, TABLE_END

    doc = (Path(__file__).resolve().parents[2] / "docs" / "risk.md").read_text()
    inner = doc.split(TABLE_BEGIN)[1].split(TABLE_END)[0]
    assert inner.strip() == defaults_table().strip()


#: The defaults before issue 31 (population rider, within-drive cruise spread).
OLD_DEFAULTS = {
    "variation": {
        "time_shift_s": {"dist": "uniform", "min": -2.0, "max": 2.0},
        "ego.cruise_speed_mps": {"dist": "normal", "mean": "recorded", "cv": 0.22, "min": 1.0},
        "rider": {"profile": "calibrated", "category": "auto"},
    }
}


def test_space_maps_standard_normal_to_the_distributions():
    m = parse_variation(OLD_DEFAULTS)
    space = resolve_space(m, recorded_cruise_mps=6.0, rider_category="cyclist")
    rng = np.random.default_rng(0)
    u = rng.standard_normal((40_000, space.dimension))
    p = space.to_params(u)
    ts = p["time_shift_s"].to_numpy()
    assert ts.min() >= -2 and ts.max() <= 2
    assert stats.kstest(ts, stats.uniform(-2, 4).cdf).pvalue > 1e-3
    v = p["ego.cruise_speed_mps"].to_numpy()
    assert v.min() >= 1.0
    assert np.mean(v) == pytest.approx(6.0, abs=0.03) and np.std(v) == pytest.approx(1.32, rel=0.03)
    # the rider population: log-parameters with the profile's mean and covariance
    from vei.calibrate.profile import POP_PARAMETERS, load_profile

    pop = load_profile("calibrated")["populations"]["cyclist"]
    logs = np.log(np.column_stack([
        p["rider.v0_mps"], 95.0 / p["rider.k_des_nspm"], p["rider.lookahead_m"],
        p["rider.max_speed_mps"], p["rider.max_accel_mps2"],
    ]))  # fmt: skip
    assert len(POP_PARAMETERS) == 5
    # clipping to the sample bounds moves the tails a little: compare medians / spreads
    assert np.median(logs, axis=0) == pytest.approx(np.asarray(pop["log_mean"]), abs=0.03)
    sd = np.sqrt(np.diag(np.asarray(pop["log_cov"])))
    iqr = np.subtract(*np.quantile(logs, [0.75, 0.25], axis=0)) / 1.349
    assert iqr == pytest.approx(sd, rel=0.06)
    assert p["rider.mass_kg"].eq(95.0).all()


def test_fixed_values_and_fixed_distributions_reach_the_parameters():
    m = parse_variation({
        "variation": {"time_shift_s": {"dist": "uniform", "min": -1, "max": 1},
                      "cap.t_safe_s": 1.5},
        "fixed": {"cap.d_buf_m": 2.0},
    })  # fmt: skip
    # a variation section replaces the defaults: no rider population unless it names one
    assert m.dimension_names == ("time_shift_s",) and m.rider is None
    space = resolve_space(m, 5.0, "escooter")
    p = space.to_params(np.zeros((3, space.dimension)))
    assert p["cap.t_safe_s"].tolist() == [1.5] * 3 and p["cap.d_buf_m"].tolist() == [2.0] * 3
    assert p["time_shift_s"].tolist() == [0.0] * 3
    assert math.isclose(Distribution("uniform", low=0, high=1).ppf(np.array([0.25]))[0], 0.25)


def test_continuations_reach_for_the_fast_end_of_the_sampled_cruise_speeds():
    """Issue 22 under a variation: every sample's riders enter from beyond the car's reach
    at the 99.9 % quantile of the cruise speed (hand value: a normal of mean 5 m/s, std
    1 m/s cut below at 1 m/s puts it at 5 + 3.0902 m/s), its value when fixed, None
    when the model leaves the cruise speed to the base configuration."""
    from vei.risk.variation import reach_speed_mps

    drawn = parse_variation(
        {
            "variation": {
                "ego.cruise_speed_mps": {
                    "dist": "normal",
                    "mean": "recorded",
                    "cv": 0.2,
                    "min": 1.0,
                }
            }
        }  # fmt: skip
    )
    assert reach_speed_mps(drawn, 5.0) == pytest.approx(5.0 + 3.0902, abs=1e-3)
    fixed = parse_variation(
        {
            "variation": {"time_shift_s": {"dist": "uniform", "min": -1, "max": 1}},
            "fixed": {"ego.cruise_speed_mps": 7.5},
        }  # fmt: skip
    )
    assert reach_speed_mps(fixed, 5.0) == 7.5
    shift_only = parse_variation(
        {"variation": {"time_shift_s": {"dist": "uniform", "min": -1, "max": 1}}}
    )
    assert reach_speed_mps(shift_only, 5.0) is None


def test_default_rider_is_centred_on_the_recorded_rider_and_bounded():
    from vei.calibrate.profile import cruise_v0_mps, load_profile
    from vei.risk.defaults import RIDER_MAX_SPEED_MPS, RIDER_SPEED_SIGMA_LOG

    m = parse_variation({})
    space = resolve_space(m, 6.0, "cyclist", rider_speed=(3.0, 4.5))
    # u = 0: the rider's cruise speed is its recorded median, its limit 1.5 x that
    p = space.to_params(np.zeros((1, space.dimension)))
    med = load_profile("calibrated")["populations"]["cyclist"]
    la = float(p["rider.lookahead_m"].iloc[0])
    assert la == pytest.approx(np.exp(med["log_mean"][2]), rel=1e-9)
    assert p["rider.v0_mps"].iloc[0] == pytest.approx(float(cruise_v0_mps(3.0, la, 1.0)))
    assert p["rider.max_speed_mps"].iloc[0] == pytest.approx(4.5)
    # one sigma up on rider.speed: exp(sigma) times faster
    u = np.zeros((1, space.dimension))
    u[0, space.names.index("rider.speed")] = 1.0
    q = space.to_params(u)
    assert q["rider.max_speed_mps"].iloc[0] == pytest.approx(4.5 * np.exp(RIDER_SPEED_SIGMA_LOG))
    # the tails stay within the cyclist's bound
    rng = np.random.default_rng(1)
    big = space.to_params(rng.standard_normal((20_000, space.dimension)) * 3)
    cap = RIDER_MAX_SPEED_MPS["cyclist"]
    assert big["rider.v0_mps"].max() <= cap + 1e-9
    assert big["rider.max_speed_mps"].max() <= cap + 1e-9
    assert big["ego.cruise_speed_mps"].max() <= 15.3 + 1e-9


def test_population_riders_are_bounded_too():
    raw = {"variation": {"time_shift_s": {"dist": "uniform", "min": -1, "max": 1},
                         "rider": {"profile": "calibrated", "category": "auto",
                                   "max_speed_mps": {"cyclist": 6.0}}}}  # fmt: skip
    space = resolve_space(parse_variation(raw), 6.0, "cyclist")
    p = space.to_params(np.random.default_rng(2).standard_normal((5000, space.dimension)) * 3)
    assert p["rider.v0_mps"].max() == pytest.approx(6.0)
    assert p["rider.max_speed_mps"].max() == pytest.approx(6.0)


@pytest.mark.parametrize(
    ("rider", "message"),
    [
        ({"speed": "fast"}, "rider.speed must be population or recorded"),
        ({"speed": "recorded"}, "rider.speed_sigma_log must be a number"),
        ({"speed_sigma_log": 0.3}, "speed_sigma_log needs speed: recorded"),
        ({"max_speed_mps": {"horse": 5}}, "unknown category 'horse'"),
        ({"max_speed_mps": {"cyclist": 40}}, r"max_speed_mps.cyclist must be in \[0.5, 15\]"),
        ({"colour": "red"}, "variation.rider: expected"),
    ],
)
def test_bad_rider_specs_name_the_key(rider, message):
    raw = {"variation": {"rider": {"profile": "calibrated", **rider}}}
    with pytest.raises(ConfigError, match=message):
        parse_variation(raw, "risk.yaml")


def test_every_model_describes_itself():
    d = parse_variation({}).description()
    assert "vei default variation" in d and "leave-one-recording-out" in d and "8/9" in d
    own = parse_variation({"variation": {"time_shift_s": 0.5, "cap.t_safe_s": {
        "dist": "uniform", "min": 1, "max": 2}}}, "mine.yaml")  # fmt: skip
    assert own.description() == (
        "conditional on the variation model the risk spec mine.yaml; not validated against "
        "held-out data"
    )
    assert own.to_dict()["model"]["description"] == own.description()


def test_a_standing_rider_is_centred_on_the_population_median():
    space = resolve_space(parse_variation({}), 6.0, "escooter", rider_speed=(float("nan"),) * 2)
    assert any("does not move in its recording" in n for n in space.notes)
    med, p99 = space.rider_speed
    assert 0.5 < med <= p99


def test_reconstruction_samples_are_one_more_dimension():
    from vei.sweep.spec import SAMPLE_COLUMN

    m = parse_variation({"reconstruction": {"samples": 4}})
    assert m.dimension_names[-1] == "reconstruction.sample" and m.dimension == 7
    assert parse_variation(m.to_dict()) == m
    space = resolve_space(m, 6.0, "cyclist", rider_speed=(3.0, 4.5))
    u = np.zeros((5, space.dimension))
    # Phi(u) in [k/4, (k+1)/4) -> sample k: u = -1 (0.159) -> 0, 0 -> 2, 0.5 (0.69) -> 2,
    # 1 (0.841) -> 3, 9 -> 3 (never 4)
    u[:, -1] = [-1.0, 0.0, 0.5, 1.0, 9.0]
    assert list(space.to_params(u)[SAMPLE_COLUMN]) == [0, 2, 2, 3, 3]
    with pytest.raises(ConfigError, match="reconstruction.samples must be an integer >= 1"):
        parse_variation({"reconstruction": {"samples": 0}}, "risk.yaml")
