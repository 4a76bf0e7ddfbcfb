"""V2X in the engine (vei.sim.observe.PolicyDriver): a message's latency delays the car's
first reaction by exactly that latency; no equipped rider = perception alone bit for bit;
a variant perceives the same alone or in a batch; the Observation says where each entry
comes from; built-in policies can be told to ignore V2X."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from vei.config import PerceptionConfig, SimConfig, V2XConfig, case_preset
from vei.policy.base import PolicyAction
from vei.policy.observation import SOURCE_BOTH, SOURCE_NONE, SOURCE_SENSOR, SOURCE_V2X
from vei.sim.engine import simulate
from vei.sim.state import VariantParams, prepare_scenario
from vei.sim.testing import standing_rider_scenario

DT = 0.05
# Every VAM delivered, no GNSS error, a fixed latency: the timing is exact.
EXACT = {"pdr_distance_m": [0.0, 1000.0], "pdr": [1.0, 1.0], "position_error_std_m": 0.0,
         "latency_jitter_s": 0.0}  # fmt: skip


@pytest.fixture(scope="module")
def standing():
    """Ego at 5.6 m/s from x = 0 (no run-up); an e-scooter standing across its path 15 m
    ahead: gap 15 - 0.3 - 2.35 = 12.35 m < d_safe = 2 s * 5.6 + 3 = 14.2 m, so the CAP
    brakes the moment it knows the rider."""
    return prepare_scenario(standing_rider_scenario(rider_x_m=15.0), SimConfig())


def blind_cap(v2x: V2XConfig | None = None):
    """paper-cap on the policy API behind a sensor that sees nothing (0.5 m range)."""
    base = case_preset("replay")
    case = replace(base, ego=replace(base.ego, policy="paper-cap", run_up_m=0.0),
                   perception=PerceptionConfig(enabled=True, range_m=0.5))  # fmt: skip
    return replace(case, v2x=v2x) if v2x is not None else case


def first_brake(result) -> int:
    """Index of the first recorded braking command (a step's command is recorded at k + 1)."""
    return int(np.flatnonzero(result.ego_command[0] < 0)[0])


@pytest.mark.parametrize("latency_s", [0.0, 0.05, 0.1, 0.25, 0.5, 1.0])
def test_latency_delays_the_first_reaction_by_exactly_the_latency(standing, latency_s):
    # The rider is present at t = 0: its first VAM is generated at step 0 and arrives at
    # t = latency; the CAP brakes at that step, recorded one step later.
    v2x = V2XConfig(enabled=True, latency_s=latency_s, **EXACT)
    r = simulate(standing, VariantParams.from_case(blind_cap(v2x), standing, 1))
    assert first_brake(r) == round(latency_s / DT) + 1
    assert not r.collision[0]
    # Without V2X the blind car never brakes and hits the standing rider.
    alone = simulate(standing, VariantParams.from_case(blind_cap(), standing, 1))
    assert not (alone.ego_command[0] < 0).any() and alone.collision[0]


def test_latency_between_steps_waits_for_the_next_step(standing):
    v2x = V2XConfig(enabled=True, latency_s=0.12, **EXACT)  # arrives at 0.12: seen at 0.15
    r = simulate(standing, VariantParams.from_case(blind_cap(v2x), standing, 1))
    assert first_brake(r) == 3 + 1


def test_clock_offset_shifts_the_stated_age_not_the_arrival(standing):
    # A device clock 0.3 s ahead: same arrival, the message looks 0.3 s younger (age >= 0).
    v2x = V2XConfig(enabled=True, latency_s=0.1, clock_offset_s=0.3, **EXACT)
    r = simulate(standing, VariantParams.from_case(blind_cap(v2x), standing, 1))
    assert first_brake(r) == 2 + 1


def test_no_equipped_rider_is_perception_alone_bit_for_bit(standing):
    case = replace(case_preset("replay"), ego=replace(case_preset("replay").ego,
                   policy="paper-cap"), perception=PerceptionConfig(enabled=True, fov_deg=40.0))  # fmt: skip
    shifts = np.linspace(-1.0, 1.0, 5)
    labels = np.array([f"v{i}" for i in range(5)], dtype=object)
    a = simulate(standing, VariantParams.from_case(case, standing, 5, time_shift_s=shifts)
                 .with_values(labels=labels))  # fmt: skip
    off = replace(case, v2x=V2XConfig(enabled=True, penetration_rate=0.0))
    b = simulate(standing, VariantParams.from_case(off, standing, 5, time_shift_s=shifts)
                 .with_values(labels=labels))  # fmt: skip
    for name in ("ego_x_m", "ego_speed_mps", "ego_command", "cap_state", "rider_x_m"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_a_variant_runs_the_same_alone_and_in_a_batch(standing):
    v2x = V2XConfig(enabled=True, latency_s=0.05, latency_jitter_s=0.2,
                    latency_distribution="uniform", pdr_factor=0.6, penetration_rate=0.7)  # fmt: skip
    case = replace(blind_cap(v2x), perception=PerceptionConfig(enabled=True, fov_deg=40.0))
    n = 6
    labels = np.array([f"variant-{i}" for i in range(n)], dtype=object)
    shifts = np.linspace(-2.0, 2.0, n)
    batch = simulate(standing, VariantParams.from_case(case, standing, n, time_shift_s=shifts)
                     .with_values(labels=labels))  # fmt: skip
    for i in (0, 3, 5):
        one = simulate(standing, VariantParams.from_case(case, standing, 1, time_shift_s=shifts[i])
                       .with_values(labels=labels[i : i + 1]))  # fmt: skip
        np.testing.assert_array_equal(one.ego_x_m[0], batch.ego_x_m[i])
        np.testing.assert_array_equal(one.ego_command[0], batch.ego_command[i])


class Recorder:
    """A user policy that records what it sees and cruises (PID-free: zero demand)."""

    seen: list = []

    def init_state(self, batch_size):
        return None

    def act(self, obs, state):
        Recorder.seen.append((obs.valid.copy(), obs.source.copy(), obs.age_s.copy(),
                              obs.position_std_m.copy()))  # fmt: skip
        return PolicyAction(accel_mps2=np.zeros(obs.batch_size)), state


def test_the_observation_says_source_and_age(standing, monkeypatch):
    from vei.policy import load as policy_load

    monkeypatch.setattr(policy_load, "load_policy", lambda spec, params=None: Recorder())
    Recorder.seen = []
    v2x = V2XConfig(enabled=True, latency_s=0.2, **EXACT)
    case = replace(blind_cap(v2x), perception=PerceptionConfig(enabled=True, range_m=8.0))
    simulate(standing, VariantParams.from_case(case, standing, 1))
    src = np.array([s[1][0, 0] for s in Recorder.seen])
    age = np.array([s[2][0, 0] for s in Recorder.seen])
    # Nothing until the first VAM arrives at 0.2 s (step 4), then V2X only, its age growing
    # by the step from 0.2 s (the standing rider sends no second VAM for 5.1 s); once the
    # 8 m sensor sees it (its point 8 m from the sensor 1 m ahead of the centre), both,
    # with the sensor's fresh age 0.
    assert (src[:4] == SOURCE_NONE).all() and np.isinf(age[:4]).all()
    assert src[4] == SOURCE_V2X and age[4] == pytest.approx(0.2)
    assert age[10] == pytest.approx(0.5)
    both = np.flatnonzero(src == SOURCE_BOTH)
    assert both.size and (src[both[0] :] == SOURCE_BOTH).all()
    assert age[both[0]] == 0.0
    assert not (src == SOURCE_SENSOR).any()  # V2X never stops within 5.1 s here


def test_builtin_policies_can_ignore_v2x(standing):
    v2x = V2XConfig(enabled=True, policies_use_v2x=False, **EXACT)
    r = simulate(standing, VariantParams.from_case(blind_cap(v2x), standing, 1))
    assert not (r.ego_command[0] < 0).any() and r.collision[0]  # as blind as without V2X
