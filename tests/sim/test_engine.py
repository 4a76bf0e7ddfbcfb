"""Built-in engine: determinism, batch = single runs, collision handling, replay, outputs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vei.boxes import box_gap
from vei.config import PAPER_CASES, CAPConfig, CaseConfig, EgoConfig, SimConfig, case_preset
from vei.errors import ConfigError, InputError
from vei.models.ego import BRAKE
from vei.sim.engine import _RECORDED, SimResult, initial_state, run_cases, simulate, step
from vei.sim.state import VariantParams, prepare_scenario
from vei.sim.testing import (
    TrackSpec,
    crossing_scenario,
    ego_straight,
    make_scenario,
    standing_rider_scenario,
)
from vei.types import TIMESERIES_COLUMNS

#: The time shift of the default crossing scenario that puts the rider's centre on the
#: ego's front-bumper centre (vei.sim.testing.crossing_scenario docstring).
SHIFT_S = (60.0 - 2.35) / 5.6 - (2.0 + 15.0 / 4.4)


@pytest.fixture(scope="module")
def crossing_arrays():
    return prepare_scenario(crossing_scenario())


def _mixed_params(arrays) -> VariantParams:
    parts = []
    for i, name in enumerate((*PAPER_CASES, "replay-speed")):
        shifts = SHIFT_S + np.array([-1.0, 0.0, 0.7]) + 0.1 * i
        parts.append(VariantParams.from_case(case_preset(name), arrays, 3, time_shift_s=shifts))
    p = VariantParams.concat(parts)
    # Vary a few per-variant parameters too (perception delay, k_des, cruise speed).
    b = p.batch_size
    i = np.arange(b)
    return p.with_values(
        perception_delay_s=np.where(i % 2 == 0, 0.0, 0.4),
        k_des_nspm=p.k_des_nspm * (1.0 + 0.1 * (i % 3)),
        cruise_speed_mps=5.6 + 0.2 * (i % 4),
        # Every model option somewhere in the batch.
        front_bumper=i % 5 == 1,
        paper_vdes=i == 7,
        paper_per_step=i % 3 == 2,
        max_speed_mps=np.where(i == 8, 4.0, np.inf),
        max_accel_mps2=np.where(i == 10, 1.0, np.inf),
    )


def _series(r: SimResult) -> dict[str, np.ndarray]:
    return {name: np.asarray(getattr(r, name)) for name, _, _ in _RECORDED}


def test_determinism_two_runs_bit_identical(crossing_arrays) -> None:
    p = _mixed_params(crossing_arrays)
    a = simulate(crossing_arrays, p)
    b = simulate(crossing_arrays, p)
    for name, arr in _series(a).items():
        assert np.array_equal(arr, _series(b)[name]), name
    assert np.array_equal(a.collision_time_s, b.collision_time_s, equal_nan=True)


def test_batch_equals_single_runs(crossing_arrays) -> None:
    p = _mixed_params(crossing_arrays)
    batch = simulate(crossing_arrays, p)
    # Shuffled order too: the engine groups variants internally and restores the order.
    perm = np.random.default_rng(1).permutation(p.batch_size)
    shuffled = simulate(crossing_arrays, p.take(perm))
    for i in range(p.batch_size):
        single = simulate(crossing_arrays, p.take([i]))
        for name, arr in _series(single).items():
            assert np.array_equal(arr[0], getattr(batch, name)[i]), (i, name)
            assert np.array_equal(
                arr[0], getattr(shuffled, name)[int(np.flatnonzero(perm == i)[0])]
            ), (i, name)
    assert batch.collision.any() and (~batch.collision).any()


def test_step_is_pure_and_matches_simulate(crossing_arrays) -> None:
    p = VariantParams.from_case(
        case_preset("normal-cap"), crossing_arrays, 2, time_shift_s=[SHIFT_S, SHIFT_S + 1]
    )
    st0 = initial_state(crossing_arrays, p)
    frozen = {k: np.copy(v) for k, v in st0._asdict().items() if k != "k"}
    st = st0
    for _ in range(200):
        st = step(st, p, crossing_arrays)
    for k, v in frozen.items():
        assert np.array_equal(getattr(st0, k), v), k  # nothing mutated
    r = simulate(crossing_arrays, p)
    assert np.array_equal(r.ego_x_m[:, 200], st.ego_x_m)
    assert np.array_equal(r.rider_y_m[:, 200], st.rider_y_m)


@pytest.mark.parametrize(
    ("names", "min_gap_m"),
    [
        # The default (calibrated) rider rides at the crossing rider's recorded 4.4 m/s and
        # passes 0.81 m in front of the stopped car (measured).
        (PAPER_CASES, 0.5),
        # The paper's rider (v0 5 m/s) passes 1.67 m (normal) / 1.95 m (aggressive) in front.
        (("replay", "paper-normal", "paper-aggressive", "paper-normal-cap",
          "paper-aggressive-cap"), 1.0),
    ],
)  # fmt: skip
def test_five_configurations_on_the_crossing(crossing_arrays, names, min_gap_m) -> None:
    r = run_cases(crossing_arrays, list(names), time_shift_s=SHIFT_S)
    assert r.labels.tolist() == list(names)
    # Paper, Section IV-C: no avoidance -> collision; CAP -> none, braking then recovery.
    assert r.collision.tolist() == [True, True, True, False, False]
    for i in (3, 4):
        assert (r.cap_state[i] == BRAKE).any()
        assert r.ego_speed_mps[i].min() < 1.0
        assert r.ego_speed_mps[i, -1] > 5.0  # back towards the cruise speed
        gap = box_gap(
            r.ego_x_m[i], r.ego_y_m[i], r.ego_yaw_rad[i], r.ego_length_m, r.ego_width_m,
            r.rider_x_m[i], r.rider_y_m[i], r.rider_yaw_rad[i], r.rider_length_m, r.rider_width_m,
        )  # fmt: skip
        assert gap[r.rider_active[i]].min() > min_gap_m


def test_aggressive_follows_its_path_normal_is_pushed_away(crossing_arrays) -> None:
    r = run_cases(crossing_arrays, ["normal", "aggressive"], time_shift_s=SHIFT_S)
    act = r.rider_active
    dev_normal = r.rider_x_m[0][act[0]] - 60.0
    dev_aggr = r.rider_x_m[1][act[1]] - 60.0
    assert np.all(dev_aggr == 0.0)  # only f_des: stays on the recorded line x = 60
    assert dev_normal.max() > 5e-4  # repelled by the car approaching from -x ...
    assert dev_normal.min() > -1e-9  # ... and only away from it


def test_collision_stops_both_and_recording_continues(crossing_arrays) -> None:
    r = run_cases(crossing_arrays, ["replay"], time_shift_s=SHIFT_S)
    t = r.t_s
    assert t.size == crossing_arrays.n_steps
    k = int(np.argmax(r.collided[0]))
    assert r.collided[0, k:].all() and not r.collided[0, :k].any()
    assert r.collision_time_s[0] == pytest.approx(t[k])
    assert np.all(r.ego_speed_mps[0, k:] == 0.0)
    assert np.all(r.rider_speed_mps[0, k:] == 0.0)
    assert np.all(r.ego_x_m[0, k:] == r.ego_x_m[0, k])
    assert np.all(r.rider_y_m[0, k:] == r.rider_y_m[0, k])
    assert r.rider_active[0, k:].all()  # the rider stays in the scene
    assert r.ego_speed_mps[0, k - 1] == pytest.approx(5.6)  # cruising until the hit


def test_constant_speed_replay_20_mps_for_2_s_is_40_m() -> None:
    ego = ego_straight(20.0, 2.0, 20.0)
    t = ego.t_s
    rider = TrackSpec(
        "escooter",
        t,
        np.full_like(t, 10.0),
        np.full_like(t, 30.0),
        np.zeros_like(t),
        np.zeros_like(t),
    )
    sc = make_scenario({"ego": ego, "r": rider}, primary_threat="r")
    r = run_cases(
        sc,
        [
            "replay-speed",
            CaseConfig(name="pid20", ego=EgoConfig(cruise_speed_mps=20.0, run_up_m=0.0)),
        ],
    )
    assert r.t_s[-1] == pytest.approx(2.0)
    assert r.ego_x_m[:, -1] == pytest.approx([40.0, 40.0], abs=1e-9)
    assert r.ego_speed_mps[:, -1] == pytest.approx([20.0, 20.0])


def test_cap_stops_short_of_a_standing_escooter_and_paper_law_hits_it() -> None:
    sc = standing_rider_scenario(rider_x_m=40.0)
    gap_law = CaseConfig(name="gap", rider="replay", ego_mode="cap")
    paper = CaseConfig(
        name="paper", rider="replay", ego_mode="cap", cap=CAPConfig(braking_law="paper_per_step")
    )
    no_lag = dataclasses.replace(gap_law, name="gap-nolag", ego=EgoConfig(actuator_lag_s=0.0))
    r = run_cases(sc, [gap_law, paper, no_lag], time_shift_s=0.0)
    final_gap = box_gap(
        r.ego_x_m[:, -1], r.ego_y_m[:, -1], r.ego_yaw_rad[:, -1], 4.7, 1.85,
        r.rider_x_m[:, -1], r.rider_y_m[:, -1], r.rider_yaw_rad[:, -1], 1.2, 0.6,
    )  # fmt: skip
    assert r.collision.tolist() == [False, True, False]
    assert np.all(r.ego_speed_mps[[0, 2], -1] == 0.0)
    # Without actuator lag the gap law stops exactly d_buf short; the 0.2 s lag is absorbed
    # by recomputing the law each step (a few cm).
    assert final_gap[2] == pytest.approx(3.0, abs=1e-6)
    assert final_gap[0] == pytest.approx(3.0, abs=0.05)
    # The paper's per-step law: exponential decay at v / (2 T_safe) travels 2 T_safe v0 =
    # 22.4 m after the trigger at a gap of T_safe v0 + d_buf = 14.2 m: it hits the scooter.
    k = int(np.argmax(r.cap_state[1] == BRAKE))
    gap_at_trigger = 40.0 - 0.3 - 2.35 - r.ego_x_m[1, k - 1]
    assert gap_at_trigger == pytest.approx(14.2, abs=5.6 * 0.05)


def test_perception_delay_postpones_braking(crossing_arrays) -> None:
    base = case_preset("aggressive-cap")
    delayed = dataclasses.replace(base, name="delayed", cap=CAPConfig(perception_delay_s=0.5))
    r = run_cases(crossing_arrays, [base, delayed], time_shift_s=SHIFT_S)
    k0 = int(np.argmax(r.cap_state[0] == BRAKE))
    k1 = int(np.argmax(r.cap_state[1] == BRAKE))
    # The trigger is the rider entering the corridor: seen 0.5 s (10 steps) later.
    assert k1 - k0 == 10
    assert r.ego_speed_mps[1].min() < r.ego_speed_mps[0, k1] or r.collision[1]


def test_rider_inactive_outside_its_shifted_span_and_sfm_starts_from_the_recording(
    crossing_arrays,
) -> None:
    shift = 3.0
    r = run_cases(crossing_arrays, ["replay", "normal"], time_shift_s=shift)
    t = r.t_s
    tr = crossing_arrays.rider_track
    inside = (t - shift >= tr.t0_s - 1e-9) & (t - shift <= tr.t_end_s + 1e-9)
    assert np.array_equal(r.rider_active[0], inside)
    k = int(np.argmax(r.rider_active[1]))
    assert t[k] == pytest.approx(tr.t0_s + shift)  # enters at its run-in's start (issue 22)
    assert (r.rider_x_m[1, k], r.rider_y_m[1, k]) == pytest.approx(tuple(tr.data[0, :2]))
    # rides the run-in replayed; the social force takes over at the first recorded sample
    k2 = int(np.argmin(np.abs(t - (crossing_arrays.rider_recorded_span_s[0] + shift))))
    assert crossing_arrays.rider_recorded_span_s[0] == pytest.approx(2.0)
    np.testing.assert_allclose(r.rider_y_m[1, k : k2 + 1], r.rider_y_m[0, k : k2 + 1])
    assert (r.rider_x_m[1, k2], r.rider_y_m[1, k2]) == pytest.approx((60.0, -15.0))
    assert r.rider_speed_mps[1, k2] == pytest.approx(4.4)


def test_other_road_users_are_replayed_and_contacts_recorded() -> None:
    t = np.arange(0, 201) / 20.0
    other = TrackSpec(
        "cyclist",
        t,
        np.full_like(t, 20.0),
        np.zeros_like(t),
        np.full_like(t, np.pi / 2),
        np.zeros_like(t),
    )
    sc = crossing_scenario(duration_s=10.0, others=[("c2", other)])
    r = run_cases(sc, ["replay"], time_shift_s=0.0)
    assert r.other_ids == ("c2",)
    k = int(np.argmax(r.hit_other[0, :, 0]))
    assert k > 0 and r.hit_other[0, k:, 0].all()
    assert r.ego_speed_mps[0, k + 5] == pytest.approx(5.6)  # nothing stops for replayed others
    df = r.to_frame()
    assert set(df["agent_id"]) == {"ego", "rider1", "c2"}
    assert df.loc[df["agent_id"] == "c2", "collided"].any()


def test_outputs_frame_and_trace(crossing_arrays) -> None:
    r = run_cases(crossing_arrays, ["replay", "normal-cap"], time_shift_s=SHIFT_S)
    df = r.to_frame()
    assert tuple(df.columns) == TIMESERIES_COLUMNS
    t = crossing_arrays.n_steps
    assert len(df) == 2 * 2 * t
    assert set(df["config"]) == {"replay", "normal-cap"}
    ego_rows = df[(df["agent_id"] == "ego") & (df["config"] == "normal-cap")]
    assert set(ego_rows["cap_state"]) == {"CRUISE", "BRAKE", "RECOVER"}
    assert np.array_equal(ego_rows["speed_mps"].to_numpy(), r.ego_speed_mps[1])
    one = r.to_frame("mine", variant_slice=[1], include_others=False)
    assert set(one["config"]) == {"mine"} and set(one["variant"]) == {1}
    tr = r.to_trace()
    assert tr.ego_xy_m.shape == (2, t, 2) and tr.other_vel_mps.shape == (2, t, 2)
    assert np.array_equal(tr.collided, r.collided)
    assert tr.dt_s == pytest.approx(0.05)
    assert r.to_trace(1).ego_speed_mps.shape == (1, t)


def test_record_none_keeps_summaries(crossing_arrays) -> None:
    p = _mixed_params(crossing_arrays)
    full = simulate(crossing_arrays, p)
    none = simulate(crossing_arrays, p, record="none")
    assert none.ego_x_m is None
    assert np.array_equal(full.collision_time_s, none.collision_time_s, equal_nan=True)
    assert np.array_equal(full.min_center_distance_m, none.min_center_distance_m)
    with pytest.raises(ConfigError):
        none.to_trace()


def test_variant_params_validation(crossing_arrays) -> None:
    p = VariantParams.from_case(
        case_preset("normal"), crossing_arrays, 4, mass_kg=[90.0, 95.0, 100.0, 105.0]
    )
    assert p.batch_size == 4 and p.mass_kg.tolist() == [90.0, 95.0, 100.0, 105.0]
    assert p.cruise_speed_mps.tolist() == [5.6] * 4  # median moving speed of the recording
    with pytest.raises(ConfigError):
        p.with_values(mass_kg=-1.0)
    with pytest.raises(ConfigError):
        VariantParams.from_case(case_preset("normal"), crossing_arrays, 2, nonsense=1.0)
    with pytest.raises(ConfigError):
        p.with_values(a_min_mps2=1.0)
    # rows of checked params are not checked again, and equal the checked construction
    fields = [f.name for f in dataclasses.fields(VariantParams)]
    for q in (p.take([3, 1]), p.take(slice(1, 3)), VariantParams.concat([p, p.take([0])])):
        again = VariantParams(**{f: getattr(q, f) for f in fields})
        assert all(np.array_equal(getattr(q, f), getattr(again, f)) for f in fields)
    assert p.take([3, 1]).mass_kg.tolist() == [105.0, 95.0]
    assert VariantParams.concat([p, p]).batch_size == 8
    with pytest.raises(ConfigError, match="at least one variant"):
        p.take(np.array([], dtype=np.intp))
    with pytest.raises(ConfigError, match="1-D"):
        p.take(np.array([[0, 1]]))


def test_scenario_without_primary_threat_is_an_input_error() -> None:
    sc = dataclasses.replace(crossing_scenario(), primary_threat=None)
    with pytest.raises(InputError):
        prepare_scenario(sc)


def test_sim_config_span_and_step() -> None:
    arrays = prepare_scenario(crossing_scenario(), SimConfig(dt_s=0.1, duration_s=12.0))
    assert arrays.n_steps == 121
    assert arrays.t_s[-1] == pytest.approx(12.0)


def test_rider_options_paper_velocity_and_limits(crossing_arrays) -> None:
    normal = case_preset("paper-normal")  # the paper's rider: v0 5 m/s, look-ahead 5 m
    p = VariantParams.concat(
        [
            VariantParams.from_case(normal, crossing_arrays, 1, time_shift_s=0.0),
            VariantParams.from_case(normal, crossing_arrays, 1, time_shift_s=0.0, paper_vdes=True),
            VariantParams.from_case(
                normal, crossing_arrays, 1, time_shift_s=0.0, max_speed_mps=3.0
            ),
        ]
    )
    r = simulate(crossing_arrays, p)
    # the social force drives the rider from its first recorded sample (its run-in before
    # is replayed, issue 22)
    act = r.rider_active & (r.t_s >= crossing_arrays.rider_sfm_entry_s - 1e-9)
    # Normalised form: ~v0 * 5 / sqrt(26) = 4.90 m/s cruising at the look-ahead distance.
    k0 = int(np.argmax(act[0]))
    assert np.median(r.rider_speed_mps[0, k0 + 80 : k0 + 110]) == pytest.approx(
        5.0 * 5.0 / np.sqrt(26.0), abs=0.02
    )
    # The paper's literal form: v0 * 5 / (25 + 1) = 0.96 m/s (relaxation m / k_des = 0.95 s).
    k1 = int(np.argmax(act[1]))
    assert np.median(r.rider_speed_mps[1, k1 + 100 : k1 + 160]) == pytest.approx(
        5.0 * 5.0 / 26.0, abs=0.02
    )
    # Speed cap from the first social-force step on.
    k2 = int(np.argmax(act[2]))
    assert r.rider_speed_mps[2, k2 + 1 :].max() <= 3.0 + 1e-12
