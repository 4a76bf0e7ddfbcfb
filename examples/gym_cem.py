"""Train a small policy on vei's Gymnasium environment and watch it learn.

A linear policy on the observation (``accel = clip(W . obs / scale + b)``, 44 numbers) is
trained by the cross-entropy method (CEM): each generation draws ``POPULATION`` parameter
vectors from a Gaussian, runs each on ``EPISODES`` episodes of the batched vector env
(one ``step`` call advances all of them: population x episodes environments), keeps the
best ``ELITE`` share by mean return and refits the Gaussian to them. The scenario is the
built-in demo (an e-scooter ahead of the car, the rider's timing varied by +-1 s per
episode) with the calibrated social-force rider.

Why CEM and not Stable-Baselines3 / CleanRL: those need PyTorch, whose PyPI wheels for
Linux bring the CUDA libraries (several GB) -- too big a download for an example on a
2-core machine without a GPU. CEM is a well-known, dependency-free baseline for small
policies (Szita & Loerincz 2006, "Learning Tetris Using the Noisy Cross-Entropy
Method"); any Gymnasium-compatible RL library trains on the same env unchanged.

    python examples/gym_cem.py               # ~1 min on 2 cores: return per generation
"""

from __future__ import annotations

import numpy as np

import vei.gym  # noqa: F401 - registers vei/Encounter-v0

POPULATION = 24
EPISODES = 16
ELITE = 0.25
GENERATIONS = 15
EPISODE_STEPS = 300  # 15 s at 20 Hz
SEED = 0


def _scale(env) -> np.ndarray:
    """A fixed scale per observation entry (metres ~ 30, speeds ~ 5, flags 1)."""
    names = env.feature_names
    out = np.ones(len(names))
    for i, n in enumerate(names):
        if n.endswith(("_m",)):
            out[i] = 30.0
        elif n.endswith(("_mps",)):
            out[i] = 5.0
        elif n.endswith("_s"):
            out[i] = 10.0
    return out


def evaluate(
    env, thetas: np.ndarray, seed: int, scale: np.ndarray, contacts: bool = False
) -> np.ndarray:
    """Mean return of each parameter vector (rows of ``thetas`` [P, D + 1]) over the first
    episode of each of its EPISODES environments (env.num_envs = P * EPISODES); with
    ``contacts`` also the share of those episodes that ended in a contact."""
    p = thetas.shape[0]
    obs, _ = env.reset(seed=seed)
    w = np.repeat(thetas[:, :-1], EPISODES, axis=0)
    b = np.repeat(thetas[:, -1], EPISODES)
    ret = np.zeros(env.num_envs)
    hit = np.zeros(env.num_envs, dtype=bool)
    alive = np.ones(env.num_envs, dtype=bool)
    lo, hi = env.action_low, env.action_high
    for _ in range(EPISODE_STEPS):
        a = np.clip(np.einsum("ij,ij->i", w, obs / scale) + b, lo, hi)
        obs, r, term, trunc, _ = env.step(a.astype(np.float32)[:, None])
        ret += np.where(alive, r, 0.0)
        hit |= alive & term
        alive &= ~(term | trunc)
        if not alive.any():
            break
    out = ret.reshape(p, EPISODES).mean(axis=1)
    return (out, float(hit.mean())) if contacts else out


def random_policy_return(env, seed: int) -> float:
    """Mean return of the uniformly random policy on the same episodes."""
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    ret = np.zeros(env.num_envs)
    alive = np.ones(env.num_envs, dtype=bool)
    for _ in range(EPISODE_STEPS):
        a = rng.uniform(env.action_low, env.action_high, size=(env.num_envs, 1))
        obs, r, term, trunc, _ = env.step(a.astype(np.float32))
        ret += np.where(alive, r, 0.0)
        alive &= ~(term | trunc)
    return float(ret.mean())


def train(generations: int = GENERATIONS, verbose: bool = True) -> dict[str, object]:
    """Run CEM; returns {'random': mean random-policy return, 'cruise' / 'cruise_contacts':
    the return and contact share of cruising at v_d (a = 0), 'history': [(generation,
    population mean, best candidate, the mean policy's return and contact share on the
    held-out episodes)], 'theta': the mean policy}."""
    import gymnasium

    env = gymnasium.make_vec(
        "vei/Encounter-v0", num_envs=POPULATION * EPISODES,
        max_episode_steps=EPISODE_STEPS, time_shift_spread_s=1.0,
    )  # fmt: skip
    scale = _scale(env)
    d = env.single_observation_space.shape[0] + 1
    rng = np.random.default_rng(SEED)
    mu, sigma = np.zeros(d), np.full(d, 1.0)
    test_seed = 10_000
    rand = random_policy_return(env, test_seed)
    cruise, cruise_hits = evaluate(env, np.zeros((POPULATION, d)), test_seed, scale, True)
    if verbose:
        print(
            f"random policy {rand:.2f}; cruise at v_d (a = 0) {cruise.mean():.2f} with "
            f"{100 * cruise_hits:.0f} % contacts (held-out episodes)",
            flush=True,
        )
    history = []
    n_elite = max(2, int(round(ELITE * POPULATION)))
    for g in range(generations):
        thetas = mu + sigma * rng.standard_normal((POPULATION, d))
        scores = evaluate(env, thetas, seed=g * 7919, scale=scale)
        elite = thetas[np.argsort(scores)[-n_elite:]]
        mu, sigma = elite.mean(axis=0), elite.std(axis=0) + 0.02
        res, hits = evaluate(env, np.repeat(mu[None], POPULATION, axis=0), test_seed, scale, True)
        test = float(res.mean())
        history.append((g, float(scores.mean()), float(scores.max()), test, hits))
        if verbose:
            print(
                f"generation {g:2d}: population mean {scores.mean():6.2f}  best {scores.max():6.2f}  "
                f"mean policy on held-out episodes {test:6.2f} ({100 * hits:.0f} % contacts)",
                flush=True,
            )
    return {
        "random": rand,
        "cruise": float(cruise.mean()),
        "cruise_contacts": cruise_hits,
        "history": history,
        "theta": mu,
    }


if __name__ == "__main__":
    train()
