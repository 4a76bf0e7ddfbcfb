"""The vector env's reacting cars (``traffic.cars_react``, backend 'numpy'): the engine's
step with each environment's own car state == single envs, through autoresets, on a car
recorded 1 s behind the ego (it reacts when the agent brakes, and stops short); the
compiled backend refuses them by name."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from vei.config import TrafficConfig, case_preset
from vei.errors import ConfigError
from vei.gym import EnvConfig
from vei.gym.env import VeiEnv
from vei.gym.vector import VeiVectorEnv
from vei.models import traffic_core as core
from vei.sim.testing import TrackSpec, make_scenario
from vei.types import EGO_ID

V = 10.0  # both cars' recorded speed [m/s]


@pytest.fixture(scope="module")
def follower_folder(tmp_path_factory):
    """tests/sim/test_traffic.py's scene: the ego at 10 m/s along +x, a car 1 s (10 m)
    behind it bumper to bumper at the same speed, an e-scooter standing far away."""
    from vei.io.scenario import write_scenario

    t = np.arange(0, 301) * 0.05
    z = np.zeros_like(t)
    ego = TrackSpec("ego", t, 20.0 + V * t, z, z, np.full_like(t, V))
    fol = TrackSpec("vehicle", t, 20.0 + V * t - 4.7 - V, z, z, np.full_like(t, V))
    rider = TrackSpec("escooter", t, np.full_like(t, 400.0), np.full_like(t, 40.0),
                      np.full_like(t, math.pi / 2), z)  # fmt: skip
    scn = make_scenario({EGO_ID: ego, "car1": fol, "r1": rider}, primary_threat="r1")
    return write_scenario(scn, tmp_path_factory.mktemp("cars") / "scenario")


def _config(folder, react: bool = True, backend: str = "numpy") -> EnvConfig:
    case = dataclasses.replace(case_preset("normal"), traffic=TrafficConfig(cars_react=react))
    return EnvConfig(
        source="folder", path=folder, case=case, road_features=False, max_episode_steps=100,
        time_shift_spread_s=1.0, backend=backend,
    )  # fmt: skip


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


def test_reacting_cars_move_the_contacts(follower_folder):
    """Full braking from the start: the replayed follower (cars_react off) runs into the
    ego, the reacting one notices, brakes (IDM) and never touches it: the contacts read
    each environment's own car poses."""
    hits = []
    for react in (False, True):
        env = VeiVectorEnv(2, _config(follower_folder, react))
        env.reset(seed=1)
        hit = False
        for _ in range(60):
            env.step(np.full((2, 1), -8.0, np.float32))
            hit |= bool(env.HIT[:, 0].any())
        hits.append(hit)
    assert hits == [True, False]


def test_compiled_backend_refuses_reacting_cars(follower_folder):
    with pytest.raises(ConfigError, match=r"reacting cars \(traffic\.cars_react\).*'numpy'"):
        VeiVectorEnv(2, _config(follower_folder, backend="numba"))
    assert VeiVectorEnv(2, _config(follower_folder, backend="auto")).backend == "numpy"
    assert VeiVectorEnv(2, _config(follower_folder, react=False)).CARS == {}
