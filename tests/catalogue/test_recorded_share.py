"""Issue 31: the catalogue's encounters say how much of their collisions the recorded
behaviour supports (hand-built rows, hand values)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from tests.catalogue.helpers import score_rows
from vei.catalogue.store import encounter_scores


def _rows(eid: str, collision, recorded, flagged) -> pd.DataFrame:
    return score_rows(eid, collision, flagged, collision_recorded=recorded)


def _wilson(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def test_recorded_share_and_share_of_collisions_by_hand() -> None:
    """A: 5 unflagged runs, 4 collide, 1 of them on recorded behaviour (+ a flagged
    recorded collision, left out): 1/5 of the runs, 1/4 of the collisions. B: no collision."""
    rows = pd.concat(
        [
            _rows(
                "a__r",
                [True, True, True, True, False, True],
                [True, False, False, False, False, True],
                [False, False, False, False, False, True],
            ),
            _rows("b__r", [False, False], [False, False], [False, False]),
        ],
        ignore_index=True,
    )
    enc = encounter_scores(rows).set_index("encounter_id")
    a = enc.loc["a__r"]
    assert a["recorded_collision_share"] == pytest.approx(0.2)
    lo, hi = _wilson(1, 5)
    assert a["recorded_collision_share_lo"] == pytest.approx(lo)
    assert a["recorded_collision_share_hi"] == pytest.approx(hi)
    assert a["collisions_on_recorded"] == pytest.approx(0.25)
    b = enc.loc["b__r"]
    assert b["recorded_collision_share"] == 0.0 and np.isnan(b["collisions_on_recorded"])
    assert b["recorded_collision_share_lo"] == 0.0


def test_a_collision_off_the_recording_is_no_recorded_collision() -> None:
    """collision_recorded without a collision (a label of a contact the metrics do not
    call a collision) never counts."""
    rows = _rows("a__r", [False, True], [True, False], [False, False])
    enc = encounter_scores(rows).set_index("encounter_id")
    assert enc.loc["a__r", "recorded_collision_share"] == 0.0
    assert enc.loc["a__r", "collisions_on_recorded"] == 0.0


def test_rows_without_the_label_have_no_recorded_columns() -> None:
    rows = _rows("a__r", [True], [True], [False]).drop(columns="collision_recorded")
    assert "recorded_collision_share" not in encounter_scores(rows)
