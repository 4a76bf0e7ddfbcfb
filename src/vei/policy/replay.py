"""A policy that replays a recorded sequence of demanded accelerations (an action file).

``vei run`` drives the ego with it to reproduce what an agent did, e.g. an episode of the
Gymnasium environment (vei.gym), step for step::

    # run.yaml
    case:
      preset: normal
      ego:
        policy: vei.policy.replay:ActionReplay
        policy_params: {actions_file: actions.csv}
    time_shift: 1.25

The file holds one demanded longitudinal acceleration [m/s^2] per engine step k = 0, 1,
... (the demand applied from step k to k + 1): a ``.npy`` array of shape [n], or a text
file (``.csv`` / ``.txt``) with one number per line, an optional header line
``accel_mps2`` first. After the last recorded action it demands ``after_end_mps2``
(default 0). Every variant of the batch replays the same sequence.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

from vei.errors import ConfigError, InputError
from vei.policy.base import PolicyAction
from vei.policy.observation import Observation

#: Header line a text action file may start with.
HEADER = "accel_mps2"


def read_actions(path: str | Path) -> npt.NDArray[np.float64]:
    """The accelerations [m/s^2] of an action file (see the module docstring).

    Raises:
        InputError: missing file, a line that is not a number, NaN / inf, no action.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError("action file not found", path=p)
    if p.suffix == ".npy":
        try:
            a = np.load(p, allow_pickle=False)
        except ValueError as exc:
            raise InputError(f"not a NumPy array file: {exc}", path=p) from None
        a = np.asarray(a, dtype=np.float64)
        if a.ndim != 1:
            raise InputError(f"expected a 1-D array of accelerations, got shape {a.shape}", path=p)
    else:
        vals = []
        lines = p.read_text().splitlines()
        for i, line in enumerate(lines, start=1):
            text = line.strip()
            if not text or (i == 1 and text == HEADER):
                continue
            try:
                vals.append(float(text))
            except ValueError:
                raise InputError(f"{text!r} is not a number", path=p, row=i) from None
        a = np.array(vals, dtype=np.float64)
    if a.size == 0:
        raise InputError("the action file holds no action", path=p)
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        raise InputError(f"action {int(bad[0])} is {a[bad[0]]!r}, expected a finite number", path=p)
    return a


def write_actions(path: str | Path, accel_mps2: npt.ArrayLike) -> Path:
    """Write accelerations [m/s^2] as a text action file (header + one repr per line:
    floats round-trip exactly), atomically."""
    from vei.io.atomic import atomic_path

    a = np.asarray(accel_mps2, dtype=np.float64).ravel()
    p = Path(path)
    with atomic_path(p) as tmp:
        Path(tmp).write_text(HEADER + "\n" + "".join(f"{float(x)!r}\n" for x in a))
    return p


class ActionReplay:
    """Replay an action file (see the module docstring).

    Args:
        actions_file: the file. after_end_mps2: the demand after the last action [m/s^2].
    """

    name = "vei.policy.replay:ActionReplay"

    def __init__(self, actions_file: str, after_end_mps2: float = 0.0) -> None:
        if not isinstance(actions_file, str | Path):
            raise ConfigError(f"actions_file must be a path, got {actions_file!r}")
        if not np.isfinite(after_end_mps2):
            raise ConfigError(f"after_end_mps2 must be finite, got {after_end_mps2!r}")
        self.actions = read_actions(actions_file)
        self.after_end_mps2 = float(after_end_mps2)

    def init_state(self, batch_size: int) -> int:
        """The next step's index (0)."""
        return 0

    def act(self, obs: Observation, state: int) -> tuple[PolicyAction, int]:
        """The recorded demand of step ``state`` for every variant."""
        a = self.actions[state] if state < self.actions.size else self.after_end_mps2
        return PolicyAction(accel_mps2=np.full(obs.batch_size, a)), state + 1


__all__ = ["HEADER", "ActionReplay", "read_actions", "write_actions"]
