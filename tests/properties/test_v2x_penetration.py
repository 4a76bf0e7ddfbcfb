"""Properties of V2X penetration: a V2X channel whose penetration rate is 0 (no rider
carries a device) is perception alone, bit for bit, whatever the channel's other settings;
more penetration never raises P(collision) beyond its confidence interval.

The second is stated on P(collision), not per variant: an equipped rider's VAMs carry a
GNSS error (3.23 m std by default) and an age, so the car can act on a message at a
different step than on its sensor, and nothing keeps a single variant from colliding with
more V2X where it did not with less (not seen on the demo: no such variant in 3 seeds x 100
variants x 3 steps of the rate). The rates share their random numbers (a variant's label fixes its
draws; the equipped riders at a rate are a subset of those at a higher one:
vei.policy.v2x.vam.equipped_riders), so the difference of two rates is paired: the rise
``P(higher) - P(lower)`` must stay within z = 1.96 standard errors of the paired
difference. The scene: the demo's CAP car behind a short-sighted sensor (6 m, every
direction, detecting a visible rider in 10 % of the steps), which collides in 12 of 100
variants without V2X (measured; seed 0 of sensor and channel: P(collision) 0.13, 0.07,
0.05, 0.03 at penetration 0, 0.25, 0.5, 1)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tests.properties.scenes import DEMO, RECORDINGS, prepared, props
from vei.config import PerceptionConfig, V2XConfig, case_preset
from vei.sim.engine import kernel_metrics, simulate_metrics
from vei.sim.state import VariantParams

NAMES = kernel_metrics()
Z = 1.96  # two-sided 95 %

sensors = st.builds(
    PerceptionConfig,
    enabled=st.just(True),
    range_m=st.sampled_from([6.0, 15.0, 50.0]),
    fov_deg=st.sampled_from([30.0, 90.0, 360.0]),
    position_noise_std_m=st.sampled_from([0.0, 0.3]),
    detection_probability=st.sampled_from([0.1, 0.5, 1.0]),
    occlusion=st.booleans(),
    seed=st.integers(0, 2**16),
)
channels = st.builds(
    V2XConfig,
    enabled=st.just(True),
    technology=st.sampled_from(["its-g5", "c-v2x-pc5"]),
    seed=st.integers(0, 2**16),
    pdr_factor=st.sampled_from([0.5, 1.0]),
    position_error_std_m=st.sampled_from([0.0, 3.23]),
    latency_s=st.sampled_from([None, 0.0, 0.3]),
)


def _params(arrays, case, shifts_s: np.ndarray) -> VariantParams:
    labels = np.array([f"v{i}" for i in range(shifts_s.size)], dtype=object)
    p = VariantParams.from_case(case, arrays, shifts_s.size, time_shift_s=shifts_s)
    return p.with_values(labels=labels)


def _check_zero_is_alone(name: str, sensor, channel, n: int) -> None:
    arrays, base = prepared(name)
    shifts = base + np.linspace(-3.0, 3.0, n)
    alone = dataclasses.replace(case_preset("normal-cap"), perception=sensor)
    zero = dataclasses.replace(alone, v2x=dataclasses.replace(channel, penetration_rate=0.0))
    a = simulate_metrics(arrays, _params(arrays, alone, shifts), names=NAMES)
    b = simulate_metrics(arrays, _params(arrays, zero, shifts), names=NAMES)
    for col in a.columns:
        np.testing.assert_array_equal(b[col].to_numpy(), a[col].to_numpy(), err_msg=col)


@props(max_examples=2)  # the policy step loop: ~0.6 s an example
@given(sensor=sensors, channel=channels)
def test_demo_penetration_zero_is_perception_alone(sensor, channel) -> None:
    _check_zero_is_alone(DEMO, sensor, channel, 6)


@pytest.mark.slow
@props(max_examples=6)
@given(name=st.sampled_from([DEMO, *RECORDINGS]), sensor=sensors, channel=channels)
def test_penetration_zero_is_perception_alone(name, sensor, channel) -> None:
    _check_zero_is_alone(name, sensor, channel, 12)


RATES = (0.0, 0.25, 0.5, 1.0)
SHORT_SIGHTED = PerceptionConfig(
    enabled=True, range_m=6.0, fov_deg=360.0, detection_probability=0.1,
    position_noise_std_m=0.3,
)  # fmt: skip


def paired_rise_bound(low: np.ndarray, high: np.ndarray) -> tuple[float, float]:
    """(P(high) - P(low), z standard errors of that paired difference) of two [n] bool
    collision vectors of the same variants."""
    d = high.astype(np.float64) - low.astype(np.float64)
    return float(d.mean()), Z * float(d.std(ddof=1)) / math.sqrt(d.size)


@pytest.mark.slow
@props(max_examples=3)  # 4 rates x 100 variants on the policy step loop: ~10 s an example
@given(
    sensor_seed=st.integers(0, 2**16),
    channel=channels,
)
def test_more_penetration_never_raises_p_collision_beyond_its_ci(sensor_seed, channel) -> None:
    arrays, base = prepared(DEMO)
    n = 100
    shifts = base + np.linspace(-3.0, 3.0, n)
    sensor = dataclasses.replace(SHORT_SIGHTED, seed=sensor_seed)
    case = dataclasses.replace(case_preset("normal-cap"), perception=sensor)
    col = {}
    for rate in RATES:
        c = dataclasses.replace(case, v2x=dataclasses.replace(channel, penetration_rate=rate))
        m = simulate_metrics(arrays, _params(arrays, c, shifts), names=("collision",))
        col[rate] = m["collision"].to_numpy()
    assert col[0.0].any()  # the sensor alone misses riders: V2X has something to do
    p = {r: float(c.mean()) for r, c in col.items()}
    for lo, hi in [*zip(RATES[:-1], RATES[1:], strict=True), (RATES[0], RATES[-1])]:
        rise, bound = paired_rise_bound(col[lo], col[hi])
        assert rise <= bound, (
            f"P(collision) {p[hi]:.3f} at penetration {hi} exceeds {p[lo]:.3f} at {lo} by "
            f"{rise:.3f} > {bound:.3f} (1.96 standard errors of the paired difference); {p}"
        )


def test_paired_rise_bound_by_hand() -> None:
    """The bound of 4 variants that flip to a collision and none back, of 100: rise
    0.04, standard deviation of d sqrt((4 (0.96)^2 + 96 (0.04)^2) / 99) = 0.19694, bound
    1.96 x 0.19694 / 10 = 0.03860 < 0.04 (a rise beyond the CI); 3 flips: 0.03 < 0.03360."""
    low = np.zeros(100, dtype=bool)
    rise, bound = paired_rise_bound(low, np.arange(100) < 4)
    assert rise == pytest.approx(0.04) and bound == pytest.approx(0.0386015, abs=1e-6)
    rise, bound = paired_rise_bound(low, np.arange(100) < 3)
    assert rise == pytest.approx(0.03) and bound == pytest.approx(0.0336035, abs=1e-6)
