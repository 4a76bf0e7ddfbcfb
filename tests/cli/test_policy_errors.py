"""A user policy that raises inside act / init_state: the CLI reports a vei error (exit 2)
naming the policy, the step and time, the exception and the policy file's frames, and
prints no Python traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BAD = """
import numpy as np
from vei.policy.base import PolicyAction


class Bad:
    def init_state(self, batch_size):
        return None

    def act(self, obs, state):
        if obs.t_s[0] >= 1.0:
            return helper(obs)
        return PolicyAction(accel_mps2=np.zeros_like(obs.ego_speed_mps)), state


def helper(obs):
    raise ValueError("boom in my policy")


class NaNAction:
    def init_state(self, batch_size):
        return None

    def act(self, obs, state):
        acc = np.zeros_like(obs.ego_speed_mps)
        if obs.t_s[0] >= 0.5:
            acc[:] = np.nan
        return PolicyAction(accel_mps2=acc), state


class BadInit:
    def init_state(self, batch_size):
        return {}["missing"]

    def act(self, obs, state):
        return PolicyAction(accel_mps2=np.zeros_like(obs.ego_speed_mps)), state
"""


@pytest.fixture(scope="module")
def demo_folder(tmp_path_factory) -> Path:
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


def _vei(*args: str) -> subprocess.CompletedProcess[str]:
    code = "import sys; from vei.cli.main import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=300
    )


@pytest.mark.parametrize(
    ("cls", "call", "exc", "line"),
    [
        ("Bad", r"act\(\) at step 20 \(t = 1.000 s\)", "ValueError: boom in my policy", 17),
        ("BadInit", r"init_state\(\)", "KeyError: 'missing'", 33),
    ],
)
def test_a_raising_user_policy_exits_2_without_traceback(
    demo_folder: Path, tmp_path: Path, cls: str, call: str, exc: str, line: int
) -> None:
    import re

    bad = tmp_path / "bad.py"
    bad.write_text(BAD)
    spec = f"{bad}:{cls}"
    res = _vei(
        "run", str(demo_folder), "--config", "normal", "--policy", spec,
        "--out", str(tmp_path / "out"), "--time-shift", "0", "--no-figures",
    )  # fmt: skip
    text = res.stdout + res.stderr
    assert res.returncode == 2, text
    assert "Traceback" not in text
    assert f"policy {spec}: " in text
    assert re.search(call, text), text
    assert exc in text
    assert f"{bad}:{line} in " in text, text  # the frame in the user's file


def test_a_nan_action_names_the_policy_file_step_and_variant(
    demo_folder: Path, tmp_path: Path
) -> None:
    """Like an exception in act(): a NaN action names the policy's file, the step and the
    time, and which variant gave it (exit 2, no traceback)."""
    bad = tmp_path / "nan.py"
    bad.write_text(BAD)
    spec = f"{bad}:NaNAction"
    res = _vei(
        "run", str(demo_folder), "--config", "normal", "--policy", spec,
        "--out", str(tmp_path / "out"), "--time-shift", "0", "--no-figures",
    )  # fmt: skip
    text = " ".join((res.stdout + res.stderr).split())
    assert res.returncode == 2, text
    assert "Traceback" not in text
    assert f"policy {spec}: act() at step 10 (t = 0.500 s)" in text, text
    assert "action.accel_mps2 has NaN or infinite values in variant(s) 0 (nan)" in text, text
