"""Perception model: known answers for field of view, range, occlusion, detection
probability, noise, the ego-frame transform, held tracks, batch invariance, validation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vei.config import load_config
from vei.errors import ConfigError
from vei.policy.perception import (
    GroundTruth,
    PerceptionConfig,
    PerceptionState,
    init_state,
    perceive,
    visible_fraction,
)
from vei.policy.perception_geometry import (
    in_range_and_fov,
    sample_points,
    segments_blocked,
    sensor_position,
)

RIDER_L, RIDER_W = 1.2, 0.6
DT = 0.1


def make_truth(
    objects: list[dict],
    ego: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0),
) -> GroundTruth:
    """One variant (B = 1) with the given objects (keys x, y, yaw, vx, vy, l, w, valid, occ)."""

    def col(key: str, default: float | bool, dtype: type = float) -> np.ndarray:
        return np.array([[o.get(key, default) for o in objects]], dtype=dtype)

    return GroundTruth(
        x_m=col("x", 0.0),
        y_m=col("y", 0.0),
        yaw_rad=col("yaw", 0.0),
        vx_mps=col("vx", 0.0),
        vy_mps=col("vy", 0.0),
        length_m=col("l", RIDER_L),
        width_m=col("w", RIDER_W),
        valid=col("valid", True, bool),
        can_occlude=col("occ", True, bool),
        ego_x_m=np.array([ego[0]]),
        ego_y_m=np.array([ego[1]]),
        ego_yaw_rad=np.array([ego[2]]),
        ego_vx_mps=np.array([ego[3]]),
        ego_vy_mps=np.array([ego[4]]),
    )


def stack(truths: list[GroundTruth]) -> GroundTruth:
    """Concatenate single-variant truths along the batch axis."""
    names = GroundTruth.__dataclass_fields__
    return GroundTruth(**{n: np.concatenate([getattr(t, n) for t in truths]) for n in names})


def take(truth: GroundTruth, i: int) -> GroundTruth:
    names = GroundTruth.__dataclass_fields__
    return GroundTruth(**{n: getattr(truth, n)[i : i + 1] for n in names})


def at_bearing(dist_m: float, bearing_deg: float, **extra) -> dict:
    b = math.radians(bearing_deg)
    return {"x": dist_m * math.cos(b), "y": dist_m * math.sin(b), **extra}


def run_steps(cfg, truths, keys=(0,)):
    """Perceive a sequence of truths from the empty state; returns the perceived list."""
    state = init_state(len(keys), truths[0].shape[1])
    out = []
    for k, truth in enumerate(truths):
        seen, state = perceive(cfg, state, truth, k, DT, np.asarray(keys))
        out.append(seen)
    return out


# ---- field of view and range ---------------------------------------------------------
def test_rider_outside_fov_never_perceived_inside_always():
    cfg = PerceptionConfig(enabled=True, fov_deg=90.0, sensor_x_m=0.0, range_m=50.0)
    outside = make_truth([at_bearing(10.0, 100.0)])
    inside = make_truth([at_bearing(10.0, 30.0)])
    for seen in run_steps(cfg, [outside] * 30):
        assert not seen.detected.any() and not seen.tracked.any()
    for seen in run_steps(cfg, [inside] * 30):
        assert seen.detected.all()
    # Behind the car (180 deg), beside it (-100 deg): never; a 360-degree sensor: always.
    for bearing in (180.0, -100.0):
        assert not run_steps(cfg, [make_truth([at_bearing(10.0, bearing)])])[0].tracked.any()
    wide = PerceptionConfig(enabled=True, fov_deg=360.0, sensor_x_m=0.0)
    assert run_steps(wide, [make_truth([at_bearing(10.0, 180.0)])])[0].detected.all()


def test_fov_edge_counts_sample_points():
    # Rider centred on the +45 deg edge of a 90 deg FOV, pointing radially: its centre
    # (bearing exactly 45) and its two right-hand corners are inside, the two left-hand
    # corners outside -> 3 of 5 points = 0.6.
    rider = make_truth([at_bearing(10.0, 45.0, yaw=math.radians(45.0))])
    cfg = PerceptionConfig(enabled=True, fov_deg=90.0, sensor_x_m=0.0)
    assert visible_fraction(cfg, rider)[0, 0] == pytest.approx(0.6)
    assert run_steps(PerceptionConfig(**{**vars(cfg), "min_visible_fraction": 0.6}), [rider])[
        0
    ].detected[0, 0]
    assert not run_steps(PerceptionConfig(**{**vars(cfg), "min_visible_fraction": 0.8}), [rider])[
        0
    ].detected[0, 0]


@pytest.mark.parametrize(
    ("min_fraction", "last_in_m"),
    [
        # all 5 points: the far corners hypot(d + 0.6, 0.3) <= 20 -> d <= sqrt(400 - 0.09) - 0.6
        (1.0, math.sqrt(400.0 - 0.09) - 0.6),  # 19.39775
        # 3 points (centre + near corners): the centre d <= 20
        (0.6, 20.0),
        # 1 point: the near corners hypot(d - 0.6, 0.3) <= 20 -> d <= sqrt(400 - 0.09) + 0.6
        (0.2, math.sqrt(400.0 - 0.09) + 0.6),  # 20.59775
    ],
)
def test_range_edge(min_fraction, last_in_m):
    cfg = PerceptionConfig(
        enabled=True, range_m=20.0, sensor_x_m=0.0, min_visible_fraction=min_fraction
    )
    for d, expected in ((last_in_m - 0.005, True), (last_in_m + 0.005, False)):
        seen = run_steps(cfg, [make_truth([{"x": d}])])[0]
        assert bool(seen.detected[0, 0]) is expected, (d, expected)


def test_sensor_mount_point_sets_the_range_origin():
    # Sensor 2 m forward of the box centre: a point 21.5 m ahead of the centre is 19.5 m
    # from the sensor. A 0.2 x 0.2 box so that all 5 points are within 0.15 m of its centre.
    obj = make_truth([{"x": 21.5, "l": 0.2, "w": 0.2}])
    near = PerceptionConfig(enabled=True, range_m=20.0, sensor_x_m=2.0, min_visible_fraction=1.0)
    far = PerceptionConfig(enabled=True, range_m=20.0, sensor_x_m=0.0, min_visible_fraction=0.2)
    assert run_steps(near, [obj])[0].detected[0, 0]
    assert not run_steps(far, [obj])[0].detected[0, 0]


# ---- occlusion ------------------------------------------------------------------------
VAN = {"x": 12.0, "y": 0.0, "yaw": 0.0, "l": 5.0, "w": 2.0}  # x in [9.5, 14.5], y in [-1, 1]


def walking_rider(k: int) -> dict:
    """A rider at x = 20 m walking left (+y) at 1 m/s from y = 0: centre y = 0.1 k at step k."""
    return {"x": 20.0, "y": 1.0 * DT * k, "yaw": math.pi / 2, "vy": 1.0}


def first_detection(cfg: PerceptionConfig, van_occludes: bool = True) -> int | None:
    truths = [make_truth([{**VAN, "occ": van_occludes}, walking_rider(k)]) for k in range(60)]
    for k, seen in enumerate(run_steps(cfg, truths)):
        assert seen.detected[0, 0]  # the van itself is always in view
        if seen.detected[0, 1]:
            return k
    return None


@pytest.mark.parametrize(("min_fraction", "step"), [(0.4, 19), (1.0, 31)])
def test_rider_behind_parked_van_appears_when_line_of_sight_clears(min_fraction, step):
    # Sensor at (2, 0) (2 m forward of the ego centre at the origin). The segment from it to
    # a point (px, py) with py > 0 clears the van's near top corner (9.5, 1) iff
    # py * 7.5 / (px - 2) >= 1, i.e. py >= (px - 2) / 7.5: 2.36 m at px = 19.7 (the rider's
    # x - 0.3) and 2.44 m at px = 20.3. The rider's box spans y_c +- 0.6 (length 1.2 along
    # y), so its upper corners clear at y_c >= 1.76 and 1.84, the centre at 2.4, its lower
    # corners at 2.96 and 3.04. Two points (0.4) first at y_c = 1.9 (step 19; at step 18,
    # y_c = 1.8, only one corner is clear); all five (1.0) first at y_c = 3.1 (step 31).
    cfg = PerceptionConfig(
        enabled=True, sensor_x_m=2.0, min_visible_fraction=min_fraction, max_hold_s=0.0
    )
    assert first_detection(cfg) == step
    # Without the van as an occluder (or with occlusion off) the rider is seen at once.
    assert first_detection(cfg, van_occludes=False) == 0
    assert first_detection(PerceptionConfig(**{**vars(cfg), "occlusion": False})) == 0


def test_hidden_rider_visible_fraction_step_by_step():
    cfg = PerceptionConfig(enabled=True, sensor_x_m=2.0)
    fractions = [
        visible_fraction(cfg, make_truth([VAN, walking_rider(k)]))[0, 1]
        for k in (0, 18, 19, 25, 30, 31)
    ]
    # y_c = 0, 1.8, 1.9, 2.5, 3.0, 3.1 -> clear points 0, 1, 2, 3 (centre + upper), 4, 5.
    assert fractions == pytest.approx([0.0, 0.2, 0.4, 0.6, 0.8, 1.0])


def test_segment_grazing_edge_not_blocked():
    box = [np.array([v]) for v in (5.0, 1.0, 0.0, 2.0, 2.0)]  # x in [4, 6], y in [0, 2]
    points_x = np.array([[10.0, 10.0, 10.0, 3.0]])
    points_y = np.array([[0.0, 0.5, -0.5, 0.5]])  # along the edge y = 0; through; below; short
    blocked = segments_blocked(np.array([0.0]), np.array([0.0]), points_x, points_y, *box)
    assert blocked.tolist() == [[False, True, False, False]]


def test_occluder_holding_the_sensor_is_ignored():
    # After a collision the sensor (at the ego centre) lies inside the van's box.
    cfg = PerceptionConfig(enabled=True, sensor_x_m=0.0)
    truth = make_truth([{**VAN, "x": 0.5}, {"x": 10.0}])
    # The rider is seen whole; of the van (x in [-2, 3]) the centre and the front corners
    # are in the 90 deg field of view, its rear corners behind the sensor.
    assert visible_fraction(cfg, truth)[0].tolist() == [0.6, 1.0]


def brute_force_fraction(cfg: PerceptionConfig, truth: GroundTruth) -> np.ndarray:
    """Every (target, occluder) pair through segments_blocked, no pre-filter."""
    n_var, n_obj = truth.shape
    out = np.zeros((n_var, n_obj))
    sx, sy = sensor_position(
        truth.ego_x_m, truth.ego_y_m, truth.ego_yaw_rad, cfg.sensor_x_m, cfg.sensor_y_m
    )
    px, py = sample_points(truth.x_m, truth.y_m, truth.yaw_rad, truth.length_m, truth.width_m)
    seen = in_range_and_fov(px, py, sx, sy, truth.ego_yaw_rad, cfg.range_m, cfg.fov_deg)
    for b in range(n_var):
        for n in range(n_obj):
            if not truth.valid[b, n]:
                continue
            ok = seen[b, n].copy()
            for m in range(n_obj):
                if m == n or not (truth.valid[b, m] and truth.can_occlude[b, m]):
                    continue
                box = [np.array([getattr(truth, f)[b, m]]) for f in BOX]
                rx, ry = sx[b] - box[0][0], sy[b] - box[1][0]
                c, s = math.cos(box[2][0]), math.sin(box[2][0])
                u, v = rx * c + ry * s, -rx * s + ry * c
                if abs(u) < 0.5 * box[3][0] and abs(v) < 0.5 * box[4][0]:
                    continue  # the sensor is inside this box
                ok &= ~segments_blocked(
                    sx[b : b + 1], sy[b : b + 1], px[b, n][None], py[b, n][None], *box
                )[0]
            out[b, n] = ok.sum() / 5.0
    return out


BOX = ("x_m", "y_m", "yaw_rad", "length_m", "width_m")


def test_occlusion_prefilter_matches_brute_force():
    rng = np.random.default_rng(12)
    truths = []
    for _ in range(150):
        objs = [
            {
                "x": float(rng.uniform(-5, 30)),
                "y": float(rng.uniform(-10, 10)),
                "yaw": float(rng.uniform(-np.pi, np.pi)),
                "l": float(rng.choice([1.2, 4.7, 5.0, 10.0])),
                "w": float(rng.choice([0.6, 1.8, 2.0])),
                "valid": bool(rng.random() < 0.9),
                "occ": bool(rng.random() < 0.8),
            }
            for _ in range(6)
        ]
        truths.append(make_truth(objs, ego=(0.0, 0.0, float(rng.uniform(-0.5, 0.5)), 0.0, 0.0)))
    truth = stack(truths)
    cfg = PerceptionConfig(enabled=True, fov_deg=120.0, range_m=35.0, sensor_x_m=1.0)
    fast = visible_fraction(cfg, truth)
    slow = brute_force_fraction(cfg, truth)
    assert np.array_equal(fast, slow)
    assert 0.05 < np.mean((fast > 0) & (fast < 1)) and np.mean(fast == 1.0) > 0.2  # non-trivial


# ---- detection probability and noise -------------------------------------------------
def many_variants(n: int, rng_seed: int = 3) -> GroundTruth:
    """n variants, each one rider in clear view at a different place, ego moving."""
    rng = np.random.default_rng(rng_seed)
    truths = [
        make_truth(
            [{"x": float(rng.uniform(5, 30)), "y": float(rng.uniform(-3, 3)), "vx": 1.5}],
            ego=(0.0, 0.0, 0.0, 5.0, 0.0),
        )
        for _ in range(n)
    ]
    return stack(truths)


@pytest.fixture(scope="module")
def crowd() -> GroundTruth:
    return many_variants(2000)


def detections(cfg: PerceptionConfig, truth: GroundTruth, steps: int) -> np.ndarray:
    keys = np.arange(truth.shape[0])
    state = init_state(*truth.shape)
    out = []
    for k in range(steps):
        seen, state = perceive(cfg, state, truth, k, DT, keys)
        out.append(seen.detected[:, 0])
    return np.array(out)


def test_detection_probability_rate_and_reproducibility(crowd):
    p = 0.3
    cfg = PerceptionConfig(enabled=True, detection_probability=p, seed=7)
    hits = detections(cfg, crowd, 5)  # 10,000 Bernoulli trials
    n = hits.size
    tol = 4.0 * math.sqrt(n * p * (1 - p))  # 4 sigma of the binomial count: 183
    assert abs(hits.sum() - n * p) < tol
    # Independent across steps: P(hit at k and k+1) = p^2.
    both = (hits[1:] & hits[:-1]).sum()
    m = hits[1:].size
    assert abs(both - m * p * p) < 4.0 * math.sqrt(m * p * p * (1 - p * p))
    assert np.array_equal(hits, detections(cfg, crowd, 5))
    other = detections(PerceptionConfig(**{**vars(cfg), "seed": 8}), crowd, 5)
    assert not np.array_equal(hits, other)
    assert abs(other.sum() - n * p) < tol
    never = detections(PerceptionConfig(enabled=True, detection_probability=0.0), crowd, 2)
    assert not never.any()


def test_noise_zero_mean_and_std(crowd):
    cfg = PerceptionConfig(
        enabled=True, position_noise_std_m=0.5, velocity_noise_std_mps=0.2, seed=11
    )
    keys = np.arange(crowd.shape[0])
    exact, _ = perceive(
        PerceptionConfig(enabled=True), init_state(*crowd.shape), crowd, 0, DT, keys
    )
    errors = {"x": [], "y": [], "vx": [], "vy": []}
    for k in range(5):  # 10,000 samples per axis
        noisy, _ = perceive(cfg, init_state(*crowd.shape), crowd, k, DT, keys)
        errors["x"].append(noisy.x_m - exact.x_m)
        errors["y"].append(noisy.y_m - exact.y_m)
        errors["vx"].append(noisy.vx_mps - exact.vx_mps)
        errors["vy"].append(noisy.vy_mps - exact.vy_mps)
    err = {key: np.concatenate(v).ravel() for key, v in errors.items()}
    n = err["x"].size
    for key, std in (("x", 0.5), ("y", 0.5), ("vx", 0.2), ("vy", 0.2)):
        e = err[key]
        assert abs(e.mean()) < 4.0 * std / math.sqrt(n), key  # zero mean
        assert e.std() == pytest.approx(std, rel=4.0 / math.sqrt(2 * n)), key  # 2.8 %
        # Gaussian tails: 95.45 % within 2 sigma (binomial 4-sigma band ~ 0.8 %).
        assert np.mean(np.abs(e) < 2 * std) == pytest.approx(0.9545, abs=0.009), key
    # Axes and quantities independent.
    for a, b in (("x", "y"), ("x", "vx"), ("vx", "vy"), ("y", "vy")):
        assert abs(np.corrcoef(err[a], err[b])[0, 1]) < 4.0 / math.sqrt(n), (a, b)


# ---- ego frame -------------------------------------------------------------------------
def test_ego_frame_hand_computed():
    cfg = PerceptionConfig(enabled=True, fov_deg=360.0)
    # Ego at (10, 5) heading north (90 deg), moving north at 5 m/s; rider at (10, 15)
    # heading east, moving east at 1 m/s: 10 m straight ahead, crossing to the right.
    truth = make_truth(
        [{"x": 10.0, "y": 15.0, "yaw": 0.0, "vx": 1.0, "vy": 0.0}],
        ego=(10.0, 5.0, math.pi / 2, 0.0, 5.0),
    )
    seen = run_steps(cfg, [truth])[0]
    assert seen.x_m[0, 0] == pytest.approx(10.0, abs=1e-12)
    assert seen.y_m[0, 0] == pytest.approx(0.0, abs=1e-12)
    # Relative velocity (1, 0) - (0, 5) = (1, -5) world -> forward -5, left -1.
    assert seen.vx_mps[0, 0] == pytest.approx(-5.0, abs=1e-12)
    assert seen.vy_mps[0, 0] == pytest.approx(-1.0, abs=1e-12)
    assert seen.yaw_rad[0, 0] == pytest.approx(-math.pi / 2, abs=1e-12)
    assert (seen.length_m[0, 0], seen.width_m[0, 0], seen.age_s[0, 0]) == (RIDER_L, RIDER_W, 0.0)
    # Heading 30 deg: a point placed at ego + R(30 deg) (3, -2) reads back as (3, -2).
    yaw = math.radians(30.0)
    c, s = math.cos(yaw), math.sin(yaw)
    obj = {"x": 1.0 + 3 * c + 2 * s, "y": -4.0 + 3 * s - 2 * c, "yaw": yaw + 4.0}
    seen = run_steps(cfg, [make_truth([obj], ego=(1.0, -4.0, yaw, 0.0, 0.0))])[0]
    assert (seen.x_m[0, 0], seen.y_m[0, 0]) == pytest.approx((3.0, -2.0), abs=1e-12)
    assert seen.yaw_rad[0, 0] == pytest.approx(4.0 - 2 * math.pi, abs=1e-12)  # wrapped
    # Heading opposite the ego's: +pi (the range is (-pi, pi]).
    seen = run_steps(cfg, [make_truth([{"x": 5.0, "yaw": math.pi}])])[0]
    assert seen.yaw_rad[0, 0] == math.pi


def test_disabled_is_exact_truth_even_with_noise_configured():
    cfg = PerceptionConfig(
        enabled=False,
        fov_deg=10.0,
        range_m=1.0,
        position_noise_std_m=3.0,
        detection_probability=0.1,
    )
    truth = make_truth(
        [{"x": 30.0, "y": -20.0, "vx": 2.0}, {"x": np.nan, "valid": False}],
        ego=(1.0, 2.0, 0.0, 4.0, 0.0),
    )
    seen = run_steps(cfg, [truth] * 3)[-1]
    assert seen.detected.tolist() == [[True, False]] and seen.tracked.tolist() == [[True, False]]
    assert (seen.x_m[0, 0], seen.y_m[0, 0], seen.vx_mps[0, 0]) == (29.0, -22.0, -2.0)
    assert np.isnan(seen.x_m[0, 1]) and np.isnan(seen.age_s[0, 1])


# ---- held tracks -----------------------------------------------------------------------
def hold_scenario(max_hold_s: float):
    """Rider at x = 20 - t (coming at 1 m/s) seen for steps 0..4, then absent (valid False);
    the ego drives +x at 5 m/s from the origin."""
    truths = []
    for k in range(10):
        t = k * DT
        present = k < 5
        rider = {"x": 20.0 - t if present else np.nan, "vx": -1.0, "valid": present}
        truths.append(make_truth([rider], ego=(5.0 * t, 0.0, 0.0, 5.0, 0.0)))
    cfg = PerceptionConfig(enabled=True, sensor_x_m=0.0, max_hold_s=max_hold_s)
    return run_steps(cfg, truths)


def test_held_track_ages_is_predicted_and_dropped():
    seen = hold_scenario(max_hold_s=0.3)
    assert [bool(s.detected[0, 0]) for s in seen] == [True] * 5 + [False] * 5
    assert [bool(s.tracked[0, 0]) for s in seen] == [True] * 8 + [False] * 2
    ages = [s.age_s[0, 0] for s in seen[:8]]
    assert ages == pytest.approx([0, 0, 0, 0, 0, 0.1, 0.2, 0.3], abs=1e-12)
    # Last detection at step 4: x = 19.6, vx = -1. At step 6 (age 0.2) predicted x = 19.4,
    # the ego is at x = 3.0 -> 16.4 ahead; relative velocity -1 - 5 = -6.
    assert seen[6].x_m[0, 0] == pytest.approx(16.4, abs=1e-9)
    assert seen[6].vx_mps[0, 0] == pytest.approx(-6.0, abs=1e-12)
    assert seen[7].x_m[0, 0] == pytest.approx(19.3 - 3.5, abs=1e-9)
    assert np.isnan(seen[8].x_m[0, 0]) and np.isnan(seen[8].age_s[0, 0])
    # No hold: dropped at the first miss.
    seen0 = hold_scenario(max_hold_s=0.0)
    assert [bool(s.tracked[0, 0]) for s in seen0] == [True] * 5 + [False] * 5


def test_redetection_resets_age():
    cfg = PerceptionConfig(enabled=True, fov_deg=90.0, sensor_x_m=0.0, max_hold_s=1.0)
    seen_at = [0, 1, 2, 6, 7]  # in view at these steps, at bearing 100 deg otherwise
    truths = [make_truth([at_bearing(10.0, 0.0 if k in seen_at else 100.0)]) for k in range(8)]
    ages = [s.age_s[0, 0] for s in run_steps(cfg, truths)]
    assert ages == pytest.approx([0, 0, 0, 0.1, 0.2, 0.3, 0, 0], abs=1e-12)


# ---- determinism and batch invariance --------------------------------------------------
def test_batch_of_five_equals_five_single_runs_bit_for_bit():
    cfg = PerceptionConfig(
        enabled=True,
        position_noise_std_m=0.3,
        velocity_noise_std_mps=0.2,
        detection_probability=0.7,
        max_hold_s=0.2,
        sensor_x_m=2.0,
        seed=2024,
    )
    keys = np.array([17, 3, 99, 4, 123456789012])
    steps = []
    for k in range(25):
        steps.append(
            stack(
                [
                    make_truth(
                        [
                            {**VAN, "x": 12.0 + i},
                            walking_rider(k + 3 * i),
                            {"x": 30.0, "y": -4.0 + i},
                        ],
                        ego=(0.3 * k, 0.1 * i, 0.02 * i, 3.0, 0.0),
                    )
                    for i in range(len(keys))
                ]
            )
        )
    batch = run_steps(cfg, steps, keys=tuple(keys))
    assert any(s.detected.sum() < s.detected.size for s in batch)  # misses happen
    for i, key in enumerate(keys):
        single = run_steps(cfg, [take(t, i) for t in steps], keys=(key,))
        for b, s in zip(batch, single, strict=True):
            for name in PerceptionState.__dataclass_fields__.keys() - {"tracked"}:
                assert np.array_equal(getattr(b, name)[i : i + 1], getattr(s, name), equal_nan=True)
            assert np.array_equal(b.tracked[i : i + 1], s.tracked)
            assert np.array_equal(b.detected[i : i + 1], s.detected)
    again = run_steps(cfg, steps, keys=tuple(keys))
    for a, b in zip(batch, again, strict=True):
        assert np.array_equal(a.x_m, b.x_m, equal_nan=True)


def test_perceive_is_pure():
    cfg = PerceptionConfig(enabled=True, position_noise_std_m=0.1, max_hold_s=1.0)
    truth = make_truth([{"x": 10.0}], ego=(0.0, 0.0, 0.0, 5.0, 0.0))
    state = init_state(1, 1)
    before = {n: getattr(truth, n).copy() for n in GroundTruth.__dataclass_fields__}
    _, s1 = perceive(cfg, state, truth, 0, DT, np.array([0]))
    assert not state.tracked.any()
    for n, arr in before.items():
        assert np.array_equal(getattr(truth, n), arr)
    _, s2 = perceive(cfg, s1, truth, 0, DT, np.array([0]))
    assert np.array_equal(s1.x_m, s2.x_m)  # same counters -> same draw


# ---- validation ------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("range_m", 0.0),
        ("range_m", float("inf")),
        ("fov_deg", 0.0),
        ("fov_deg", 361.0),
        ("position_noise_std_m", -0.1),
        ("velocity_noise_std_mps", float("nan")),
        ("detection_probability", 1.5),
        ("detection_probability", -0.01),
        ("min_visible_fraction", 0.0),
        ("min_visible_fraction", 1.2),
        ("max_hold_s", -1.0),
        ("sensor_x_m", "front"),
        ("range_m", True),
        ("enabled", "yes"),
        ("occlusion", 1),
        ("seed", 1.5),
    ],
)
def test_config_validation(key, value):
    with pytest.raises(ConfigError, match=key):
        PerceptionConfig(**{key: value})


def test_config_from_mapping():
    cfg = load_config({"enabled": True, "fov_deg": 120, "range_m": 40, "seed": 5}, PerceptionConfig)
    assert cfg.fov_deg == 120.0 and isinstance(cfg.fov_deg, float) and cfg.range_m == 40.0
    with pytest.raises(ConfigError, match="fov"):
        load_config({"enabled": True, "fov": 120}, PerceptionConfig)
    assert PerceptionConfig().enabled is False


def test_shape_errors():
    truth = make_truth([{"x": 10.0}])
    with pytest.raises(ValueError, match="variant_keys"):
        perceive(PerceptionConfig(), init_state(1, 1), truth, 0, DT, np.array([0, 1]))
    with pytest.raises(ValueError, match="state shape"):
        perceive(PerceptionConfig(), init_state(1, 2), truth, 0, DT, np.array([0]))
    with pytest.raises(ValueError, match="ego_x_m"):
        GroundTruth(**{**vars(truth), "ego_x_m": np.zeros(2)})
