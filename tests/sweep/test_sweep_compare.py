"""Policy verdicts in a sweep: each row against 'none' at the same design point (by hand)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from vei.errors import InputError
from vei.sweep.compare import policy_summary, policy_verdicts


def _results() -> pd.DataFrame:
    nan = np.nan
    return pd.DataFrame(
        {
            "scenario_id": ["s"] * 6,
            "time_shift_s": [0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            "ego.policy": ["none", "aeb", "paper-cap"] * 2,
            "collision": [True, False, True, True, True, True],
            "impact_speed_mps": [5.0, nan, 3.9, 5.0, 4.5, nan],
            "injury_risk": [0.02, 0.0, 0.01, 0.02, 0.015, nan],
        }
    )


def test_verdicts_against_none_at_the_same_design_point():
    out = policy_verdicts(_results(), ["scenario_id", "time_shift_s"])
    assert list(out["verdict"]) == [
        "reference",  # none itself (collided): not a verdict against itself
        "avoided",
        "mitigated",  # 3.9 <= 0.8 x 5.0
        "reference",
        "not-mitigated",  # 4.5 > 4.0
        "not-mitigated",  # a collision without approach (speed unknown)
    ]
    table = policy_summary(out).set_index("ego.policy")
    assert table.loc["aeb", "collisions"] == 1
    assert table.loc["aeb", "mean_impact_speed_mps"] == pytest.approx(4.5)
    assert table.loc["paper-cap", "mitigated"] == 1
    # none's own collisions are not counted as not-mitigated
    assert table.loc["none", "not-mitigated"] == 0 and table.loc["none", "reference"] == 2
    assert table.loc["none", "collisions"] == 2
    assert table.loc["paper-cap", "mean_injury_risk"] == pytest.approx(0.01)  # NaN left out


def test_missing_reference_and_bad_input():
    df = _results()
    df.loc[3, "ego.policy"] = "idm"  # design point 1.0 has no 'none' row
    out = policy_verdicts(df, ["scenario_id", "time_shift_s"])
    assert list(out["verdict"][3:]) == ["", "", ""]
    with pytest.raises(InputError):
        policy_verdicts(df.drop(columns="impact_speed_mps"), ["scenario_id"])
    with pytest.raises(InputError):
        policy_verdicts(_results(), ["scenario_id"])  # two rows per policy at a point
