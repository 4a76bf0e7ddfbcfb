"""vei.models.decision_core: the rider's yield / go law, one implementation for both engines
(NumPy on arrays, numba on scalars, bit for bit), and hand-computed answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vei.models import decision_core as core

N = 2000


@pytest.fixture(scope="module")
def rng_inputs() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(24)
    return {
        "prog": rng.uniform(-20, 40, N), "vr": rng.uniform(0, 6, N), "se": rng.uniform(-50, 80, N),
        "ve": rng.uniform(0, 12, N), "src": rng.uniform(0, 30, N), "sec": rng.uniform(0, 60, N),
        "hzr": rng.uniform(0.5, 4, N), "hze": rng.uniform(2, 6, N), "clear": rng.uniform(0, 2, N),
        "vref": rng.uniform(0.2, 3, N), "state": rng.integers(0, 3, N), "live": rng.random(N) < 0.8,
        "dta": rng.normal(0, 4, N), "ttar": rng.uniform(0, 10, N), "dr": rng.normal(5, 8, N),
        "tc": rng.normal(0, 2, N), "hor": rng.uniform(1, 6, N), "tclear": rng.uniform(0, 10, N),
        "margin": rng.uniform(0, 2, N), "decel": rng.uniform(0.5, 4, N), "tau": rng.uniform(0.1, 1, N),
        "vx": rng.normal(0, 4, N), "vy": rng.normal(0, 4, N),
        "cap": np.where(rng.random(N) < 0.3, np.inf, rng.uniform(0, 6, N)),
        "v0": rng.uniform(0.5, 6, N), "look": rng.uniform(0.5, 6, N), "sigma": rng.uniform(0.2, 2, N),
    }  # fmt: skip


CASES = (
    ("conflict_times_core", "conflict_times",
     ("prog", "vr", "se", "ve", "src", "sec", "hzr", "hze", "clear", "vref")),
    ("decide_core", "decide", ("state", "live", "dta", "ttar", "dr", "tc", "hor")),
    ("yield_speed_core", "yield_speed",
     ("state", "dr", "vr", "ttar", "tclear", "margin", "decel", "tau")),
    ("capped_velocity_core", "capped_velocity", ("vx", "vy", "cap")),
    ("reference_speed_core", "reference_speed", ("v0", "look", "sigma")),
)  # fmt: skip


@pytest.mark.parametrize(("name", "compiled", "args"), CASES, ids=[c[0] for c in CASES])
def test_numpy_and_compiled_cores_are_bit_identical(name, compiled, args, rng_inputs) -> None:
    kernel_dec = pytest.importorskip("vei.sim.kernel.decision")  # needs numba
    vec = [rng_inputs[a] for a in args]
    out_np = getattr(core, name)(*vec)
    fn = getattr(kernel_dec, compiled)
    rows = [fn(*[v[i].item() for v in vec]) for i in range(N)]
    if not isinstance(out_np, tuple):
        out_np, rows = (out_np,), [(r,) for r in rows]
    for j, a in enumerate(out_np):
        got = np.array([r[j] for r in rows]).astype(np.asarray(a).dtype)
        assert np.asarray(a).tobytes() == got.tobytes(), (name, j)


def test_zone_half_lengths_by_hand() -> None:
    # a perpendicular crossing of a 4.7 x 1.85 m sedan and a 1.2 x 0.6 m e-scooter: the
    # rider overlaps the car's strip within 1.85 / 2 + 1.2 / 2 of the crossing, the car
    # the rider's within 0.6 / 2 + 4.7 / 2
    hz_r, hz_e = core.zone_half_lengths_core(1.0, 0.0, 4.7, 1.85, 1.2, 0.6)
    assert hz_r == pytest.approx(0.925 + 0.6)
    assert hz_e == pytest.approx(0.3 + 2.35)
    # at 30 deg: (W_e / 2 + L_r / 2 sin + W_r / 2 cos) / sin
    s, c = 0.5, math.sqrt(3) / 2
    hz_r, hz_e = core.zone_half_lengths_core(s, c, 4.7, 1.85, 1.2, 0.6)
    assert hz_r == pytest.approx((0.925 + 0.3 + 0.3 * c) / s)
    assert hz_e == pytest.approx((0.3 + 2.35 * s + 0.925 * c) / s)


def test_offered_gap_by_hand() -> None:
    # rider 12 m before the crossing at 4 m/s, zone half-length 2 m: 10 m to go, 2.5 s;
    # car 40 m before it at 10 m/s, half-length 3 m: 37 m, 3.7 s; DTA = 1.2 s; the car has
    # left the zone after 40 + 3 + 1 m: 4.4 s
    d_r, tta_r, dta, t_clear, live = core.conflict_times_core(
        0.0, 4.0, 0.0, 10.0, 12.0, 40.0, 2.0, 3.0, 1.0, 1.0
    )
    assert (d_r, tta_r, t_clear, bool(live)) == pytest.approx((10.0, 2.5, 4.4, True))
    assert dta == pytest.approx(1.2)
    # a standing rider arrives at its speed floor; a standing car never (0.05 m/s floor)
    _, tta_r, dta, _, _ = core.conflict_times_core(
        0.0, 0.0, 0.0, 0.0, 12.0, 40.0, 2.0, 3.0, 1.0, 2.0
    )
    assert tta_r == pytest.approx(5.0) and dta == pytest.approx(37.0 / 0.05 - 5.0)
    # the car in the zone: it arrives now (0 s); once its centre is 1 m past, no conflict
    _, _, dta, _, live = core.conflict_times_core(
        0.0, 4.0, 39.0, 2.0, 12.0, 40.0, 2.0, 3.0, 1.0, 1.0
    )
    assert dta == pytest.approx(-2.5) and bool(live)
    *_, live = core.conflict_times_core(0.0, 4.0, 44.01, 2.0, 12.0, 40.0, 2.0, 3.0, 1.0, 1.0)
    assert not live


def test_go_above_and_yield_below_the_critical_gap() -> None:
    free, go, yld = core.FREE, core.GO, core.YIELD
    # within the horizon: the offered gap decides
    assert core.decide_core(free, True, 1.2, 2.5, 10.0, 1.0, 4.0) == go
    assert core.decide_core(free, True, 0.8, 2.5, 10.0, 1.0, 4.0) == yld
    assert core.decide_core(free, True, 1.0, 2.5, 10.0, 1.0, 4.0) == go  # at t_c: goes
    # before the horizon: free; a committed rider keeps going, a yielding one decides again
    assert core.decide_core(free, True, -5.0, 4.5, 18.0, 1.0, 4.0) == free
    assert core.decide_core(go, True, -5.0, 2.0, 8.0, 1.0, 4.0) == go
    assert core.decide_core(yld, True, 3.0, 6.0, 2.0, 1.0, 4.0) == go
    assert core.decide_core(yld, True, 0.0, 6.0, 2.0, 1.0, 4.0) == yld
    # inside the zone it goes; no live conflict: free
    assert core.decide_core(yld, True, -3.0, 0.0, -0.1, 1.0, 4.0) == go
    assert core.decide_core(yld, False, -3.0, 1.0, 4.0, 1.0, 4.0) == free
    # a population: P(go) at t_c is 1/2, at t_c + s 1 / (1 + e^-1)
    assert core.go_probability_core(1.0, 1.0, 0.5) == pytest.approx(0.5)
    assert core.go_probability_core(1.5, 1.0, 0.5) == pytest.approx(1 / (1 + math.exp(-1)))


def test_yield_speed_cap_by_hand() -> None:
    # 10 m to the zone, 0.5 m margin, at 4 m/s with tau 0.5 s: sqrt(2 * 2 * (10 - 0.5 - 2))
    cap = core.yield_speed_core(core.YIELD, 10.0, 4.0, 2.5, 4.4, 0.5, 2.0, 0.5)
    assert cap == pytest.approx(math.sqrt(2 * 2.0 * 7.5))
    # the car leaves before the rider arrives: no braking; GO / FREE: no cap
    assert core.yield_speed_core(core.YIELD, 10.0, 4.0, 2.5, 2.0, 0.5, 2.0, 0.5) == math.inf
    assert core.yield_speed_core(core.GO, 10.0, 4.0, 2.5, 4.4, 0.5, 2.0, 0.5) == math.inf
    # at the stop point: 0
    assert core.yield_speed_core(core.YIELD, 0.4, 0.0, 0.4, 4.4, 0.5, 2.0, 0.5) == 0.0
    vx, vy = core.capped_velocity_core(3.0, 4.0, 2.5)
    assert (vx, vy) == pytest.approx((1.5, 2.0))
    assert core.capped_velocity_core(3.0, 4.0, math.inf) == (3.0, 4.0)
