"""The vector env's features (the rider's obstacle braking and yield / go decision, the
perception delay) equal to the engine's NumPy step and to single envs, its refusals naming the features it does not
model, and a catalogue read once per encounter."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from vei.config import case_preset
from vei.config.behaviour import DecisionConfig
from vei.errors import ConfigError, InputError
from vei.gym import EnvConfig
from vei.gym.env import VeiEnv
from vei.gym.vector import VeiVectorEnv

pytest.importorskip("numba")

B = 4
#: Step at which environment i starts braking at 8 m/s^2 (cruising at +0.5 before): the
#: car stops 5-6 m before or on the rider's crossing at x = 60 m, depending on the episode's
#: time shift (seed 1, spread 2 s): environments 0 and 1 stand in the rider's way
#: (obstacle braking acts), 0-2 meet a rider that yields (found by a scan of 64 starts).
BRAKE_STEP = 150 + np.arange(B)
STEPS = 299


@pytest.fixture(scope="module")
def crossing_folder(tmp_path_factory):
    """vei.sim.testing's crossing: the ego along +x, an e-scooter crossing at x = 60 m."""
    from vei.io.scenario import write_scenario
    from vei.sim.testing import crossing_scenario

    return write_scenario(crossing_scenario(), tmp_path_factory.mktemp("cross") / "scenario")


def _config(folder, case, backend="numba") -> EnvConfig:
    return EnvConfig(
        source="folder", path=folder, case=case, road_features=False, max_episode_steps=300,
        time_shift_spread_s=2.0, backend=backend,
    )  # fmt: skip


def _actions(k: int) -> np.ndarray:
    return np.where(k < BRAKE_STEP, 0.5, -8.0)[:, None].astype(np.float32)


