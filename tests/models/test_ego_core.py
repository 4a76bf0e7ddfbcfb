"""vei.models.ego_core: one implementation of the ego's laws for both engines.

The NumPy engine runs the cores on arrays (through vei.models.ego), the compiled kernel
runs numba's scalar compilation of the same source (vei.sim.kernel.ego). Here the two
agree bit for bit on random and edge-case inputs (the exp / expm1 of the PID decay and
the actuator lag to 1 ulp: NumPy's vectorised exp may round differently from the C
library's), and the cores give hand-computed answers.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from vei.models import ego_core as core

N = 4000


@pytest.fixture(scope="module")
def inputs() -> dict[str, np.ndarray]:
    """Random operating points with the edge cases mixed in (ties, zeros, signs, 0 gains)."""
    rng = np.random.default_rng(7)

    def mix(x: np.ndarray, specials: list[float]) -> np.ndarray:
        x = x.copy()
        pick = rng.random(N) < 0.2
        x[pick] = rng.choice(np.array(specials), int(pick.sum()))
        return x

    return {
        "err": mix(rng.normal(0, 3, N), [0.0, -0.0, 1.0]),
        "integral": mix(rng.normal(0, 5, N), [0.0, 20.0, -20.0]),
        "prev": mix(rng.normal(0, 3, N), [0.0]),
        "decay": mix(rng.uniform(0.5, 1.0, N), [1.0]),
        "lim": mix(rng.uniform(0.5, 30, N), [1.0, 20.0]),
        "kp": mix(rng.uniform(0, 1, N), [0.0, 0.05]),
        "ki": mix(rng.uniform(0, 1, N), [0.0, 0.05]),
        "kd": mix(rng.uniform(0, 1, N), [0.0, 0.05]),
        "u": mix(rng.uniform(-1, 1, N), [0.0, -0.0, 1.0, -1.0]),
        "a": mix(rng.normal(0, 4, N), [0.0, -0.0, -6.0, 3.0]),
        "amax": mix(rng.uniform(0.5, 6, N), [3.0]),
        "dmax": mix(rng.uniform(0.5, 10, N), [8.0]),
        "alpha": mix(rng.uniform(0, 1, N), [1.0, 0.0]),
        "v": mix(rng.uniform(0, 12, N), [0.0, 5.6]),
        "v2": mix(rng.uniform(-0.5, 12, N), [0.0, -0.0, 5.6]),
        "gap": mix(rng.uniform(-2, 60, N), [0.0, 3.0, np.inf, 1e9]),
        "dsafe": mix(rng.uniform(0, 40, N), [3.0, 0.0]),
        "tsafe": mix(rng.uniform(0, 4, N), [2.0, 0.0]),
        "dbuf": mix(rng.uniform(0, 5, N), [3.0, 0.0]),
        "amin": mix(rng.uniform(-10, -0.5, N), [-6.0]),
        "lag": mix(rng.uniform(0, 1, N), [0.0, -0.1, 0.2]),
        "window": mix(rng.uniform(0.05, 5, N), [np.inf, 0.5]),
        "cap": rng.integers(0, 3, N).astype(np.int64),
        "ahead": rng.random(N) < 0.5,
        "margin": mix(rng.uniform(0, 4, N), [2.0]),
        "tol": mix(rng.uniform(0, 1, N), [0.2]),
        # the corridor: arc lengths, positions [m], headings (cos, sin), sizes [m]
        "s": rng.uniform(0, 200, N), "x": rng.uniform(-60, 60, N), "y": rng.uniform(-60, 60, N),
        "px": rng.uniform(-60, 60, N), "py": rng.uniform(-60, 60, N),
        "cp": np.cos(yp := rng.uniform(-np.pi, np.pi, N)), "sp": np.sin(yp),
        "cr": np.cos(yr := rng.uniform(-np.pi, np.pi, N)), "sr": np.sin(yr),
        "lat": mix(rng.normal(0, 3, N), [0.0, -1.5, 1.5]),
        "dfront": mix(rng.normal(5, 20, N), [0.0, -0.9]),
        "len": rng.uniform(1, 6, N), "wid": rng.uniform(0.4, 2.2, N),
        "halfw": mix(rng.uniform(0.5, 3, N), [1.5]), "ext": rng.uniform(0.2, 3, N),
        "range": mix(rng.uniform(5, 80, N), [np.inf]),
    }  # fmt: skip


# (core function name, input names); dt is passed as a scalar where the core takes one.
CASES = (
    ("pid_core", ("err", "integral", "prev", "dt", "decay", "lim", "kp", "ki", "kd")),
    ("pid_limit", ("lim", "ki")),
    ("command_to_accel_core", ("u", "amax", "dmax")),
    ("accel_to_command_core", ("a", "amax", "dmax")),
    ("actuator_core", ("a", "u", "alpha")),
    ("speed_core", ("v", "a", "dt")),
    ("reported_accel_core", ("v", "v2", "a", "dt")),
    ("safe_distance_core", ("v", "tsafe", "dbuf", "amin")),
    ("gap_braking_core", ("v", "gap", "dbuf", "amin")),
    ("paper_braking_core", ("v", "dsafe", "dbuf", "amin")),
    ("cap_transition_core", ("cap", "v", "v2", "ahead", "gap", "dsafe", "margin", "tol")),
    ("path_foot_core", ("s", "x", "y", "px", "py", "cp", "sp")),
    ("half_diagonal_core", ("len", "wid")),
    ("corridor_entry_core", ("dfront", "lat", "s", "len", "halfw", "ext")),
    ("box_extent_core", ("cr", "sr", "cp", "sp", "len", "wid")),
    ("corridor_gap_core", ("dfront", "ext", "range")),
)
CASES_EXP = (("pid_decay", ("dt", "window")), ("lag_factor", ("lag", "dt")))
DT = 0.05


def _compiled(name: str):
    kernel_ego = pytest.importorskip("vei.sim.kernel.ego")  # needs numba
    corridor = pytest.importorskip("vei.sim.kernel.corridor")  # the corridor test's cores
    table = {
        "pid_core": kernel_ego.pid_core, "pid_limit": kernel_ego.pid_limit,
        "pid_decay": kernel_ego.pid_decay, "lag_factor": kernel_ego.lag_factor,
        "command_to_accel_core": kernel_ego.command_to_accel,
        "accel_to_command_core": kernel_ego.accel_to_command,
        "actuator_core": kernel_ego.actuator, "speed_core": kernel_ego.speed,
        "reported_accel_core": kernel_ego.reported_accel,
        "safe_distance_core": kernel_ego.safe_distance,
        "gap_braking_core": kernel_ego.gap_braking, "paper_braking_core": kernel_ego.paper_braking,
        "cap_transition_core": kernel_ego.cap_transition,
        "path_foot_core": corridor.path_foot, "half_diagonal_core": corridor.half_diagonal,
        "corridor_entry_core": corridor.corridor_entry, "box_extent_core": corridor.box_extent,
        "corridor_gap_core": corridor.corridor_gap,
    }  # fmt: skip
    return table[name]


def _both(name: str, args: tuple[str, ...], inputs: dict[str, np.ndarray]):
    vec = [DT if a == "dt" else inputs[a] for a in args]
    out_np = getattr(core, name)(*vec)
    out_np = out_np if isinstance(out_np, tuple) else (out_np,)
    fn = _compiled(name)
    rows = []
    for i in range(N):
        r = fn(*[v if np.ndim(v) == 0 else v[i].item() for v in vec])
        rows.append(r if isinstance(r, tuple) else (r,))
    out_nb = [np.array([row[j] for row in rows]) for j in range(len(out_np))]
    return [np.asarray(o) for o in out_np], out_nb


@pytest.mark.parametrize(("name", "args"), CASES, ids=[c[0] for c in CASES])
def test_numpy_and_compiled_cores_are_bit_identical(name, args, inputs) -> None:
    out_np, out_nb = _both(name, args, inputs)
    for a, b in zip(out_np, out_nb, strict=True):
        a = np.broadcast_to(a, b.shape)
        assert a.dtype.kind == b.dtype.kind
        # Bit for bit, signed zeros and infinities included.
        assert np.ascontiguousarray(a).astype(b.dtype).tobytes() == b.tobytes(), name


@pytest.mark.parametrize(("name", "args"), CASES_EXP, ids=[c[0] for c in CASES_EXP])
def test_exp_cores_agree_to_one_ulp(name, args, inputs) -> None:
    (a,), (b,) = _both(name, args, inputs)
    np.testing.assert_array_max_ulp(np.broadcast_to(a, b.shape), b, maxulp=1)


def test_cores_hand_values() -> None:
    # PID: I = 2 * 0.9 + 1 * 0.05 = 1.85 (within the clamp 10 / 0.5 = 20); u = 0.1 * 1 +
    # 0.5 * 1.85 + 0.2 * (1 - 0.5) / 0.05 = 3.025 -> clipped to 1.
    lim = core.pid_limit(10.0, 0.5)
    assert float(lim) == 20.0 and float(core.pid_limit(10.0, 0.0)) == 10.0
    u, integral = core.pid_core(1.0, 2.0, 0.5, 0.05, 0.9, lim, 0.1, 0.5, 0.2)
    assert float(integral) == pytest.approx(1.85) and float(u) == 1.0
    u, integral = core.pid_core(0.1, 0.0, 0.1, 0.05, 1.0, 1.0, 0.5, 0.0, 0.2)
    assert float(u) == pytest.approx(0.05) and float(integral) == pytest.approx(0.005)
    assert float(core.pid_decay(0.05, 0.5)) == pytest.approx(math.exp(-0.1))
    assert float(core.pid_decay(0.05, np.inf)) == 1.0
    # Actuator: lag 0.2 s at dt 0.05: alpha = 1 - exp(-0.25); no lag: alpha 1.
    assert float(core.lag_factor(0.2, 0.05)) == pytest.approx(1.0 - math.exp(-0.25))
    assert float(core.lag_factor(0.0, 0.05)) == 1.0
    assert float(core.actuator_core(1.0, 3.0, 0.25)) == 1.5
    assert float(core.command_to_accel_core(-0.5, 3.0, 8.0)) == -4.0
    assert float(core.accel_to_command_core(-12.0, 3.0, 8.0)) == -1.0
    assert float(core.speed_core(0.1, -4.0, 0.05)) == 0.0
    # Stopped by braking: reported (0 - 0.1) / 0.05 = -2, not the actuator's -4.
    assert float(core.reported_accel_core(0.1, 0.0, -4.0, 0.05)) == pytest.approx(-2.0)
    assert float(core.reported_accel_core(5.0, 5.1, 2.0, 0.05)) == 2.0
    # CAP laws at 10 m/s, a_min -6, T_safe 2, d_buf 3: d_safe = max(100 / 12, 20) + 3 = 23.
    assert float(core.safe_distance_core(10.0, 2.0, 3.0, -6.0)) == 23.0
    assert float(core.gap_braking_core(10.0, 13.0, 3.0, -6.0)) == -5.0  # -100 / 20
    assert float(core.gap_braking_core(10.0, 5.0, 3.0, -6.0)) == -6.0  # saturated
    assert float(core.gap_braking_core(10.0, 2.0, 3.0, -6.0)) == -6.0  # inside the buffer
    assert float(core.gap_braking_core(0.0, 2.0, 3.0, -6.0)) == 0.0  # standing
    assert float(core.paper_braking_core(10.0, 23.0, 3.0, -6.0)) == -2.5  # -100 / 40
    assert float(core.paper_braking_core(10.0, 3.0, 3.0, -6.0)) == 0.0
    # State machine (d_safe 23, margin 2, tolerance 0.2, v_d 5.6).
    tr = core.cap_transition_core
    assert tuple(map(bool, tr(0, 10.0, 5.6, True, 10.0, 23.0, 2.0, 0.2))) == (True, False)
    assert int(tr(0, 10.0, 5.6, True, 10.0, 23.0, 2.0, 0.2)[0]) == core.BRAKE
    assert int(tr(1, 10.0, 5.6, True, 24.0, 23.0, 2.0, 0.2)[0]) == core.BRAKE  # in margin
    new, release = tr(1, 10.0, 5.6, True, 25.5, 23.0, 2.0, 0.2)
    assert int(new) == core.RECOVER and bool(release)
    assert int(tr(1, 10.0, 5.6, False, np.inf, 23.0, 2.0, 0.2)[0]) == core.RECOVER
    assert int(tr(2, 5.7, 5.6, False, np.inf, 23.0, 2.0, 0.2)[0]) == core.CRUISE
    assert int(tr(2, 5.0, 5.6, False, np.inf, 23.0, 2.0, 0.2)[0]) == core.RECOVER


def test_corridor_cores_hand_values() -> None:
    # Path through (10, 0) heading +y at arc 4 m: the point (7, 9) is 9 m further along
    # (arc 13) and 3 m to the left (-x is left of +y).
    s_f, lat = core.path_foot_core(4.0, 7.0, 9.0, 10.0, 0.0, 0.0, 1.0)
    assert (float(s_f), float(lat)) == (13.0, 3.0)
    # heading +x: (7, 9) from (10, 0) is 3 m behind and 9 m to the left
    assert tuple(map(float, core.path_foot_core(4.0, 7.0, 9.0, 10.0, 0.0, 1.0, 0.0))) == (1.0, 9.0)
    assert float(core.half_diagonal_core(6.0, 8.0)) == 5.0
    # Ego 4.5 m long at arc 10: a foot at arc 20 is 20 - 10 - 2.25 = 7.75 m ahead of the
    # bumper; lateral 1.2 within a 1.5 m half width: in; lateral 1.6: out.
    d, entry = core.corridor_entry_core(20.0, 1.2, 10.0, 4.5, 1.5, 0.95)
    assert (float(d), bool(entry)) == (7.75, True)
    assert not bool(core.corridor_entry_core(20.0, 1.6, 10.0, 4.5, 1.5, 0.95)[1])
    # ... and a foot 1 m behind the bumper whose circle (0.95 m) does not reach past it: out
    assert not bool(core.corridor_entry_core(11.25, 0.0, 10.0, 4.5, 1.5, 0.95)[1])
    # A 1.8 x 0.6 m rider along the path: half-extent 0.9; across it: 0.3; at 45 deg:
    # (0.9 + 0.3) / sqrt(2).
    assert float(core.box_extent_core(1.0, 0.0, 1.0, 0.0, 1.8, 0.6)) == pytest.approx(0.9)
    assert float(core.box_extent_core(0.0, 1.0, 1.0, 0.0, 1.8, 0.6)) == pytest.approx(0.3)
    c = math.sqrt(0.5)
    assert float(core.box_extent_core(c, c, 1.0, 0.0, 1.8, 0.6)) == pytest.approx(1.2 * c)
    # gap = d_front - extent, clipped at 0, within range
    ahead, gap = core.corridor_gap_core(7.75, 0.9, 50.0)
    assert (bool(ahead), float(gap)) == (True, pytest.approx(6.85))
    ahead, gap = core.corridor_gap_core(0.5, 0.9, 50.0)  # overlapping the bumper: gap 0
    assert (bool(ahead), float(gap)) == (True, 0.0)
    assert not bool(core.corridor_gap_core(60.0, 0.9, 50.0)[0])  # beyond range
    assert not bool(core.corridor_gap_core(-1.0, 0.9, 50.0)[0])  # wholly behind the bumper
