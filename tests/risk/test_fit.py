"""The default variation's figures are today's fits of the shared recordings
(vei.risk.fit): the car's cruise-speed spread from the INS drives, the arrival offsets of
the car-rider path crossings the roadside camera saw."""

from __future__ import annotations

import numpy as np
import pytest

from vei.risk.defaults import ARRIVAL_HALF_WIDTH_S, CRUISE_SPEED_CV, DEFAULTS
from vei.risk.fit import arrival_offsets, cruise_speed_spread


def test_cruise_speed_spread_is_the_declared_default(trafficmonitoring_root):
    c = cruise_speed_spread(trafficmonitoring_root)
    assert len(c.drives) == 9 and sum(c.n_samples) == 24_612
    assert c.median_cv == pytest.approx(CRUISE_SPEED_CV, abs=0.005)
    assert min(c.cv) == pytest.approx(0.02, abs=0.005) and max(c.cv) == pytest.approx(
        0.59, abs=0.005
    )
    src = next(d.source for d in DEFAULTS if d.name == "ego.cruise_speed_mps")
    assert "9 TrafficMonitoring INS drives (24,612 moving samples" in src


def test_arrival_offsets_have_no_peak_at_the_encounter_scale(trafficmonitoring_root):
    a = arrival_offsets(trafficmonitoring_root)
    off = np.abs(a.offsets_s)
    assert len(off) == 88 and a.n_riders == 15 and a.n_vehicles == 94
    assert off.min() == pytest.approx(2.1, abs=0.05) and off.max() == pytest.approx(57.8, abs=0.05)
    assert (off < ARRIVAL_HALF_WIDTH_S).sum() == 0 and (off < 10).sum() == 6
    src = next(d.source for d in DEFAULTS if d.name == "time_shift_s")
    assert "88 car-rider path crossings" in src and "none within 2 s, 6 within 10 s" in src
