"""The sweep's severity map: mean injury risk (or impact speed) per bin, hand-made results."""

from __future__ import annotations

import numpy as np
import pytest

from vei.metrics.severity import injury_risk_of_speed
from vei.sweep.riskmap import sweep_severity_map
from vei.sweep.spec import spec_from_dict, variants_table


def _grid():
    spec = spec_from_dict(
        {
            "design": "grid",
            "parameters": {
                "time_shift_s": {"min": -2.0, "max": 2.0, "num": 5},
                "ego.cruise_speed_mps": {"min": 4.0, "max": 8.0, "num": 3},
            },
        }
    )
    df = variants_table(spec, "s")
    # Collisions above 5 m/s; impact speed = the cruise speed (a standing rider).
    v = df["ego.cruise_speed_mps"].to_numpy()
    df["collision"] = v > 5.0
    df["impact_speed_mps"] = np.where(df["collision"], v, np.nan)
    df["injury_risk"] = np.where(df["collision"], injury_risk_of_speed(v), 0.0)
    df["safety_index"] = np.where(df["collision"], 0.0, 1.0)
    return spec, df


def test_severity_map_values_by_hand(tmp_path):
    spec, df = _grid()
    drawn = sweep_severity_map(df, spec, tmp_path / "sev.png")
    assert (drawn["x"], drawn["y"]) == ("time_shift_s", "ego.cruise_speed_mps")
    value = drawn["binned"]["value"]  # [Ky = 3 speeds, Kx = 5 shifts]
    assert value.shape == (3, 5)
    np.testing.assert_allclose(value[0], 0.0)  # 4 m/s: no collision, risk 0
    np.testing.assert_allclose(value[1], injury_risk_of_speed(6.0))
    np.testing.assert_allclose(value[2], injury_risk_of_speed(8.0))
    assert value[2, 0] > value[1, 0] > 0
    assert len(drawn["segments"]) > 0  # the collision boundary between 4 and 6 m/s
    assert (tmp_path / "sev.png").stat().st_size > 10_000


def test_impact_speed_map_is_a_mean_over_collisions(tmp_path):
    spec, df = _grid()
    df.loc[df.index[-1], "injury_risk"] = np.nan  # a contact without approach: left out
    drawn = sweep_severity_map(df, spec, tmp_path / "v.png", value="impact_speed_mps")
    value = drawn["binned"]["value"]
    assert np.isnan(value[0]).all()  # no collision at 4 m/s: blank
    np.testing.assert_allclose(value[1], 6.0)
    np.testing.assert_allclose(value[2], 8.0)
    risk = sweep_severity_map(df, spec, tmp_path / "r.png")["binned"]["value"]
    # the bin's only variant has no known risk: blank, not 0 and not NaN-poisoned around it
    assert np.isnan(risk[2, -1])
    assert np.isfinite(np.delete(risk.ravel(), risk.size - 1)).all()
    assert risk[2, 0] == pytest.approx(injury_risk_of_speed(8.0))


def test_no_plane_no_map(tmp_path):
    spec = spec_from_dict(
        {"design": "grid", "parameters": {"time_shift_s": {"min": -1.0, "max": 1.0, "num": 3}}}
    )
    df = variants_table(spec, "s").assign(collision=False, injury_risk=0.0)
    assert sweep_severity_map(df, spec, tmp_path / "x.png") is None
    assert not (tmp_path / "x.png").exists()


def test_lhs_map_with_many_unknown_values_keeps_one_binning(tmp_path):
    """A Latin-hypercube sweep in which many collisions have no known value (contact
    without approach: NaN): the value's bins are the boundary's bins (the bin count was
    derived twice, from all rows and from the finite ones, and the map crashed with
    'Dimensions of C (9, 9) should be one smaller than X(11) and Y(11)')."""
    spec = spec_from_dict(
        {
            "design": "lhs",
            "n_samples": 1200,
            "seed": 3,
            "parameters": {
                "time_shift_s": {"min": -3.0, "max": 3.0},
                "ego.cruise_speed_mps": {"min": 3.0, "max": 9.0},
            },
        }
    )
    df = variants_table(spec, "s")
    v = df["ego.cruise_speed_mps"].to_numpy()
    df["collision"] = v > 4.0
    known = df["time_shift_s"].to_numpy() > 0.5  # 5/12 of the collisions have a speed
    df["impact_speed_mps"] = np.where(df["collision"] & known, v, np.nan)
    df["injury_risk"] = np.where(df["collision"], np.where(known, 0.3, np.nan), 0.0)
    for value in ("injury_risk", "impact_speed_mps"):
        drawn = sweep_severity_map(df, spec, tmp_path / f"{value}.png", value=value)
        grid = drawn["binned"]
        assert (
            grid["value"].shape == (grid["y_centres"].size, grid["x_centres"].size) == (10, 10)
        )  # sqrt(1200 / 10)
        assert (tmp_path / f"{value}.png").is_file()
