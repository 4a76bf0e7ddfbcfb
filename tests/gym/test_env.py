"""The single Gymnasium environment: registration, Gymnasium's checker, determinism,
equality with `vei run` of the same actions, the reward's terms, bad input."""

from __future__ import annotations

import dataclasses

import gymnasium
import numpy as np
import pandas as pd
import pytest
from gymnasium.utils.env_checker import check_env

import vei.gym
from vei.errors import ConfigError, InputError
from vei.gym import ENV_ID, EnvConfig, RewardConfig
from vei.gym.env import VeiEnv


def _episode(env, seed: int, actions: np.ndarray):
    obs, info = env.reset(seed=seed)
    out = [obs]
    rewards, states = [], [env.unwrapped.state]
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        out.append(obs)
        rewards.append(r)
        states.append(env.unwrapped.state)
        if term or trunc:
            break
    return np.array(out), np.array(rewards), states, info


def test_registered_and_made_without_arguments():
    assert ENV_ID in gymnasium.registry
    env = gymnasium.make(ENV_ID)
    assert isinstance(env.unwrapped, VeiEnv)
    assert env.unwrapped.config.source == "demo"
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    assert info["scenario"] == "demo"
    assert env.action_space.shape == (1,)
    # the actuator's limits of the 'normal' configuration: full brake 8, full throttle 3 m/s^2
    assert env.action_space.low[0] == pytest.approx(-8.0)
    assert env.action_space.high[0] == pytest.approx(3.0)
    assert len(env.unwrapped.feature_names) == env.observation_space.shape[0]


def test_passes_gymnasium_env_checker(demo_config):
    env = VeiEnv(demo_config, render_mode="rgb_array")
    check_env(env, skip_render_check=False)
    env.reset(seed=0)
    img = env.render()
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3


def test_seeded_episode_is_bit_identical(demo_config):
    rng = np.random.default_rng(5)
    actions = rng.uniform(-8.0, 3.0, size=(300, 1)).astype(np.float32)
    a = _episode(VeiEnv(demo_config), 11, actions)
    b = _episode(VeiEnv(demo_config), 11, actions)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    for sa, sb in zip(a[2], b[2], strict=True):
        for name in ("ego_s_m", "ego_v_mps", "rider_x_m", "rider_y_m", "rider_vx_mps"):
            assert np.array_equal(getattr(sa, name), getattr(sb, name))
    # another seed draws another time shift (the episode's variation)
    c = VeiEnv(demo_config)
    c.reset(seed=12)
    assert c.time_shift_s != VeiEnv(demo_config).reset(seed=11)[1]["time_shift_s"]


def test_equals_vei_run_of_the_same_actions(demo_config, demo_folder, tmp_path):
    """An episode's actions replayed by `vei run` (vei.policy.replay.ActionReplay) give
    the same ego and rider states bit for bit."""
    from vei.cli.main import main
    from vei.policy.replay import write_actions

    env = VeiEnv(demo_config)
    rng = np.random.default_rng(1)
    actions = rng.uniform(-2.0, 3.0, size=(400, 1)).astype(np.float32)
    _, _, states, info = _episode(env, 4, actions)
    n = len(states) - 1
    write_actions(tmp_path / "actions.csv", actions[:n, 0].astype(np.float64))
    (tmp_path / "run.yaml").write_text(
        "case:\n  preset: normal\n  ego:\n    policy: vei.policy.replay:ActionReplay\n"
        f"    policy_params: {{actions_file: {tmp_path / 'actions.csv'}}}\n"
    )
    out = tmp_path / "run"
    args = ["run", str(demo_folder), "--config", str(tmp_path / "run.yaml"), "--time-shift",
            repr(info["time_shift_s"]), "--out", str(out), "--no-figures"]  # fmt: skip
    assert main(args) == 0
    ts = pd.read_parquet(out / "timeseries.parquet")
    ego = ts[ts["agent_id"] == "ego"].sort_values("t_s")
    rider = ts[ts["agent_id"] == env.world.scenarios[0].arrays.rider_id].sort_values("t_s")
    for k, st in enumerate(states):
        e, r = ego.iloc[k], rider.iloc[k]
        assert e["x_m"] == st.ego_x_m[0] and e["y_m"] == st.ego_y_m[0]
        assert e["speed_mps"] == st.ego_v_mps[0] and e["accel_mps2"] == st.ego_a_mps2[0]
        assert bool(r["active"]) == bool(st.rider_active[0])
        assert r["x_m"] == st.rider_x_m[0] and r["y_m"] == st.rider_y_m[0]
        assert bool(e["collided"]) == bool(st.collided[0])


