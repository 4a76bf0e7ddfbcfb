"""The engine with policies on the API: batch invariance, mixed batches (compiled kernel +
policies), perception latency and the sensor model's range / field of view (known answers)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from vei.config import CaseConfig, EgoConfig, SimConfig, case_preset
from vei.policy.aeb import AEB_FCW, AEB_PARTIAL
from vei.policy.perception import PerceptionConfig
from vei.sim import kernel as compiled
from vei.sim.engine import prepare_scenario, simulate
from vei.sim.params import VariantParams
from vei.sim.result import _RECORDED
from vei.sim.testing import crossing_scenario, standing_rider_scenario

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "my_policy.py"


@pytest.fixture(scope="module")
def crossing():
    return prepare_scenario(crossing_scenario())


@pytest.fixture(scope="module")
def standing():
    # ego at 10 m/s, a rider standing across the path, its near edge 30 m ahead of the bumper
    return prepare_scenario(
        standing_rider_scenario(ego_speed_mps=10.0, rider_x_m=30.0 + 2.35 + 0.3, duration_s=8.0),
        SimConfig(kernel="numpy"),
    )


def _case(policy: str, **kw) -> CaseConfig:
    c = case_preset("normal")
    return replace(c, name=policy.rpartition(":")[2], ego=replace(c.ego, policy=policy), **kw)


@pytest.mark.parametrize("policy", ["aeb", "idm", f"{EXAMPLE}:MyPolicy"])
def test_single_runs_equal_one_batch(crossing, policy) -> None:
    shifts = np.array([3.5, 4.886, 6.0])
    batch = simulate(
        crossing, VariantParams.from_case(_case(policy), crossing, 3, time_shift_s=shifts)
    )
    for i, s in enumerate(shifts):
        one = simulate(
            crossing, VariantParams.from_case(_case(policy), crossing, 1, time_shift_s=s)
        )
        for name, _, _ in _RECORDED:
            np.testing.assert_array_equal(
                getattr(one, name)[0], getattr(batch, name)[i], err_msg=name
            )


@pytest.mark.skipif(not compiled.available(), reason="numba not installed")
def test_mixed_batch_runs_the_kernel_variants_compiled(crossing) -> None:
    cap = VariantParams.from_case(
        case_preset("normal-cap"), crossing, 2, time_shift_s=np.array([4.0, 4.886])
    )
    # a Python policy (the NumPy step loop; aeb / idm run in the kernel: tests/sim/kernel)
    aeb = VariantParams.from_case(
        _case(f"{EXAMPLE}:MyPolicy"), crossing, 2, time_shift_s=np.array([4.0, 4.886])
    )
    mixed = simulate(crossing, VariantParams.concat([aeb, cap]), kernel="numba")
    only_cap = simulate(crossing, cap, kernel="numba")
    only_aeb = simulate(crossing, aeb, kernel="numpy")
    for name, _, _ in _RECORDED:
        np.testing.assert_array_equal(
            getattr(mixed, name)[2:], getattr(only_cap, name), err_msg=name
        )
        np.testing.assert_array_equal(
            getattr(mixed, name)[:2], getattr(only_aeb, name), err_msg=name
        )


def _aeb_run(arrays, *, delay_s: float = 0.0, perception: PerceptionConfig | None = None):
    case = CaseConfig(
        name="aeb",
        ego=EgoConfig(cruise_speed_mps=10.0, run_up_m=0.0, policy="aeb"),
        perception=perception,
    )
    case = replace(case, cap=replace(case.cap, perception_delay_s=delay_s))
    r = simulate(arrays, VariantParams.from_case(case, arrays, 1))
    st = r.cap_state[0]
    return r, (r.t_s[np.argmax(st > 0)] if (st > 0).any() else None), st


def test_latency_hides_the_first_steps_of_a_standing_rider(standing) -> None:
    # TTC(t) = 3 - t; FCW at TTC 2.6 s: observation of t = 0.40 s, recorded 0.45 s. With a
    # 0.5 s delay a standing rider is seen where it is, but only from t = 0.5 s (TTC 2.5 s
    # then: the warning is recorded at 0.55 s).
    _, t0, _ = _aeb_run(standing)
    _, t1, _ = _aeb_run(standing, delay_s=0.5)
    assert t0 == pytest.approx(0.45)
    assert t1 == pytest.approx(0.55)


def test_latency_shows_a_moving_rider_where_it_was() -> None:
    # A rider riding ahead at 4 m/s (yaw 0, rear edge 40 m ahead of the ego's bumper), ego
    # at 10 m/s: gap 40 - 6 t, FCW at TTC 2.6 s -> gap 15.6 m -> t = 4.067 s (observation
    # of 4.10 s, recorded 4.15 s). With 0.5 s delay the rider is seen 2 m further back:
    # gap 38 - 6 t <= 15.6 -> t = 3.733 s (observation 3.75 s, recorded 3.80 s).
    from vei.sim.testing import TrackSpec, ego_straight, make_scenario
    from vei.types import EGO_ID

    t = np.arange(0, 12.0 + 1e-9, 0.05)
    x0 = 2.35 + 0.6 + 40.0
    rider = TrackSpec(
        "escooter", t, x0 + 4.0 * t, np.zeros_like(t), np.zeros_like(t), np.full_like(t, 4.0)
    )
    scen = make_scenario(
        {EGO_ID: ego_straight(10.0, 12.0), "r": rider}, primary_threat="r", rate_hz=20.0
    )
    arrays = prepare_scenario(scen, SimConfig(kernel="numpy"))
    _, t0, _ = _aeb_run(arrays)
    _, t1, _ = _aeb_run(arrays, delay_s=0.5)
    assert t0 == pytest.approx(4.15)
    assert t1 == pytest.approx(3.80)


def test_a_rider_outside_the_field_of_view_is_never_perceived(standing) -> None:
    # fov 1 deg (+-0.5 deg): of the rider's 5 sample points only its centre lies in the field
    # of view (its corners are 0.6 m to the side at >= 28 m: >= 1.2 deg) - 1/5 < 0.4
    r, t_first, _ = _aeb_run(standing, perception=PerceptionConfig(enabled=True, fov_deg=1.0))
    assert t_first is None  # never warned, never braked
    assert r.collision_time_s[0] == pytest.approx(3.0)  # hits it like the PID (30 m at 10 m/s)


def test_range_decides_when_the_rider_is_first_perceived(standing) -> None:
    # range 15 m from the sensor (1 m ahead of the ego's centre, 1.35 m behind the bumper):
    # the rider's two near corners (0.6 m to the side) come in range at gap g with
    # (g + 1.35)^2 + 0.6^2 <= 15^2: g <= 13.638 m, i.e. at t = 1.65 s (gap 30 - 10 t, on the
    # 0.05 s grid); TTC is then 1.35 s < 1.6 s: the AEB goes straight to partial braking.
    r, t_first, st = _aeb_run(standing, perception=PerceptionConfig(enabled=True, range_m=15.0))
    assert t_first == pytest.approx(1.70)
    assert st[np.argmax(st > 0)] == AEB_PARTIAL
    assert not (st == AEB_FCW).any()
    assert np.isnan(r.collision_time_s[0])


class _Recorder:
    """A test policy: cruises (zero demand) and records what it sees of object 0."""

    def __init__(self) -> None:
        self.seen: list[tuple[float, bool]] = []

    def init_state(self, batch_size: int) -> None:
        return None

    def act(self, obs, state):
        from vei.policy.base import PolicyAction

        self.seen.append((float(obs.t_s[0]), bool(obs.valid[0, 0])))
        return PolicyAction(accel_mps2=np.zeros(obs.batch_size)), None


def test_a_rider_behind_a_parked_van_appears_when_the_line_of_sight_clears() -> None:
    """Ego along +x at 8 m/s (sensor 1 m ahead of its centre); a van (5 x 2 m) parked at
    (20, -4); a rider (1.2 x 0.6 m) standing at (30, -8). The sight line from the sensor
    at (xs, 0) to a rider point (px, py) passes the van's near side y = -3 at
    x = xs + (px - xs) 3 / |py|; it clears the van once that is beyond x = 22.5. The
    five sample points clear at xs = 17.33 (corner 30.6, -7.7), 17.91 (30.6, -8.3), 18.0
    (centre), 18.10, 18.59: two points (0.4) at xs > 17.91, i.e. ego x > 16.91 m: the
    first step with x = 0.4 k beyond it is k = 43 (t = 2.15 s). Without occlusion it is
    seen from the start."""
    from vei.sim.testing import TrackSpec, ego_straight, make_scenario
    from vei.types import EGO_ID

    t = np.arange(0, 5.0 + 1e-9, 0.05)
    one = np.ones_like(t)
    van = TrackSpec(
        "vehicle", t, 20.0 * one, -4.0 * one, 0 * one, 0 * one, length_m=5.0, width_m=2.0
    )
    rider = TrackSpec(
        "escooter", t, 30.0 * one, -8.0 * one, 0 * one, 0 * one, length_m=1.2, width_m=0.6
    )
    scen = make_scenario(
        {EGO_ID: ego_straight(8.0, 5.0), "r": rider, "van": van}, primary_threat="r", rate_hz=20.0
    )
    arrays = prepare_scenario(
        scen, SimConfig(kernel="numpy", rider_length_m=1.2, rider_width_m=0.6)
    )
    case = CaseConfig(name="rec", ego=EgoConfig(cruise_speed_mps=8.0, run_up_m=0.0))
    first = {}
    for occlusion in (True, False):
        rec = _Recorder()
        p = VariantParams.from_case(case, arrays, 1).with_values(
            ego_mode=3, policy=rec, perception=PerceptionConfig(enabled=True, occlusion=occlusion)
        )
        simulate(arrays, p)
        seen = np.array([v for _, v in rec.seen])
        first[occlusion] = int(np.argmax(seen))
        assert seen[first[occlusion] : 64].all() and not seen[64:].any()
    assert first[False] == 0
    assert first[True] == 43
