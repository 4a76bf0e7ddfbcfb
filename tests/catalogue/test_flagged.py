"""Issue 22: runs flagged seen_too_late never decide a catalogue rank (hand-built rows)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from tests.catalogue.helpers import score_rows
from vei.catalogue.store import encounter_scores


def _rows(eid: str, collision, flagged, si) -> pd.DataFrame:
    return score_rows(eid, collision, flagged, safety_index=si)


def test_flagged_runs_are_counted_apart_and_never_rank() -> None:
    """Encounter A collides in 3 of 4 runs, but 2 of those are flagged (the rider appeared
    in contact): of its 2 unflagged runs 1 collides (share 0.5). B collides in 2 of 4,
    none flagged (share 0.5) with a lower mean safety index: B ranks first. C's runs
    are all flagged: it ranks last, with NaN scores."""
    rows = pd.concat(
        [
            _rows(
                "a__r", [True, True, True, False], [True, True, False, False], [0.0, 0.0, 0.0, 1.0]
            ),
            _rows("b__r", [True, True, False, False], [False] * 4, [0.0, 0.0, 0.2, 0.2]),
            _rows("c__r", [True, True], [True, True], [0.0, 0.0]),
        ],
        ignore_index=True,
    )
    enc = encounter_scores(rows).set_index("encounter_id")
    assert enc.loc["a__r", "n_configs"] == 4 and enc.loc["a__r", "n_flagged"] == 2
    assert enc.loc["a__r", "flagged_collisions"] == 2
    assert enc.loc["a__r", "collision_share"] == 0.5
    assert enc.loc["a__r", "mean_safety_index"] == 0.5
    assert enc.loc["b__r", "collision_share"] == 0.5 and enc.loc["b__r", "n_flagged"] == 0
    assert enc["rank"].to_dict() == {"b__r": 1, "a__r": 2, "c__r": 3}
    assert np.isnan(enc.loc["c__r", "collision_share"]) and enc.loc["c__r", "n_flagged"] == 2
    # without the flag (a catalogue written before it): every run counts
    old = encounter_scores(rows.drop(columns="seen_too_late")).set_index("encounter_id")
    assert old.loc["a__r", "collision_share"] == 0.75 and old.loc["a__r", "n_flagged"] == 0
