"""Train a policy in vei.gym's vector env, then test it with ``vei risk`` -- no code changes.

The policy is linear on the vector env's observation vector (``accel = clip(w . x /
scale + b)``; vei.gym.features); the cross-entropy method (CEM: each generation draws
``population`` parameter vectors from a Gaussian, runs each on ``episodes`` episodes of
one vector env, refits the Gaussian to the best quarter) trains it on the built-in demo
(an e-scooter, the calibrated social-force rider, its timing varied by +-1 s). The
weights go to a JSON file; :class:`LinearGymPolicy` is a vei policy (docs/policy.md) that
reads them and rebuilds the same observation vector from the engine's Observation with
:func:`vei.gym.features.vectorize`, so the engine (``vei run``, ``vei risk``, ``vei
sweep``) runs the trained policy as it was trained, once per step for the whole batch:

    python examples/gym_trained_policy.py      # train (~10-30 s), write the weights, run vei risk
    vei risk SCENARIO --out risk --policy examples/gym_trained_policy.py:LinearGymPolicy

Two observation entries are not the policy's to use: ``time_remaining_s`` (the span's end
is the environment's, not the car's, knowledge) and ``rider_on_road`` (needs the map;
trained with ``road_features=False``): the first's weight is held at 0.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

#: Where ``main`` writes the trained weights and LinearGymPolicy reads them by default.
WEIGHTS = Path(__file__).with_name("gym_trained_policy.json")
MAX_OBJECTS = 4  # road-user slots of the observation
GAP_CAP_M = 60.0  # clip of distances [m]
#: Entries whose weight is held at 0 (unknown to a policy in the engine).
MASKED = ("time_remaining_s",)
EPISODE_STEPS = 300  # 15 s at 20 Hz
ENV_ID = "vei/Encounter-v0"


def feature_scale(names: tuple[str, ...]) -> np.ndarray:
    """A fixed scale per entry: metres 30, speeds 5, seconds 10, else 1."""
    out = np.ones(len(names))
    for i, n in enumerate(names):
        if n.endswith("_m"):
            out[i] = 30.0
        elif n.endswith("_mps"):
            out[i] = 5.0
        elif n.endswith("_s"):
            out[i] = 10.0
    return out


def linear_accel(
    w: np.ndarray, b: np.ndarray, x: np.ndarray, scale: np.ndarray, lo: Any, hi: Any
) -> np.ndarray:
    """The demanded acceleration [B] m/s^2 of weights w [B, D] (or [D]), offsets b [B] (or
    scalar) on observations x [B, D]: clip(sum(x w / scale) + b, lo, hi)."""
    x = np.asarray(x, np.float64)
    z = x @ (w / scale) if w.ndim == 1 else np.einsum("ij,ij->i", x, w / scale)
    return np.clip(z + b, lo, hi)


def make_env(num_envs: int) -> Any:
    """The training environment: the demo, no road features, 15 s episodes."""
    import gymnasium

    import vei.gym  # noqa: F401 - registers the id

    return gymnasium.make_vec(
        ENV_ID, num_envs=num_envs, road_features=False, max_objects=MAX_OBJECTS,
        gap_cap_m=GAP_CAP_M, max_episode_steps=EPISODE_STEPS, time_shift_spread_s=1.0,
    )  # fmt: skip


def returns(env: Any, thetas: np.ndarray, episodes: int, seed: int) -> tuple[np.ndarray, float]:
    """Mean return of each parameter vector (rows of thetas [P, D + 1]) over the first
    episode of its ``episodes`` environments (env.num_envs = P x episodes), and the share
    of those episodes that ended in a contact."""
    scale = feature_scale(env.feature_names)
    obs, _ = env.reset(seed=seed)
    w = np.repeat(thetas[:, :-1], episodes, axis=0)
    b = np.repeat(thetas[:, -1], episodes)
    ret = np.zeros(env.num_envs)
    hit = np.zeros(env.num_envs, dtype=bool)
    alive = np.ones(env.num_envs, dtype=bool)
    for _ in range(EPISODE_STEPS):
        a = linear_accel(w, b, obs, scale, env.action_low, env.action_high)
        obs, r, term, trunc, _ = env.step(a.astype(np.float32)[:, None])
        ret += np.where(alive, r, 0.0)
        hit |= alive & term
        alive &= ~(term | trunc)
        if not alive.any():
            break
    return ret.reshape(thetas.shape[0], episodes).mean(axis=1), float(hit.mean())


def train(
    generations: int = 12, population: int = 24, episodes: int = 16, seed: int = 0,
    verbose: bool = True,
) -> dict[str, Any]:  # fmt: skip
    """CEM on the vector env (module docstring).

    Returns:
        {'theta': the mean policy [D + 1] (weights, then the offset [m/s^2]),
        'names': the observation's entry names, 'history': [(generation, population
        mean, held-out return of the mean policy, its contact share)], 'cruise': the
        held-out return and contact share of a = 0}.
    """
    env = make_env(population * episodes)
    names = tuple(env.feature_names)
    d = len(names) + 1
    masked = np.array([n in MASKED for n in names] + [False])
    rng = np.random.default_rng(seed)
    mu, sigma = np.zeros(d), np.ones(d)
    held_out = 10_000
    cruise = returns(env, np.zeros((population, d)), episodes, held_out)
    history = []
    n_elite = max(2, population // 4)
    for g in range(generations):
        thetas = mu + sigma * rng.standard_normal((population, d))
        thetas[:, masked] = 0.0
        scores, _ = returns(env, thetas, episodes, seed=1 + g)
        elite = thetas[np.argsort(scores)[-n_elite:]]
        mu, sigma = elite.mean(axis=0), elite.std(axis=0) + 0.02
        res, hits = returns(env, np.repeat(mu[None], population, axis=0), episodes, held_out)
        history.append((g, float(scores.mean()), float(res.mean()), hits))
        if verbose:
            print(
                f"generation {g:2d}: population {scores.mean():6.2f}, mean policy on held-out "
                f"episodes {res.mean():6.2f} ({100 * hits:.0f} % contacts)",
                flush=True,
            )
    env.close()
    return {
        "theta": mu,
        "names": names,
        "history": history,
        "cruise": (float(cruise[0].mean()), cruise[1]),
    }


def save(theta: np.ndarray, names: tuple[str, ...], path: Path = WEIGHTS) -> Path:
    """Write the weights as JSON (atomically): the entry names, scales, weights, offset."""
    from vei.io.atomic import write_json

    write_json(
        Path(path),
        {
            "format": "vei.example.gym_linear/1",
            "max_objects": MAX_OBJECTS,
            "gap_cap_m": GAP_CAP_M,
            "features": list(names),
            "scale": feature_scale(names).tolist(),
            "weights": [float(v) for v in theta[:-1]],
            "offset_mps2": float(theta[-1]),
        },
    )
    return Path(path)


class LinearGymPolicy:
    """The trained linear policy as a vei policy (vei.policy API: init_state / act).

    Args:
        weights_file: the JSON ``save`` wrote (default: gym_trained_policy.json beside
            this file). ``vei risk --policy examples/gym_trained_policy.py:LinearGymPolicy``
            uses the default; in a run configuration ``policy_params: {weights_file: ...}``.
    """

    def __init__(self, weights_file: str | Path | None = None) -> None:
        from vei.errors import ConfigError
        from vei.gym.features import feature_names

        path = Path(weights_file) if weights_file is not None else WEIGHTS
        if not path.is_file():
            raise ConfigError(
                f"{path}: no trained weights; run 'python examples/gym_trained_policy.py' first"
            )
        raw = json.loads(path.read_text(encoding="utf-8"))
        self.max_objects = int(raw["max_objects"])
        self.cap_m = float(raw["gap_cap_m"])
        names = tuple(raw["features"])
        if names != feature_names(self.max_objects, False):
            raise ConfigError(f"{path}: features {names} are not vei.gym's observation layout")
        self.scale = np.array(raw["scale"], dtype=np.float64)
        self.w = np.array(raw["weights"], dtype=np.float64)
        self.b = float(raw["offset_mps2"])
        if self.w.shape != (len(names),) or not np.isfinite(self.w).all():
            raise ConfigError(f"{path}: expected {len(names)} finite weights")

    def init_state(self, batch_size: int) -> None:
        """No memory."""
        return None

    def act(self, obs: Any, state: Any) -> tuple[Any, Any]:
        """accel [B] m/s^2 = the linear map of the observation vector (vei.gym.features)
        of the batch's Observation, clipped to the car's limits."""
        from vei.gym.features import vectorize
        from vei.policy.base import PolicyAction

        x = vectorize(
            obs, max_objects=self.max_objects, cap_m=self.cap_m,
            time_remaining_s=np.zeros(obs.batch_size), rider_on_road=None,
        )  # fmt: skip
        a = linear_accel(self.w, self.b, x, self.scale, -obs.max_decel_mps2, obs.max_accel_mps2)
        return PolicyAction(accel_mps2=a), state


def main(argv: list[str]) -> int:
    """Train, write the weights, then run ``vei risk`` on the demo scenario with the
    trained policy and 'none' (a small Monte Carlo budget: an illustration)."""
    import tempfile

    from vei.cli.main import main as vei
    from vei.experiments.demo_map import write_demo_scenario

    out = train()
    path = save(out["theta"], out["names"])
    print(f"cruise at v_d (a = 0): {out['cruise'][0]:.2f}; weights written to {path}")
    tmp = Path(tempfile.mkdtemp(prefix="vei-gym-risk-"))
    scen = write_demo_scenario(tmp / "demo")
    args = ["risk", str(scen), "--out", str(tmp / "risk"), "--policy",
            f"{Path(__file__).resolve()}:LinearGymPolicy", "--policy", "none",
            "--method", "mc", "--budget", "2000", "--sobol", "0", "--configs", "none"]  # fmt: skip
    print("vei " + " ".join(args), flush=True)
    return vei(args)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
