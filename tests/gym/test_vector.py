"""The batched vector environment: Gymnasium's vector conventions (make_vec, batched
spaces, NEXT_STEP autoreset), and the compiled step equal to the engine's own step."""

from __future__ import annotations

import dataclasses

import gymnasium
import numpy as np
import pandas as pd
import pytest
from gymnasium.vector import AutoresetMode

import vei.gym  # noqa: F401 - registers the id
from vei.errors import ConfigError, InputError
from vei.gym import ENV_ID, EnvConfig
from vei.gym.env import VeiEnv
from vei.gym.vector import VeiVectorEnv

pytest.importorskip("numba")


def test_make_vec_gives_the_batched_env():
    envs = gymnasium.make_vec(ENV_ID, num_envs=5)
    assert isinstance(envs, VeiVectorEnv) and envs.num_envs == 5
    assert envs.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert envs.observation_space.shape == (5, envs.single_observation_space.shape[0])
    assert envs.action_space.shape == (5, 1)
    obs, info = envs.reset(seed=0)
    assert obs.shape == envs.observation_space.shape and obs.dtype == np.float32
    assert envs.observation_space.contains(obs)
    obs, rew, term, trunc, _ = envs.step(envs.action_space.sample())
    assert rew.shape == term.shape == trunc.shape == (5,)
    assert envs.observation_space.contains(obs)


def _compare(config: EnvConfig, b: int, steps: int, seed: int, accel: tuple[float, float]):
    """numba backend == numpy backend (the engine's step) == b single envs of seed + i,
    over `steps` steps of random demands, autoresets included."""
    vn = VeiVectorEnv(b, dataclasses.replace(config, backend="numba"))
    vp = VeiVectorEnv(b, dataclasses.replace(config, backend="numpy"))
    singles = [VeiEnv(config) for _ in range(b)]
    on, inf_n = vn.reset(seed=seed)
    op, _ = vp.reset(seed=seed)
    first = [e.reset(seed=seed + i) for i, e in enumerate(singles)]
    assert np.array_equal(on, op) and np.array_equal(on, np.stack([o for o, _ in first]))
    assert np.array_equal(inf_n["time_shift_s"], [i["time_shift_s"] for _, i in first])
    rng = np.random.default_rng(seed)
    done = np.zeros(b, dtype=bool)
    ended = contacts = 0
    worst = 0.0
    for _ in range(steps):
        a = rng.uniform(*accel, size=(b, 1)).astype(np.float32)
        o1, r1, te1, tr1, _ = vn.step(a)
        o2, r2, te2, tr2, _ = vp.step(a)
        rows = []
        for i, e in enumerate(singles):
            rows.append((e.reset()[0], 0.0, False, False) if done[i] else e.step(a[i]))
        o3 = np.stack([r[0] for r in rows])
        r3 = np.array([r[1] for r in rows])
        te3 = np.array([r[2] for r in rows])
        tr3 = np.array([r[3] for r in rows])
        done = te3 | tr3
        assert np.array_equal(te1, te2) and np.array_equal(tr1, tr2)
        assert np.array_equal(te2, te3) and np.array_equal(tr2, tr3)
        np.testing.assert_allclose(r1, r2, rtol=0, atol=1e-9)
        assert np.array_equal(r2, r3)  # the same engine step and the same reward code
        np.testing.assert_allclose(o1, o2, rtol=1e-6, atol=1e-5)
        assert np.array_equal(o2, o3)
        worst = max(worst, float(np.abs(vn.FS - vp.FS).max()))
        if vn.XS.size:  # the extra social-force riders (sim.sfm_riders)
            worst = max(worst, float(np.abs(vn.XS - vp.XS).max()))
        assert np.array_equal(vn.BS, vp.BS) and np.array_equal(vn.HIT, vp.HIT)
        assert np.array_equal(vn.XB, vp.XB)
        assert np.array_equal(vn.K, vp.K)
        ended += int((te1 | tr1).sum())
        contacts += int(te1.sum())
    # compiled vs NumPy: the same equations, libm vs NumPy's vectorised functions
    assert worst < 1e-9, worst
    return ended, contacts


