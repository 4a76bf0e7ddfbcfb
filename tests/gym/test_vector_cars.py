"""The vector env's reacting cars (``traffic.cars_react``): backend 'numpy' (the engine's
step with each environment's own car state) == single envs, and the compiled backend
(vei.gym.cars_kernel) == backend 'numpy' in every state field, through autoresets, on a
car recorded 1 s behind the ego (it reacts when the agent brakes, and stops short)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vei.config import TrafficConfig, case_preset
from vei.gym import EnvConfig
from vei.gym.env import VeiEnv
from vei.gym.vector import VeiVectorEnv
from vei.models import traffic_core as core

V = 10.0  # both cars' recorded speed [m/s]


@pytest.fixture(scope="module")
def follower_folder(tmp_path_factory):
    """vei.sim.testing.follower_scenario (tests/sim/test_traffic.py's scene): the ego at
    10 m/s along +x, a car 1 s (10 m) behind it bumper to bumper at the same speed, an
    e-scooter standing far away."""
    from vei.io.scenario import write_scenario
    from vei.sim.testing import follower_scenario

    return write_scenario(follower_scenario(V), tmp_path_factory.mktemp("cars") / "scenario")


def _config(folder, react: bool = True, backend: str = "numpy", **traffic) -> EnvConfig:
    tc = TrafficConfig(cars_react=react, **traffic)
    case = dataclasses.replace(case_preset("normal"), traffic=tc)
    return EnvConfig(
        source="folder", path=folder, case=case, road_features=False, max_episode_steps=100,
        time_shift_spread_s=1.0, backend=backend,
    )  # fmt: skip


def _delayed(cfg: EnvConfig, delay_s: float = 0.3) -> EnvConfig:
    """``cfg`` with the perception delay ``delay_s`` [s]."""
    cap = dataclasses.replace(cfg.case.cap, perception_delay_s=delay_s)
    return dataclasses.replace(cfg, case=dataclasses.replace(cfg.case, cap=cap))


def _against_singles(cfg: EnvConfig, b: int, steps: int, seed: int) -> tuple[bool, bool]:
    """The vector env (backend 'numpy') == b single envs of seed + i, observation, reward
    and flags, step by step through autoresets, under random demands in [-8, 1] m/s^2.
    Returns (some car reacted, some reacting car got its recording back on a reset)."""
    vp = VeiVectorEnv(b, cfg)
    assert vp.backend == "numpy"
    singles = [VeiEnv(cfg) for _ in range(b)]
    op, _ = vp.reset(seed=seed)
    first = [e.reset(seed=seed + i)[0] for i, e in enumerate(singles)]
    assert np.array_equal(op, np.stack(first))
    assert (vp.CARS["car_mode"] == core.REPLAY).all()
    rng = np.random.default_rng(seed)
    done = np.zeros(b, dtype=bool)
    reacted = reset_back = False
    for _ in range(steps):
        a = rng.uniform(-8.0, 1.0, size=(b, 1)).astype(np.float32)
        mode0 = vp.CARS["car_mode"][:, 0].copy()
        o, r, te, tr, _ = vp.step(a)
        rows = [(e.reset()[0], 0.0, False, False) if done[i] else e.step(a[i])[:4]
                for i, e in enumerate(singles)]  # fmt: skip
        assert np.array_equal(o, np.stack([x[0] for x in rows]))
        assert np.array_equal(r, np.array([x[1] for x in rows]))
        assert np.array_equal(te, [x[2] for x in rows])
        assert np.array_equal(tr, [x[3] for x in rows])
        done = te | tr
        mode = vp.CARS["car_mode"][:, 0]
        reacted |= bool((mode >= core.REACTING).any())
        reset_back |= bool(((mode0 >= core.REACTING) & (mode == core.REPLAY) & (vp.K == 0)).any())
    return reacted, reset_back


@pytest.mark.slow
def test_reacting_cars_equal_single_envs(follower_folder):
    """The follower reacts (IDM) in the vector env as in single envs, and a reset gives it
    back its recording."""
    cfg = _config(follower_folder)
    assert VeiVectorEnv(4, cfg).CARS["car_mode"].shape == (4, 1)
    assert _against_singles(cfg, 4, 260, seed=7) == (True, True)
    # with a perception delay: the agent sees the cars' engine poses of 0.3 s ago
    assert _against_singles(_delayed(cfg), 4, 200, seed=8)[0]


@pytest.mark.slow
def test_worlds_with_and_without_reacting_cars(follower_folder, tmp_path):
    """A folder of the follower scene and a crossing without cars: each environment steps
    its own scenario's cars (the padded column of the carless one stays inert)."""
    import shutil

    from vei.io.scenario import write_scenario
    from vei.sim.testing import crossing_scenario

    shutil.copytree(follower_folder, tmp_path / "a_follower")
    write_scenario(crossing_scenario(), tmp_path / "b_crossing")
    cfg = _config(tmp_path)
    env = VeiVectorEnv(6, cfg)
    assert [ws.arrays.traffic.n for ws in env.world.scenarios] == [1, 0]
    env.reset(seed=3)
    assert set(env.SC.tolist()) == {0, 1}
    reacted, _ = _against_singles(cfg, 6, 220, seed=3)
    assert reacted


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_reacting_cars_move_the_contacts(follower_folder, backend):
    """Full braking from the start: the replayed follower (cars_react off) runs into the
    ego, the reacting one notices, brakes (IDM) and never touches it: the contacts read
    each environment's own car poses."""
    hits = []
    for react in (False, True):
        env = VeiVectorEnv(2, _config(follower_folder, react, backend))
        env.reset(seed=1)
        hit = False
        for _ in range(60):
            env.step(np.full((2, 1), -8.0, np.float32))
            hit |= bool(env.HIT[:, 0].any())
        hits.append(hit)
    assert hits == [True, False]


def _compiled_equals_numpy(
    cfg: EnvConfig, b: int, steps: int, seed: int, demand=None
) -> dict[str, bool]:
    """backend 'numba' == backend 'numpy' (observation, reward, flags, the float and bool
    state, the ego's contact latches and every car / contact field), step by step through
    autoresets, under random demands in [-8, 1] m/s^2 (or ``demand(rng, step)`` -> [b, 1]
    m/s^2). Returns what happened on the way."""
    envs = [VeiVectorEnv(b, dataclasses.replace(cfg, backend=x)) for x in ("numba", "numpy")]
    assert [e.backend for e in envs] == ["numba", "numpy"]
    outs = [e.reset(seed=seed)[0] for e in envs]
    assert np.array_equal(*outs)
    rng = np.random.default_rng(seed)
    keys = ("reacted", "driven", "contact", "terminated", "stopped", "rear_end",
            "rider_hit_other", "car_hit", "summaries_without_cars")  # fmt: skip
    seen = dict.fromkeys(keys, False)
    carless = np.array([ws.arrays.traffic.n == 0 for ws in envs[0].world.scenarios])
    for step in range(steps):
        if demand is None:
            a = rng.uniform(-8.0, 1.0, size=(b, 1)).astype(np.float32)
        else:
            a = np.asarray(demand(rng, step), np.float32)
        (oc, rc, tc, uc, _), (op, rp, tp, up, _) = (e.step(a) for e in envs)
        nb, npy = envs
        np.testing.assert_allclose(oc, op, rtol=0, atol=1e-5)
        np.testing.assert_allclose(rc, rp, rtol=0, atol=1e-9)
        assert np.array_equal(tc, tp) and np.array_equal(uc, up)
        np.testing.assert_allclose(nb.FS, npy.FS, rtol=0, atol=1e-9)
        assert np.array_equal(nb.BS, npy.BS) and np.array_equal(nb.HIT, npy.HIT)
        assert np.array_equal(nb.K, npy.K)
        for name, arr in npy.CARS.items():
            np.testing.assert_allclose(nb.CARS[name], arr, rtol=0, atol=1e-9, err_msg=name)
        mode = nb.CARS["car_mode"]
        seen["reacted"] |= bool((mode >= core.REACTING).any())
        seen["driven"] |= bool((mode >= core.IDM).any())
        seen["contact"] |= bool(nb.HIT.any())
        seen["terminated"] |= bool(tc.any())
        seen["stopped"] |= bool((mode == core.STOPPED).any())
        seen["rear_end"] |= bool(nb.CARS["rear_end"].any())
        seen["rider_hit_other"] |= bool(nb.CARS["rider_hit_other"].any())
        seen["car_hit"] |= bool(nb.CARS["car_hit"].any())
        seen["summaries_without_cars"] |= bool((nb.CARS["sec_count"][carless[nb.SC]] > 0).any())
    return seen


def test_compiled_cars_equal_numpy(follower_folder, tmp_path):
    """The compiled car step == the engine's NumPy step in every field, in a world of the
    follower scene and a crossing without cars (an e-scooter stands in the ego's lane: the
    contact summaries of a scenario without cars are kept too): the follower reacts and is
    driven by IDM; a slow, weakly braking follower (1.5 s, 3 m/s^2) runs into the braking
    agent (a rear-end contact ends the episode, the car stops)."""
    import shutil

    from vei.io.scenario import write_scenario
    from vei.sim.testing import TrackSpec, crossing_scenario

    seen = _compiled_equals_numpy(_config(follower_folder), 8, 150, seed=11)
    assert seen["reacted"] and seen["driven"]
    seen = _compiled_equals_numpy(_delayed(_config(follower_folder)), 8, 120, seed=4)
    assert seen["reacted"] and seen["driven"]
    shutil.copytree(follower_folder, tmp_path / "a_follower")
    t = np.arange(0, 501) * 0.05
    z = np.zeros_like(t)
    standing = TrackSpec("escooter", t, np.full_like(t, 4.0), z, z, z)  # 0.75 m ahead
    write_scenario(crossing_scenario(others=[("s1", standing)]), tmp_path / "b_crossing")
    weak = _config(tmp_path, reaction_time_s=1.5, max_decel_mps2=3.0)
    seen = _compiled_equals_numpy(weak, 8, 150, seed=5)
    assert seen.pop("rider_hit_other") is False and seen.pop("car_hit") is False
    assert all(seen.values()), seen


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_the_agent_sees_the_reacting_car_where_it_is(follower_folder, backend):
    """Full braking for 3 s: the agent's observation shows the reacting follower where the
    engine stopped it, behind the ego (object slot 1, x relative < -L_ego), while its
    recording has driven on past the ego (> 0): not the recorded pose."""
    env = VeiVectorEnv(2, _config(follower_folder, backend=backend))
    env.reset(seed=1)
    for _ in range(60):
        obs, *_ = env.step(np.full((2, 1), -8.0, np.float32))
    base = 6 + 9  # slot 1: valid, x, y (the ego's frame) ...
    assert (obs[:, base] == 1.0).all()
    assert (obs[:, base + 1] < -4.7).all(), obs[:, base + 1]
    k = int(env.K[0])
    a = env.world.scenarios[0].arrays
    assert a.other_x_m[k, 0] > env.FS[1, 0]  # the recording: ahead of the stopped ego
    assert (env.CARS["car_mode"] >= core.IDM).all()


@pytest.mark.slow
def test_compiled_cars_with_extra_riders_equal_numpy(tmp_path):
    """Reacting cars beside extra social-force riders (sim.sfm_riders='all'): the four-rider
    crossing with a car 1 s behind the ego; the compiled backend == the NumPy backend in
    every field (the contacts' summaries see the riders' contacts in the engine's order)."""
    from vei.config import SimConfig
    from vei.io.scenario import write_scenario
    from vei.sim.testing import TrackSpec, ego_straight, four_rider_scenario

    ego = ego_straight()
    car = TrackSpec("vehicle", ego.t_s, ego.x_m - 4.7 - 5.6, ego.y_m, ego.yaw_rad, ego.speed_mps)
    folder = write_scenario(four_rider_scenario([("car1", car)]), tmp_path / "four_car")
    cfg = dataclasses.replace(_config(folder, reaction_time_s=1.5, max_decel_mps2=3.0),
                              sim=SimConfig(sfm_riders="all"), max_episode_steps=200)  # fmt: skip
    seen = _compiled_equals_numpy(cfg, 8, 200, seed=2)
    assert seen["driven"] and seen["contact"] and seen["terminated"], seen


@pytest.mark.slow
def test_compiled_cars_rider_and_car_contacts_equal_numpy(tmp_path):
    """The rider's contacts with a reacting car and a driven car's with another road user
    (the order of vei.sim.contacts.contact_step: a car the rider hits stops at once): the
    crossing with a car 1 s behind the ego and an e-scooter crossing at x = 40 m, the
    replayed rider starting 7-10 s in, agents cruising or braking mildly."""
    from vei.io.scenario import write_scenario
    from vei.sim.testing import TrackSpec, crossing_scenario, ego_straight

    ego = ego_straight()
    car = TrackSpec("vehicle", ego.t_s, ego.x_m - 4.7 - 5.6, ego.y_m, ego.yaw_rad, ego.speed_mps)
    for t0 in (7.0, 8.0, 9.0, 10.0):
        tt = np.arange(int(t0 * 20) - 40, int(t0 * 20) + 120) / 20.0
        cr = TrackSpec("escooter", tt, np.full_like(tt, 40.0), -10.0 + 2.5 * (tt - tt[0]),
                       np.full_like(tt, np.pi / 2), np.full_like(tt, 2.5))  # fmt: skip
        scn = crossing_scenario(rider_t0_s=t0, others=[("car1", car), ("x1", cr)],
                                scenario_id=f"c{t0:g}")  # fmt: skip
        write_scenario(scn, tmp_path / f"s{int(t0)}")
    case = dataclasses.replace(
        case_preset("replay"), traffic=TrafficConfig(cars_react=True, reaction_time_s=0.5)
    )
    cfg = EnvConfig(source="folder", path=tmp_path, case=case, road_features=False,
                    max_episode_steps=400, time_shift_spread_s=3.0)  # fmt: skip
    b = 32
    cruising = np.arange(b)[:, None] < b // 4
    level = np.zeros((b, 1))

    def demand(rng, step):
        if step % 50 == 0:
            level[:] = np.where(np.arange(b)[:, None] < b // 2, 0.0, rng.uniform(-1.0, 0.0, (b, 1)))
        return np.where(cruising, 0.0, level + rng.normal(0.0, 0.3, (b, 1)))

    seen = _compiled_equals_numpy(cfg, b, 300, seed=5, demand=demand)
    assert seen["rider_hit_other"] and seen["car_hit"] and seen["driven"], seen


@pytest.mark.slow
def test_a_replaying_car_is_seen_with_its_recorded_speed(tmp_path):
    """A follower whose recorded speed varies (10 + 2 sin(t / 2) m/s): while it replays the
    agent sees its recorded speed (not its arc-length rate), as single envs, also with a
    perception delay."""
    from vei.io.scenario import write_scenario
    from vei.sim.testing import follower_scenario

    folder = write_scenario(follower_scenario(V, wave_mps=2.0), tmp_path / "wave")
    cfg = _config(folder)
    assert _against_singles(cfg, 2, 120, seed=3)[0]
    assert _against_singles(_delayed(cfg), 2, 120, seed=4)[0]
    assert _compiled_equals_numpy(cfg, 4, 120, seed=6)["reacted"]


def test_backend_choice_with_reacting_cars(follower_folder):
    """'auto' picks the compiled backend where cars react; without reaction no car state."""
    assert VeiVectorEnv(2, _config(follower_folder, backend="auto")).backend == "numba"
    assert VeiVectorEnv(2, _config(follower_folder, react=False)).CARS == {}
