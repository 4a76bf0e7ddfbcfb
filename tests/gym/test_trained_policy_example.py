"""examples/gym_trained_policy.py: trained in the vector env, run by the engine as trained
(the same actions step for step), and by ``vei risk --policy file.py:Class`` unchanged."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from vei.errors import ConfigError

pytest.importorskip("numba")

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "gym_trained_policy.py"


@pytest.fixture(scope="module")
def example():
    spec = importlib.util.spec_from_file_location("vei_example_gym_trained_policy", EXAMPLE)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def weights(example, tmp_path_factory):
    """Two CEM generations of 4 x 2 environments, saved."""
    out = example.train(generations=2, population=4, episodes=2, verbose=False)
    return example.save(out["theta"], out["names"], tmp_path_factory.mktemp("w") / "w.json"), out


def test_training_pieces(example, weights):
    path, out = weights
    names = out["names"]
    assert len(out["theta"]) == len(names) + 1 and len(out["history"]) == 2
    assert "rider_on_road" not in names  # trained without the map entry
    assert out["theta"][names.index("time_remaining_s")] == 0.0  # masked
    raw = json.loads(path.read_text())
    assert raw["features"] == list(names) and len(raw["weights"]) == len(names)
    pol = example.LinearGymPolicy(path)
    np.testing.assert_array_equal(pol.w, out["theta"][:-1])
    # the linear map by hand: w . x / scale + b, clipped
    x = np.zeros((1, len(names)))
    x[0, 0] = 5.0  # ego_speed_mps, scale 5
    a = example.linear_accel(pol.w, pol.b, x, pol.scale, -8.0, 3.0)
    assert a[0] == pytest.approx(np.clip(pol.w[0] * 1.0 + pol.b, -8.0, 3.0))
    bad = path.with_name("bad.json")
    bad.write_text(json.dumps({**raw, "weights": raw["weights"][:-1]}))
    with pytest.raises(ConfigError, match="finite weights"):
        example.LinearGymPolicy(bad)
    with pytest.raises(ConfigError, match="no trained weights"):
        example.LinearGymPolicy(path.with_name("missing.json"))


def test_engine_runs_it_as_trained(example, weights):
    """The policy on the single env's observation vector and the same policy in the
    engine's seat (vei.sim.engine.simulate, the Observation -> vectorize path) drive the
    same episode (to the float32 rounding of the env's actions)."""
    import gymnasium

    from vei.sim.engine import simulate

    path, _ = weights
    pol = example.LinearGymPolicy(path)
    env = gymnasium.make(
        example.ENV_ID, road_features=False, max_objects=example.MAX_OBJECTS,
        gap_cap_m=example.GAP_CAP_M, time_shift_spread_s=1.0,
    ).unwrapped  # fmt: skip
    obs, info = env.reset(seed=4)
    s = [env.state.ego_s_m[0]]
    done = False
    while not done:
        a = example.linear_accel(
            pol.w, pol.b, obs[None], pol.scale, env.action_low, env.action_high
        )
        obs, _, term, trunc, _ = env.step(a.astype(np.float32))
        s.append(env.state.ego_s_m[0])
        done = term or trunc
    ws = env.world.scenarios[info["scenario_index"]]
    params = ws.params.with_values(
        policy=np.array([pol], dtype=object), time_shift_s=np.array([info["time_shift_s"]])
    )
    res = simulate(ws.arrays, params, record="full")
    n = len(s)
    np.testing.assert_allclose(res.ego_s_m[0, :n], s, rtol=0, atol=1e-4)
    assert np.ptp(np.diff(s)) > 1e-3  # the policy changed the car's speed


@pytest.mark.slow
def test_vei_risk_runs_the_trained_policy(example, weights, tmp_path):
    """`vei risk SCEN --policy examples/gym_trained_policy.py:LinearGymPolicy` with the
    weights beside the file (here: the committed ones) exits 0 and estimates it."""
    from vei.cli.main import main
    from vei.experiments.demo_map import write_demo_scenario

    assert example.WEIGHTS.is_file()  # committed: --policy works without training first
    scen = write_demo_scenario(tmp_path / "demo")
    args = ["risk", str(scen), "--out", str(tmp_path / "risk"), "--policy",
            f"{EXAMPLE}:LinearGymPolicy", "--method", "mc", "--budget", "100", "--sobol", "0",
            "--configs", "none", "--no-progress"]  # fmt: skip
    assert main(args) == 0
    raw = json.loads((tmp_path / "risk" / "risk.json").read_text())
    assert "LinearGymPolicy" in json.dumps(raw)
