from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vei.errors import InputError
from vei.recon.sync import active_matrix, active_per_frame, synchronise
from vei.types import Interaction, InteractionMeta


def _interaction(ann_t, root=None):
    ego = pd.DataFrame({"t_s": np.arange(0.0, 5.01, 0.1), "lat_deg": 48.0, "lon_deg": 11.0})
    ann = pd.DataFrame({"t_s": ann_t, "track_id": ["a"] * 3 + ["b"] * (len(ann_t) - 3)})
    meta = InteractionMeta("x", "test", datetime(2021, 1, 1, tzinfo=UTC))
    return Interaction(meta, ego, ann, root=root)


def test_synchronise_reports_rates_and_offsets():
    rep = synchronise(_interaction([0.0, 1.0, 2.0, 0.55, 1.55]))
    assert rep.gps_rate_hz == pytest.approx(10.0)
    assert rep.annotation_rate_hz == pytest.approx(1.0)
    assert rep.max_gap_to_gps_fix_s == pytest.approx(0.05)
    assert (rep.t_start_s, rep.t_end_s) == pytest.approx((0.0, 5.0))
    assert rep.as_dict()["gps_rate_hz"] == pytest.approx(10.0)


def test_annotation_outside_gps_span_names_file_row_field():
    with pytest.raises(InputError) as err:
        synchronise(_interaction([0.0, 1.0, 2.0, 4.0, 5.2], root=Path("/data/i")))
    assert err.value.row == 5
    assert err.value.field == "t_s"
    assert err.value.path == Path("/data/i/annotations.csv")
    assert "outside the GPS span" in str(err.value)


def test_active_matrix_and_per_frame():
    act = active_matrix([0.0, 1.0, 2.0, 3.0], [0.0, 1.5], [2.0, 3.0])
    assert act.tolist() == [[True, False], [True, False], [True, True], [False, True]]
    traj = pd.DataFrame(
        {
            "t_s": [0.0, 0.05, 0.05, 0.1, 0.0],
            "agent_id": ["a", "a", "b", "b", "ego"],
            "category": ["escooter", "escooter", "cyclist", "cyclist", "ego"],
        }
    )
    per = active_per_frame(traj, ("escooter", "cyclist"))
    assert per["t_s"].tolist() == pytest.approx([0.0, 0.05, 0.1])
    assert per["n_active"].tolist() == [1, 2, 1]
