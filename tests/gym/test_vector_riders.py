"""The vector env's extra social-force riders (``sim.sfm_riders``): the compiled step ==
the engine's NumPy step == single envs, through autoresets, on a synthetic four-rider
crossing and on a real recording; the riders are seen, touched and driven."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vei.config import SimConfig, case_preset
from vei.config.behaviour import DecisionConfig
from vei.gym import EnvConfig
from vei.gym.vector import VeiVectorEnv

pytest.importorskip("numba")

ALL = SimConfig(sfm_riders="all")


@pytest.fixture(scope="module")
def riders_folder(tmp_path_factory):
    """vei.sim.testing's four-rider crossing: e2 and e3 cross the ego's lane at x = 45 m and
    75 m, e4 rides along it (opposite direction), the primary crosses at x = 60 m."""
    from vei.io.scenario import write_scenario
    from vei.sim.testing import four_rider_scenario

    return write_scenario(four_rider_scenario(), tmp_path_factory.mktemp("riders") / "scenario")


def _case(variant: str):
    normal = case_preset("normal")
    if variant == "decisions+delay":
        return dataclasses.replace(
            normal, decision=DecisionConfig(enabled=True),
            cap=dataclasses.replace(normal.cap, perception_delay_s=0.3),
        )  # fmt: skip
    return case_preset(variant)


def _config(folder, variant: str, sim: SimConfig = ALL) -> EnvConfig:
    return EnvConfig(
        source="folder", path=folder, case=_case(variant), road_features=False,
        max_episode_steps=120, time_shift_spread_s=2.0, sim=sim,
    )  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("variant", ["normal", "decisions+delay", "replay"])
def test_extra_riders_equal_the_engine(riders_folder, variant):
    """The three extra riders' state, the observation (they are objects 1..3, before the
    others), rewards and flags agree with the engine's step and single envs."""
    from tests.gym.test_vector import _compare

    cfg = _config(riders_folder, variant)
    env = VeiVectorEnv(4, cfg)
    assert env.pk.xr is not None and env.pk.xr.n.tolist() == [3]
    ended, contacts = _compare(cfg, 4, 250, seed=2, accel=(-2.0, 3.0))
    assert ended >= 4  # autoresets
    assert contacts >= 1
    # the extra riders are seen: an e-scooter (category 0) in a slot after the rider's
    obs, _ = env.reset(seed=2)
    seen = False
    for _ in range(60):
        obs, *_ = env.step(np.zeros((4, 1), np.float32))
        slots = obs[:, 6 + 9 : 6 + 9 * cfg.max_objects].reshape(4, -1, 9)
        seen |= bool(((slots[:, :, 0] == 1) & (slots[:, :, 8] == 0)).any())
    assert seen


@pytest.mark.slow
def test_extra_riders_are_touched_and_driven(riders_folder):
    """A contact with an extra rider ends the episode with a collision term (as in the
    single env), and social-force extra riders are not their recordings: the observation
    differs from the same episodes with them replayed (sfm_riders = 'primary')."""
    cfg = _config(riders_folder, "normal")
    env = VeiVectorEnv(8, cfg)
    ref = VeiVectorEnv(8, dataclasses.replace(cfg, sim=SimConfig()))
    assert ref.pk.xr is None and ref.XS.shape[2] == 0
    env.reset(seed=0)
    ref.reset(seed=0)
    differs = touched = False
    for _ in range(110):
        a = np.full((8, 1), 1.0, np.float32)  # full speed ahead through the crossings
        before = env.XB[:, 3].copy()
        o, r, te, _, _ = env.step(a)
        o_ref, *_ = ref.step(a)
        differs |= not np.array_equal(o, o_ref)
        new = (env.XB[:, 3] & ~before).any(axis=1)
        if new.any():
            touched = True
            assert te[new].all() and (env.TERMS[new, 0] >= 1).all()  # the collision term
            assert (r[new] < cfg.reward.collision / 2).all()
    assert differs and touched


@pytest.mark.slow
def test_extra_riders_on_a_real_recording(real_folder):
    """stadtmitte_12 with every other rider social-force driven (its replayed others the
    cars and pedestrians, which repel the riders), the map's raster."""
    from tests.gym.test_vector import _compare

    cfg = EnvConfig(source="folder", path=real_folder, max_episode_steps=150, sim=ALL)
    env = VeiVectorEnv(2, cfg)
    assert env.pk.xr is not None and env.pk.xr.n[0] >= 2
    ended, _ = _compare(cfg, 3, 170, seed=4, accel=(-6.0, 3.0))
    assert ended >= 3


@pytest.mark.slow
def test_worlds_with_and_without_extra_riders(riders_folder, tmp_path):
    """A folder of three scenarios with three, one and no extra riders: the environments
    of each step their own riders (the padded columns stay inert, through autoresets from
    one scenario to another)."""
    import shutil

    from tests.gym.test_vector import _compare
    from vei.io.scenario import write_scenario
    from vei.sim.testing import TrackSpec, crossing_scenario

    shutil.copytree(riders_folder, tmp_path / "a_riders")
    t = np.arange(20, 221) / 20.0  # one e-scooter crossing at x = 40 m from t = 1 s at 3 m/s
    one = TrackSpec("escooter", t, np.full_like(t, 40.0), -15.0 + 3.0 * (t - 1.0),
                    np.full_like(t, np.pi / 2), np.full_like(t, 3.0))  # fmt: skip
    write_scenario(crossing_scenario(others=[("e9", one)], scenario_id="one"), tmp_path / "b_one")
    write_scenario(crossing_scenario(), tmp_path / "c_crossing")
    cfg = dataclasses.replace(_config(riders_folder, "normal"), path=tmp_path)
    env = VeiVectorEnv(8, cfg)
    assert env.pk.xr is not None and env.pk.xr.n.tolist() == [3, 1, 0]
    env.reset(seed=4)
    assert set(env.SC.tolist()) == {0, 1, 2}  # every scenario drawn
    ended, _ = _compare(cfg, 8, 200, seed=4, accel=(-2.0, 3.0))
    assert ended >= 8
    for _ in range(150):  # through autoresets from one scenario to the other
        env.step(np.zeros((8, 1), np.float32))
        assert not env.XB[env.SC == 2].any()  # no riders where the scenario has none
        assert not env.XB[env.SC == 1, :, 1:].any()  # one where it has one