def _run(cfg: EnvConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(float states [T, 15, B], decisions [T, B], observations [T, B, D]) of B envs."""
    env = VeiVectorEnv(B, cfg)
    obs0, _ = env.reset(seed=1)
    fs, dec, obs = [], [], [obs0]
    for k in range(STEPS):
        o, *_ = env.step(_actions(k))
        fs.append(env.FS.copy())
        dec.append(env.BS[4].copy())
        obs.append(o)
    return np.array(fs), np.array(dec), np.array(obs)


def _singles(cfg: EnvConfig) -> np.ndarray:
    """Observations [T, B, D] of B single envs (the engine's own step) reset with 1 + i."""
    out = []
    for i in range(B):
        env = VeiEnv(cfg)
        rows = [env.reset(seed=1 + i)[0]]
        done = False
        for k in range(STEPS):
            if done:
                rows.append(env.reset()[0])
                done = False
                continue
            o, _, te, tr, _ = env.step(_actions(k)[i])
            rows.append(o)
            done = te or tr
        out.append(np.array(rows))
    return np.stack(out, axis=1)


@pytest.mark.slow
@pytest.mark.parametrize("feature", ["obstacle", "decision"])
def test_rider_feature_equals_the_engine(crossing_folder, feature):
    """The compiled step with the feature == the engine's NumPy step == single envs, and
    the feature changes the rider (against the same run without it)."""
    base = case_preset("normal")  # calibrated rider: obstacle braking on
    assert base.sfm.obstacle_braking
    without = dataclasses.replace(base, sfm=dataclasses.replace(base.sfm, obstacle_braking=False))
    case = base if feature == "obstacle" else dataclasses.replace(
        base, decision=DecisionConfig(enabled=True)
    )  # fmt: skip
    ref = without if feature == "obstacle" else base
    fs_n, dec_n, obs_n = _run(_config(crossing_folder, case, "numba"))
    fs_p, dec_p, obs_p = _run(_config(crossing_folder, case, "numpy"))
    assert np.abs(fs_n - fs_p).max() < 1e-9
    assert np.array_equal(dec_n, dec_p)
    np.testing.assert_allclose(obs_n, obs_p, rtol=1e-6, atol=1e-5)
    assert np.array_equal(obs_p, _singles(_config(crossing_folder, case)))
    fs_r, _, _ = _run(_config(crossing_folder, ref, "numba"))
    changed = np.abs(fs_n - fs_r).max(axis=(0, 1)) > 1e-6  # per environment
    if feature == "obstacle":
        assert changed[:2].all()  # the car stood in the rider's way
    else:
        assert (dec_n == 2).any(axis=0)[:3].all()  # YIELD
        assert changed[:3].all()


@pytest.mark.slow
def test_perception_delay_equals_the_engine(demo_config, real_folder):
    """A perception delay of 0.3 s (6 steps): the compiled observation == the engine's
    (PolicyDriver's ring) == single envs through autoresets, on the demo and on a real
    recording with six replayed riders; and the delay changes what the agent sees."""
    from tests.gym.test_vector import _compare

    for cfg in (demo_config, EnvConfig(source="folder", path=real_folder)):
        case = cfg.case
        delayed = dataclasses.replace(
            cfg, case=dataclasses.replace(case, cap=dataclasses.replace(case.cap, perception_delay_s=0.3)),
            max_episode_steps=80,
        )  # fmt: skip
        ended, _ = _compare(delayed, 4, 170, seed=5, accel=(-3.0, 3.0))
        assert ended >= 4  # autoresets: nothing perceived in the first 6 steps again
        a = np.zeros((4, 1), np.float32)
        env_d, env_0 = (
            VeiVectorEnv(4, delayed),
            VeiVectorEnv(4, dataclasses.replace(delayed, case=case)),
        )
        assert env_d.delay == 6 and env_0.delay == 0
        od, o0 = env_d.reset(seed=5)[0], env_0.reset(seed=5)[0]
        assert not od[:, 6].any() and o0[:, 6].any()  # slot 0 (the rider) not yet perceived
        for _ in range(30):
            od, o0 = env_d.step(a)[0], env_0.step(a)[0]
        assert od[:, 6].all() and not np.array_equal(od, o0)  # seen, 6 steps late


def test_refuses_what_it_does_not_model(demo_config):
    """Each feature the vector env does not model is a ConfigError naming it and the way out."""
    from vei.config import SimConfig
    from vei.config.behaviour import TrafficConfig
    from vei.config.perception import PerceptionConfig

    normal = case_preset("normal")
    cases = {
        r"a sensor model \(case\.perception\)": dataclasses.replace(
            normal, perception=PerceptionConfig(enabled=True)
        ),
        r"walking pedestrians \(traffic\.pedestrians\)": dataclasses.replace(
            normal, traffic=TrafficConfig(pedestrians=True)
        ),
    }
    for pattern, case in cases.items():
        with pytest.raises(ConfigError, match=pattern + ".*vectorization_mode='sync'"):
            VeiVectorEnv(2, dataclasses.replace(demo_config, case=case))
    # extra social-force riders are modelled (tests/gym/test_vector_riders.py), reacting
    # cars by the NumPy backend (tests/gym/test_vector_cars.py)
    assert VeiVectorEnv(2, dataclasses.replace(demo_config, sim=SimConfig(sfm_riders="all")))


def test_catalogue_one_world_per_encounter(demo_folder, tmp_path, capsys):
    """A catalogue table has a row per encounter and configuration: the world reads each
    encounter once (issue 34: 1,225 rows of 5 encounters took 1,000 s), and says so."""
    import shutil

    from vei.catalogue.store import TABLE, encounter_dir

    ids = ["demo__b", "demo__a"]
    for eid in ids:
        shutil.copytree(demo_folder, encounter_dir(tmp_path, eid) / "scenario")
    n = 1225
    pd.DataFrame(
        {
            "encounter_id": [ids[i % 2] for i in range(n)],
            "time_shift_auto_s": [1.5 if i % 2 == 0 else -0.5 for i in range(n)],
            "config": [f"c{i}" for i in range(n)],
        }
    ).to_parquet(tmp_path / TABLE)
    envs = VeiVectorEnv(4, EnvConfig(source="catalogue", path=tmp_path, time_shift_spread_s=0.0))
    assert [w.name for w in envs.world.scenarios] == ids  # table order, once each
    assert [w.base_shift_s for w in envs.world.scenarios] == [1.5, -0.5]
    err = capsys.readouterr().err
    assert "vei.gym: preparing scenarios: 2/2 scenarios" in err
    # a missing stored shift (NaN) is found again: the demo's automatic shift
    pd.DataFrame({"encounter_id": ["demo__a"] * 3, "time_shift_auto_s": [np.nan] * 3}).to_parquet(
        tmp_path / TABLE
    )
    from vei.io.scenario import read_scenario
    from vei.sim.timeshift import find_time_shift

    envs = VeiVectorEnv(2, EnvConfig(source="catalogue", path=tmp_path))
    auto = float(find_time_shift(read_scenario(demo_folder)))
    assert envs.world.n == 1 and envs.world.scenarios[0].base_shift_s == auto
    # an encounter whose rows disagree on the stored shift is named
    pd.DataFrame({"encounter_id": ["demo__a"] * 2, "time_shift_auto_s": [1.0, 2.0]}).to_parquet(
        tmp_path / TABLE
    )
    with pytest.raises(InputError, match=r"encounter 'demo__a' has rows with different"):
        VeiVectorEnv(2, EnvConfig(source="catalogue", path=tmp_path))
