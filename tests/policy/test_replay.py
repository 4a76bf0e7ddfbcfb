"""ActionReplay: an action file replayed step by step; bad files are clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from vei.errors import ConfigError, InputError
from vei.policy.replay import ActionReplay, read_actions, write_actions


class _Obs:
    batch_size = 3


def test_replays_then_holds(tmp_path):
    acts = np.array([0.1, -2.5, 1.0 / 3.0])
    path = write_actions(tmp_path / "a.csv", acts)
    assert np.array_equal(read_actions(path), acts)  # repr round-trips exactly
    np.save(tmp_path / "a.npy", acts)
    assert np.array_equal(read_actions(tmp_path / "a.npy"), acts)
    pol = ActionReplay(str(path), after_end_mps2=-1.0)
    state = pol.init_state(3)
    got = []
    for _ in range(5):
        action, state = pol.act(_Obs(), state)
        assert action.accel_mps2.shape == (3,)
        got.append(action.accel_mps2[0])
    assert got == [0.1, -2.5, 1.0 / 3.0, -1.0, -1.0]


def test_bad_action_files(tmp_path):
    with pytest.raises(InputError, match="not found"):
        read_actions(tmp_path / "none.csv")
    (tmp_path / "b.csv").write_text("accel_mps2\n0.5\nfast\n")
    with pytest.raises(InputError, match="'fast' is not a number") as err:
        read_actions(tmp_path / "b.csv")
    assert err.value.row == 3
    (tmp_path / "c.csv").write_text("accel_mps2\nnan\n")
    with pytest.raises(InputError, match="expected a finite number"):
        read_actions(tmp_path / "c.csv")
    (tmp_path / "d.csv").write_text("accel_mps2\n")
    with pytest.raises(InputError, match="no action"):
        read_actions(tmp_path / "d.csv")
    with pytest.raises(ConfigError, match="after_end_mps2"):
        ActionReplay(str(write_actions(tmp_path / "e.csv", [0.0])), after_end_mps2=float("inf"))
