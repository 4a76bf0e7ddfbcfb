"""The default variation's figures of vei.risk.fit on the shared recordings: the car's
speed spread within each INS drive (no longer the default), the arrival offsets of the
car-rider path crossings the roadside camera saw."""

from __future__ import annotations

import numpy as np
import pytest

from vei.risk.defaults import ARRIVAL_HALF_WIDTH_S, CRUISE_SPEED_CV, DEFAULTS
from vei.risk.fit import arrival_offsets, cruise_speed_spread


def test_within_drive_spread_is_no_longer_the_default(trafficmonitoring_root):
    """The spread within one drive (the default until issue 31: 0.22) is not the spread
    between encounters the default now uses (vei.calibrate.variation, its own test)."""
    c = cruise_speed_spread(trafficmonitoring_root)
    assert len(c.drives) == 9 and sum(c.n_samples) == 24_612
    assert c.median_cv == pytest.approx(0.22, abs=0.005)
    assert min(c.cv) == pytest.approx(0.02, abs=0.005) and max(c.cv) == pytest.approx(
        0.59, abs=0.005
    )
    assert CRUISE_SPEED_CV == pytest.approx(0.3645)
    src = next(d.source for d in DEFAULTS if d.name == "ego.cruise_speed_mps")
    assert "spread between encounters" in src and "9 TrafficMonitoring" in src


def test_arrival_offsets_have_no_peak_at_the_encounter_scale(trafficmonitoring_root):
    a = arrival_offsets(trafficmonitoring_root)
    off = np.abs(a.offsets_s)
    assert len(off) == 88 and a.n_riders == 15 and a.n_vehicles == 94
    assert off.min() == pytest.approx(2.1, abs=0.05) and off.max() == pytest.approx(57.8, abs=0.05)
    assert (off < ARRIVAL_HALF_WIDTH_S).sum() == 0 and (off < 10).sum() == 6
    src = next(d.source for d in DEFAULTS if d.name == "time_shift_s")
    assert "88 car-rider path crossings" in src and "none within 2 s, 6 within 10 s" in src
