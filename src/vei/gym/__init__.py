"""Gymnasium environments on vei's engine: one car, the agent, among real road users.

``import vei.gym`` registers (Gymnasium 1.x):

- ``vei/Encounter-v0``: ``gymnasium.make("vei/Encounter-v0")`` is a :class:`VeiEnv` on the
  built-in demo scenario (the synthetic case study of vei.experiments.demo_data, with its
  synthetic map); ``gymnasium.make_vec("vei/Encounter-v0", num_envs=B)`` is the batched
  :class:`VeiVectorEnv` (one compiled call steps all B). Keyword arguments are
  :class:`EnvConfig` fields (``source="folder", path="scen"``, ``reward={"progress": 0.2}``,
  ``case="aggressive"``, ...).

The agent demands the ego's longitudinal acceleration [m/s^2] (a Box of the actuator's
limits); the ego follows its recorded path; the observation is built from the policy
API's Observation (vei.gym.features); the reward's terms are collision, injury risk,
progress and comfort (:class:`RewardConfig`). See docs/gym.md.
"""

from __future__ import annotations

from vei.gym.config import REWARD_TERMS, EnvConfig, RewardConfig

#: The registered environment id (docs/gym.md).
ENV_ID = "vei/Encounter-v0"


def register() -> None:
    """Register :data:`ENV_ID` with Gymnasium (idempotent; done on import)."""
    import gymnasium

    if ENV_ID in gymnasium.registry:
        return
    gymnasium.register(
        id=ENV_ID,
        entry_point="vei.gym.env:VeiEnv",
        vector_entry_point="vei.gym.vector:VeiVectorEnv",
    )


register()


def __getattr__(name: str):  # noqa: ANN202 - lazy exports (the env modules import the engine)
    if name == "VeiEnv":
        from vei.gym.env import VeiEnv

        return VeiEnv
    if name == "VeiVectorEnv":
        from vei.gym.vector import VeiVectorEnv

        return VeiVectorEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "ENV_ID",
    "REWARD_TERMS",
    "EnvConfig",
    "RewardConfig",
    "VeiEnv",
    "VeiVectorEnv",
    "register",
]
