"""Issue 22: sweep runs flagged seen_too_late never rank before an unflagged one, and the
maps leave them out of the colours and mark them."""

from __future__ import annotations

import numpy as np
import pandas as pd

from vei.sweep.io import most_critical
from vei.sweep.riskmap import sweep_risk_map
from vei.sweep.spec import spec_from_dict


def test_flagged_runs_rank_after_every_unflagged_one() -> None:
    res = pd.DataFrame(
        {
            "variant_id": list("abcd"),
            "collision": [True, True, False, False],
            "safety_index": [0.0, 0.0, 0.3, 0.9],
            "min_gap_m": [0.0, 0.0, 1.0, 3.0],
            "seen_too_late": [True, False, False, False],
        }
    )
    assert most_critical(res, 4)["variant_id"].tolist() == ["b", "c", "d", "a"]
    assert most_critical(res.drop(columns="seen_too_late"), 4)["variant_id"].tolist() == list(
        "abcd"
    )


def test_risk_map_leaves_flagged_runs_out_and_marks_them(tmp_path) -> None:
    """A 3 x 3 grid, one run per cell; the runs of the cell (x = 0, y = 0) are flagged:
    that cell is blank (NaN) and its point drawn as a grey +."""
    spec = spec_from_dict(
        {
            "design": "grid",
            "parameters": {
                "time_shift_s": {"min": -1.0, "max": 1.0, "num": 3},
                "ego.cruise_speed_mps": {"min": 4.0, "max": 6.0, "num": 3},
            },
        }
    )
    xs, ys = np.meshgrid([-1.0, 0.0, 1.0], [4.0, 5.0, 6.0])
    res = pd.DataFrame(
        {
            "time_shift_s": xs.ravel(),
            "ego.cruise_speed_mps": ys.ravel(),
            "collision": False,
            "safety_index": 0.8,
            "seen_too_late": (xs.ravel() == -1.0) & (ys.ravel() == 4.0),
        }
    )
    out = sweep_risk_map(res, spec, tmp_path / "riskmap.png")
    value = out["binned"]["value"]
    assert np.isnan(value).sum() == 1 and np.nanmax(value) == 0.8
    assert (tmp_path / "riskmap.png").stat().st_size > 5_000
    from vei.report.riskmap import risk_map_figure

    fig = risk_map_figure(
        x_centres=np.array([0.0, 1.0]), y_centres=np.array([0.0, 1.0]),
        value=np.ones((2, 2)), segments=np.zeros((0, 2, 2)),
        flagged_x=np.array([0.5]), flagged_y=np.array([0.5]),
    )  # fmt: skip
    gids = [c.get_gid() for c in fig.axes[0].collections]
    assert "flagged" in gids
