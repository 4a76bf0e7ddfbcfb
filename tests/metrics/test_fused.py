"""The compiled per-run metrics (vei.metrics.fused) equal summarize() bit for bit.

Every comparison is exact (np.testing.assert_array_equal: ==, NaN == NaN; the labels as
strings): the fused rows replace summarize's in sweeps, so no tolerance is allowed.
Traces come from the engine (NumPy kernel: only the metrics are under test here) on the
demo, the four-rider scene and the standing-rider scene, from a real TrafficMonitoring
recording (stadtmitte_12), and hand-edited edge cases.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("numba")

from vei.config import ContinuationConfig, SimConfig, case_preset  # noqa: E402
from vei.metrics import MetricsConfig, as_timeseries_trace, summarize  # noqa: E402
from vei.metrics.fused import fused_summary, pairwise_sum  # noqa: E402
from vei.metrics.fused_layout import FUSED_METRICS, config_vector, metrics_frame  # noqa: E402
from vei.sim.engine import run_cases, simulate  # noqa: E402
from vei.sim.state import VariantParams, prepare_scenario  # noqa: E402

#: Thresholds other than the paper's: the other TTC scope, a low DRAC ceiling (the flag
#: drac_unavoidable fires), a fixed rider mass, a shorter reaction time, other zones.
OTHER_CFG = MetricsConfig(
    safe_ttc_s=3.0,
    alert_ttc_s=1.5,
    ttc_scope="all",
    drac_ceiling_mps2=2.0,
    reaction_time_s=0.2,
    rider_mass_kg=80.0,
    car_mass_kg=1200.0,
    injury_intercept=5.0,
    injury_slope_per_kmh=0.1,
)


def assert_same(trace, cfg=None, params=None) -> pd.DataFrame:
    """fused_summary(trace) == summarize(as_timeseries_trace(trace)), column by column."""
    ref = summarize(as_timeseries_trace(trace), cfg, names=FUSED_METRICS, params=params)
    got = fused_summary(trace, cfg, names=FUSED_METRICS, params=params)
    assert list(got.columns) == list(ref.columns)
    for name in FUSED_METRICS:
        assert got[name].dtype == ref[name].dtype, name
        np.testing.assert_array_equal(got[name].to_numpy(), ref[name].to_numpy(), err_msg=name)
        if ref[name].dtype == np.float64:  # bit for bit: also the sign of a zero
            np.testing.assert_array_equal(np.signbit(got[name]), np.signbit(ref[name]), name)
    return ref


def _params_of(params: VariantParams) -> dict[str, np.ndarray]:
    return {"rider_mass_kg": params.mass_kg, "ego_max_decel_mps2": params.max_decel_mps2_ego}


@pytest.fixture(scope="module")
def demo():
    from vei.experiments.demo_data import demo_interaction
    from vei.recon.pipeline import reconstruct
    from vei.sim.timeshift import find_time_shift

    scenario = reconstruct(demo_interaction())
    # without continuations (the rider appears at its first recorded sample): the grid
    # then has contacts without an approach step, an edge case the metrics must score
    sim = SimConfig(continuation=ContinuationConfig(enabled=False))
    arrays = prepare_scenario(scenario, sim)
    return scenario, arrays, float(find_time_shift(scenario, sim=sim))


@pytest.fixture(scope="module")
def demo_grid(demo):
    """Time shifts x cruise speeds x (normal-cap, normal without CAP): the NumPy kernel."""
    _, arrays, base = demo
    shifts = base + np.linspace(-3.0, 3.0, 13)
    parts = []
    for case in ("normal-cap", "normal"):
        for cruise in (3.0, 5.6, 9.0, 12.0):
            p = VariantParams.from_case(case_preset(case), arrays, shifts.size, time_shift_s=shifts)
            parts.append(p.with_values(cruise_speed_mps=np.full(shifts.size, cruise)))
    params = VariantParams.concat(parts)
    return params, simulate(arrays, params, record="full", kernel="numpy").to_trace()


def test_pairwise_sum_is_numpys_row_sum() -> None:
    """The port of NumPy's pairwise summation: 0 + pairwise over the row, bit for bit,
    for every length up to past two splits (and the 500-step runs of the demo)."""
    rng = np.random.default_rng(0)
    for n in [*range(1, 300), 501, 1000, 4097]:
        x = rng.standard_normal((2, n)) * 10.0 ** rng.uniform(-3, 3, (2, n))
        for row in range(2):
            assert pairwise_sum(x[row], 0, n) == x.sum(axis=1)[row], n


def test_box_gap_and_time_to_contact_equal_vei_boxes() -> None:
    """The scalar ports equal vei.boxes on random pairs, exactly touching pairs (gap 0 by
    the overlap test's 1e-9 m slack) and boxes far apart."""
    from vei.boxes import box_corners, box_gap, time_to_contact
    from vei.metrics import fused_ops as fused

    rng = np.random.default_rng(2)
    n = 4000
    ax, ay, bx, by = rng.uniform(-6, 6, (4, n))
    ayaw, byaw = rng.uniform(-4, 4, (2, n))
    al, bl = rng.uniform(0.5, 5.0, (2, n))
    aw, bw = rng.uniform(0.3, 2.0, (2, n))
    ayaw[:500], byaw[:500], ay[:500], by[:500] = 0.0, 0.0, 0.0, 0.0
    bx[:500] = ax[:500] + 0.5 * (al[:500] + bl[:500])  # end to end: touching
    bx[500:600] += 1e9
    ref = box_gap(ax, ay, ayaw, al, aw, bx, by, byaw, bl, bw)
    cols = (ax, ay, ayaw, al, aw, bx, by, byaw, bl, bw)
    got = np.array([fused.box_gap(*(c[i] for c in cols)) for i in range(n)])
    np.testing.assert_array_equal(got, ref)
    assert (ref[:500] == 0).all() and (ref > 0).sum() > 1000
    ca = box_corners(ax, ay, ayaw, al, aw)
    cb = box_corners(bx, by, byaw, bl, bw)
    v = rng.uniform(-10, 10, (n, 2))
    ref = time_to_contact(ca, cb, v)
    got = np.array([fused.time_to_contact(ca[i], cb[i], v[i, 0], v[i, 1]) for i in range(n)])
    np.testing.assert_array_equal(got, ref)
    assert np.isfinite(ref).sum() > 100 and np.isinf(ref).sum() > 100


def test_demo_grid_bit_identical(demo_grid) -> None:
    """Collisions (with and without an approach step), near misses, braking and free
    runs: every metric equal, with the runs' own masses / brakes and with other thresholds."""
    params, trace = demo_grid
    ref = assert_same(trace, params=_params_of(params))
    hit = ref["collision"].to_numpy()
    assert 10 < hit.sum() < hit.size - 10  # both outcomes
    assert ref["impact_speed_mps"][hit].isna().any()  # contact without an approach step
    assert ref["impact_speed_mps"][hit].notna().sum() > 10
    assert set(ref["striking"]) == {"", "car-hits-rider", "rider-hits-car"}
    assert ((ref["min_gap_m"] < 1.0) & ~ref["collision"]).any()  # near misses
    assert (ref["peak_decel_mps2"] > 2.0).any()  # the CAP brakes
    assert (ref["max_drac_mps2"] > 0).sum() > 20
    rng = np.random.default_rng(1)
    own = {
        "rider_mass_kg": rng.uniform(60.0, 130.0, params.batch_size),
        "ego_max_decel_mps2": rng.uniform(1.0, 9.0, params.batch_size),
    }
    ref = assert_same(trace, params=own)
    assert ref["drac_unavoidable"].any() and not ref["drac_unavoidable"].all()
    ref = assert_same(trace, OTHER_CFG, params=own)
    assert ref["drac_unavoidable"].sum() > 5


def test_edge_cases(demo_grid) -> None:
    """Rider never active; collision on the first step; collision on the rider's first
    active step (no approach: NaN impact, '' striking); NaN rider yaw / speed and
    non-finite ego accelerations; a one-step run."""
    params, trace = demo_grid
    b = 6
    sel = list(range(b))
    tr = replace(
        trace,
        **{
            f: np.array(getattr(trace, f)[sel])
            for f in (
                "ego_xy_m", "ego_yaw_rad", "ego_speed_mps", "ego_accel_mps2", "other_xy_m",
                "other_yaw_rad", "other_speed_mps", "other_vel_mps", "other_active", "collided",
            )
        },
    )  # fmt: skip
    tr.other_active[0] = False  # never active
    tr.collided[1] = True  # collided from the first step
    first = int(np.argmax(tr.other_active[2]))
    assert first > 0
    tr.collided[2] = False
    tr.collided[2, first:] = True  # contact on the rider's first active step
    act3 = np.flatnonzero(tr.other_active[3])
    tr.other_yaw_rad[3, act3[::3]] = np.nan
    tr.other_speed_mps[3, act3[1::4]] = np.nan
    tr.ego_accel_mps2[4, 10:13] = [np.nan, np.inf, -np.inf]
    tr.collided[5, 300:] = True
    tr.other_xy_m[5, 310:, 0] = np.nan  # a non-finite position while active
    ref = assert_same(tr)
    assert np.isnan(ref["safety_index"][0]) and np.isnan(ref["min_gap_m"][0])
    assert ref["collision"][1] and ref["collision_time_s"][1] == trace.t_s[0]
    assert np.isnan(ref["impact_speed_mps"][1]) and ref["striking"][1] == ""
    assert ref["collision"][2] and np.isnan(ref["impact_speed_mps"][2])
    assert ref["striking"][2] == "" and ref["impact_side"][2] != ""
    assert ref["peak_decel_mps2"][4] > 1e300  # nan_to_num(-inf) -> -max float
    assert_same(tr, OTHER_CFG)
    one = replace(
        tr,
        t_s=tr.t_s[:1],
        **{
            f: np.ascontiguousarray(getattr(tr, f)[:, :1])
            for f in (
                "ego_xy_m", "ego_yaw_rad", "ego_speed_mps", "ego_accel_mps2", "other_xy_m",
                "other_yaw_rad", "other_speed_mps", "other_vel_mps", "other_active", "collided",
            )
        },
    )  # fmt: skip
    assert_same(one)


def test_gap_bound_and_reused_yaws(demo_grid) -> None:
    """The paths the compiled loop takes to skip work: yaws repeated bit for bit and
    alternating 0.0 / -0.0 (cos / sin reused only for the same bits), the rider jumping
    far away and back (the gap's lower bound decides the step, DRAC deferred), a NaN
    ego yaw (no bound), all with the paper's and the other thresholds."""
    params, trace = demo_grid
    sel = [10, 30, 60, 90]
    fields = (
        "ego_xy_m", "ego_yaw_rad", "ego_speed_mps", "ego_accel_mps2", "other_xy_m",
        "other_yaw_rad", "other_speed_mps", "other_vel_mps", "other_active", "collided",
    )  # fmt: skip
    tr = replace(trace, **{f: np.array(getattr(trace, f)[sel]) for f in fields})
    n = tr.t_s.size
    zeros = np.where(np.arange(n) % 3 == 0, -0.0, 0.0)
    tr.ego_yaw_rad[0] = zeros
    tr.other_yaw_rad[0] = zeros[::-1]
    tr.ego_yaw_rad[1, 1::2] = tr.ego_yaw_rad[1, : n - 1 : 2]  # each yaw twice in a row
    act = np.flatnonzero(tr.other_active[2])
    far = act[: act.size // 2]
    tr.other_xy_m[2, far] += 1e6
    tr.ego_yaw_rad[3, act[::5]] = np.nan
    for run in range(4):
        assert tr.other_active[run].sum() > 20
    for cfg in (None, OTHER_CFG):
        ref = assert_same(tr, cfg, params=_params_of(params.take(np.array(sel))))
        assert np.isfinite(ref["min_gap_m"]).all()


def test_standing_rider_and_four_riders() -> None:
    """A rider standing in the lane (speed 0, the car brakes or hits), and the crossing
    scene with three more social-force e-scooters (the primary rider scored)."""
    from vei.sim.testing import four_rider_scenario, standing_rider_scenario

    cases = ["replay", "normal", "normal-cap", "aggressive-cap"]
    res = run_cases(standing_rider_scenario(), cases)
    ref = assert_same(res.to_trace(), params=_params_of(res.params))
    assert (ref["ego_speed_min_mps"] == 0).any()
    arrays = prepare_scenario(four_rider_scenario(), SimConfig(sfm_riders="all"))
    parts = [
        VariantParams.from_case(case_preset(c), arrays, 5, time_shift_s=np.linspace(3.5, 6.5, 5))
        for c in cases
    ]
    params = VariantParams.concat(parts)
    trace = simulate(arrays, params, kernel="numpy").to_trace()
    ref = assert_same(trace, params=_params_of(params))
    assert ref["collision"].any() and not ref["collision"].all()


def test_real_recording_stadtmitte_12(trafficmonitoring_root, tmp_path_factory) -> None:
    """A real TrafficMonitoring recording, replayed and with the social-force rider: the
    engine's trace and the trace read back from its long time series (what vei run
    scores) both equal summarize."""
    from vei.datasets.trafficmonitoring import import_scenario
    from vei.io.interaction import read_interaction
    from vei.metrics import trace_from_timeseries
    from vei.recon.pipeline import reconstruct
    from vei.sim.timeshift import find_time_shift

    out = tmp_path_factory.mktemp("stadtmitte") / "i"
    import_scenario(trafficmonitoring_root, "stadtmitte_12_audi_geradeaus_03", out, rate_hz=1.0)
    scenario = reconstruct(read_interaction(out))
    shift = float(find_time_shift(scenario))
    res = run_cases(scenario, ["replay", "normal"], time_shift_s=shift)
    ref = assert_same(res.to_trace(), params=_params_of(res.params))
    # the replayed cyclist is hit by the front at ~10 m/s; the social-force one escapes
    assert ref["collision"].tolist() == [True, False]
    assert ref["impact_side"][0] == "front" and 9.0 < ref["impact_speed_mps"][0] < 11.0
    assert np.isfinite(ref["min_gap_m"]).all()
    frame = res.to_frame()
    trace, runs = trace_from_timeseries(
        frame,
        other_id=res.rider_id,
        ego_dims_m=(res.ego_length_m, res.ego_width_m),
        other_dims_m=(res.rider_length_m, res.rider_width_m),
    )
    assert [r[0] for r in runs] == ["replay", "normal"]
    ref2 = summarize(trace, names=FUSED_METRICS, params=_params_of(res.params))
    got = fused_summary(trace, names=FUSED_METRICS, params=_params_of(res.params))
    for name in FUSED_METRICS:
        np.testing.assert_array_equal(got[name].to_numpy(), ref2[name].to_numpy(), err_msg=name)
    assert_same(res.to_trace(), OTHER_CFG, params=_params_of(res.params))


def test_config_vector_and_frame_layout() -> None:
    """The config vector carries NaN for 'the run's own' ceiling / mass; a row becomes the
    summarize columns (bools, labels with '' for none)."""
    v = config_vector(MetricsConfig())
    assert np.isnan(v[4]) and np.isnan(v[7]) and v[2] == 1.0
    assert config_vector(OTHER_CFG)[2] == 0.0
    rows = np.zeros((2, len(FUSED_METRICS)))
    i = FUSED_METRICS.index
    rows[0, i("collision")] = 1.0
    rows[:, i("impact_side")] = [2.0, -1.0]
    rows[:, i("striking")] = [1.0, -1.0]
    f = metrics_frame(rows, ("collision", "impact_side", "striking", "min_gap_m"))
    assert f["collision"].tolist() == [True, False]
    assert f["impact_side"].tolist() == ["left", ""]
    assert f["striking"].tolist() == ["rider-hits-car", ""]
    assert f["min_gap_m"].dtype == np.float64
    from vei.errors import ConfigError

    with pytest.raises(ConfigError, match="pet_s"):
        metrics_frame(rows, ("pet_s",))