def test_compiled_step_equals_the_engine_on_the_demo(demo_config):
    for case in ("normal", "replay", "aggressive"):
        cfg = dataclasses.replace(
            demo_config, case=case, max_episode_steps=120, time_shift_spread_s=1.0
        )
        ended, contacts = _compare(cfg, 6, 260, seed=3, accel=(-3.0, 3.0))
        assert ended >= 6  # every environment went through an autoreset
        if case == "replay":
            assert contacts >= 1  # the contact path (freeze, collision term) is exercised


def test_compiled_step_equals_the_engine_on_a_real_recording(real_folder):
    """stadtmitte_12: six replayed riders besides the primary one (the nearest-slot choice),
    the Ingolstadt map's raster, a real ego path."""
    cfg = EnvConfig(source="folder", path=real_folder, max_episode_steps=200)
    vn = VeiVectorEnv(2, cfg)
    assert vn.pk.n_o[0] > cfg.max_objects - 1  # more others than slots: the nearest choice matters
    ended, _ = _compare(cfg, 4, 230, seed=9, accel=(-8.0, 3.0))
    assert ended >= 4


def test_next_step_autoreset(demo_config):
    cfg = dataclasses.replace(demo_config, max_episode_steps=3)
    envs = VeiVectorEnv(2, cfg)
    obs0, _ = envs.reset(seed=1)
    a = np.zeros((2, 1), np.float32)
    for _ in range(2):
        _, _, term, trunc, _ = envs.step(a)
        assert not (term | trunc).any()
    _, rew, term, trunc, _ = envs.step(a)
    assert trunc.all() and not term.any()
    # the next step resets (action ignored): the first observation of a new episode
    obs, rew, term, trunc, _ = envs.step(np.full((2, 1), 3.0, np.float32))
    assert not (term | trunc).any() and (rew == 0).all()
    assert (envs.K == 0).all()
    single = VeiEnv(cfg)
    single.reset(seed=1)
    for _ in range(3):
        single.step(a[0])
    first, _ = single.reset()  # the same generator continues: the same new episode
    assert np.array_equal(obs[0], first)


def test_vector_bad_input(demo_config):
    envs = VeiVectorEnv(3, demo_config)
    with pytest.raises(InputError, match="before step"):
        envs.step(np.zeros((3, 1), np.float32))
    envs.reset(seed=0)
    with pytest.raises(
        InputError, match=r"action 9\.0 \(environment 1\) is outside the action space"
    ):
        envs.step(np.array([[0.0], [9.0], [0.0]], np.float32))
    with pytest.raises(InputError, match="expected 3 action"):
        envs.step(np.zeros((2, 1), np.float32))
    with pytest.raises(ConfigError, match="num_envs"):
        VeiVectorEnv(0, demo_config)


def test_catalogue_source(demo_folder, tmp_path):
    """A catalogue: each encounter's scenario with its stored automatic time shift."""
    import shutil

    from vei.catalogue.store import TABLE, encounter_dir

    for eid in ("demo__a", "demo__b"):
        shutil.copytree(demo_folder, encounter_dir(tmp_path, eid) / "scenario")
    pd.DataFrame(
        {"encounter_id": ["demo__a", "demo__b"], "time_shift_auto_s": [1.5, -0.5]}
    ).to_parquet(tmp_path / TABLE)
    envs = VeiVectorEnv(8, EnvConfig(source="catalogue", path=tmp_path, time_shift_spread_s=0.0))
    assert [w.name for w in envs.world.scenarios] == ["demo__a", "demo__b"]
    _, info = envs.reset(seed=0)
    shifts = dict(zip(info["scenario_index"], info["time_shift_s"], strict=True))
    assert set(shifts) == {0, 1} and shifts[0] == 1.5 and shifts[1] == -0.5
    with pytest.raises(InputError, match="not a vei catalogue"):
        VeiVectorEnv(2, EnvConfig(source="catalogue", path=demo_folder))