def test_reward_terms_known_answers(demo_config):
    """Progress alone sums to the distance travelled (up to v_d dt a step); a contact gives
    the collision term and the injury risk of the impact speed of the step before it."""
    from vei.metrics.severity import injury_risk_of_speed

    only_progress = dataclasses.replace(
        demo_config, reward=RewardConfig(collision=0.0, injury_risk=0.0, progress=1.0, comfort=0.0)
    )
    env = VeiEnv(only_progress)
    env.reset(seed=2, options={"time_shift_s": -20.0})  # the rider long gone: no contact
    s0 = env.state.ego_s_m[0]
    total = 0.0
    for _ in range(100):
        _, r, term, trunc, info = env.step(np.array([-1.0], np.float32))  # below v_d
        total += r
        assert not term
    assert total == pytest.approx(env.state.ego_s_m[0] - s0, abs=1e-9)
    vd_dt = env._params.cruise_speed_mps[0] * 0.05
    _, r, _, _, _ = env.step(np.array([3.0], np.float32))
    _, r, _, _, _ = env.step(np.array([3.0], np.float32))
    assert env.state.ego_v_mps[0] < env._params.cruise_speed_mps[0]  # still below: all counted
    for _ in range(60):
        _, r, _, _, info = env.step(np.array([3.0], np.float32))
    assert env.state.ego_v_mps[0] > env._params.cruise_speed_mps[0] and r == pytest.approx(vd_dt)
    assert info["reward_terms"]["comfort"] == pytest.approx(env.state.ego_a_mps2[0] ** 2 * 0.05)
    # the automatic shift makes the replayed rider meet the ego's front at cruise speed
    env = VeiEnv(dataclasses.replace(demo_config, case="replay"))
    env.reset(seed=2, options={"time_shift_s": env.world.scenarios[0].base_shift_s})
    for _ in range(600):
        prev = env.state
        _, r, term, trunc, info = env.step(np.array([0.0], np.float32))
        if term:
            break
    assert term and not trunc and env.state.collided[0]
    v, yaw = prev.ego_v_mps[0], prev.ego_yaw_rad[0]
    impact = np.hypot(
        v * np.cos(yaw) - prev.rider_vx_mps[0], v * np.sin(yaw) - prev.rider_vy_mps[0]
    )
    terms = info["reward_terms"]
    assert terms["collision"] == 1.0
    assert terms["injury_risk"] == pytest.approx(float(injury_risk_of_speed(impact)))
    w = RewardConfig()
    expect = sum(getattr(w, k) * v for k, v in terms.items())
    assert r == pytest.approx(expect)
    # the car catches up with the rider riding ahead in its lane: a slow closing impact
    assert terms["injury_risk"] > 0 and 0.5 < impact < 5.6


def test_truncated_at_the_end_of_the_span(demo_config):
    env = VeiEnv(dataclasses.replace(demo_config, max_episode_steps=30))
    env.reset(seed=0, options={"time_shift_s": -20.0})
    flags = [env.step(np.array([0.0], np.float32))[3] for _ in range(30)]
    assert flags == [False] * 29 + [True]
    env = VeiEnv(demo_config)
    env.reset(seed=0, options={"time_shift_s": -20.0})
    n = 0
    while True:
        obs, _, term, trunc, info = env.step(np.array([0.0], np.float32))
        n += 1
        if term or trunc:
            break
    assert trunc and n == env.world.scenarios[0].arrays.n_steps - 1
    assert obs[env.unwrapped.feature_names.index("time_remaining_s")] == 0.0


def test_bad_input_errors(demo_config, tmp_path):
    env = VeiEnv(demo_config)
    with pytest.raises(InputError, match="before step"):
        env.step(np.array([0.0], np.float32))
    env.reset(seed=0)
    with pytest.raises(InputError, match=r"outside the action space.*\[-8, 3\] m/s\^2"):
        env.step(np.array([5.0], np.float32))
    with pytest.raises(InputError, match="outside the action space"):
        env.step(np.array([np.nan], np.float32))
    with pytest.raises(
        ConfigError, match=r"unknown reward term\(s\) 'colision'.*known terms: collision"
    ):
        gymnasium.make(ENV_ID, reward={"colision": -1.0})
    with pytest.raises(ConfigError, match="unknown env setting"):
        gymnasium.make(ENV_ID, max_object=3)
    with pytest.raises(ConfigError, match="preset"):
        EnvConfig(case="nomral")
    with pytest.raises(InputError, match="no scenario.json"):
        VeiEnv(EnvConfig(source="folder", path=tmp_path))


def test_scenario_without_map(demo_folder, tmp_path):
    """A scenario folder without map.xodr: a clear error naming the folder and the way
    out; with road_features=False it runs (and rider_on_road is not observed)."""
    import shutil

    from vei.io.scenario import read_scenario, write_scenario

    scen = read_scenario(demo_folder)
    folder = write_scenario(dataclasses.replace(scen, maps={}), tmp_path / "nomap")
    assert not (folder / "map.xodr").exists()
    with pytest.raises(InputError, match=r"no road map \(map.xodr\).*road_features=False") as err:
        VeiEnv(EnvConfig(source="folder", path=folder))
    assert str(folder) in str(err.value)
    env = VeiEnv(EnvConfig(source="folder", path=folder, road_features=False))
    obs, _ = env.reset(seed=0)
    assert "rider_on_road" not in env.feature_names and obs.shape == (6 + 9 * 4,)
    shutil.rmtree(folder)


def test_rider_on_road_from_the_map(demo_config):
    """The demo's rider rides in the street (its recorded path lies on the drivable lanes
    of the synthetic map): rider_on_road is 1 whenever the rider is observed."""
    env = VeiEnv(demo_config)
    env.reset(seed=0, options={"time_shift_s": env.world.scenarios[0].base_shift_s})
    names = env.feature_names
    seen = 0
    for _ in range(200):
        obs, _, term, _, _ = env.step(np.array([-8.0], np.float32))
        if obs[names.index("slot0.valid")]:
            seen += 1
            assert obs[names.index("rider_on_road")] == 1.0
        else:
            assert obs[names.index("rider_on_road")] == 0.0
        if term:
            break
    assert seen > 50


def test_demo_import_is_light():
    """`import vei.gym` registers without importing the engine's compiled kernel."""
    assert vei.gym.ENV_ID == ENV_ID
