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
