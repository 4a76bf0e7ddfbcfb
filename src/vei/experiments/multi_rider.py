"""Case studies with several social-force riders: which riders, and what each one did.

``SimConfig.sfm_riders`` makes every selected rider of a scenario social-force driven at
once (vei.sim.riders). The metrics of a case study stay about the primary threat; this
module tabulates every simulated rider per configuration from the long time series, so a
reader sees what the other riders did (how far they left their recordings, how close they
came to each other and to the ego).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from vei.config import SimConfig
from vei.types import EGO_ID, Scenario

#: Columns of :func:`rider_table`.
RIDER_TABLE_COLUMNS = (
    "config",
    "rider",
    "category",
    "primary",
    "steps_active",
    "mean_speed_mps",
    "max_deviation_m",
    "min_rider_distance_m",
    "min_ego_distance_m",
    "ego_contact",
)


def sfm_rider_ids(scenario: Scenario, sim: SimConfig) -> tuple[str, ...]:
    """The riders that the SFM configurations drive: the primary threat first, then the
    extra riders that ``sim.sfm_riders`` selects (vei.sim.riders.select_extra_riders)."""
    from vei.sim.riders import select_extra_riders

    primary = scenario.primary_threat
    if primary is None:
        return ()
    extra = select_extra_riders(scenario, primary, sim.sfm_riders, f"scenario {scenario.id}")
    return (primary, *extra)


def rider_table(
    frame: pd.DataFrame,
    scenario: Scenario,
    riders: Sequence[str],
    time_shift_s: float,
) -> pd.DataFrame:
    """One row per configuration and simulated rider (RIDER_TABLE_COLUMNS).

    Args:
        frame: the case study's long time series (TIMESERIES_COLUMNS).
        scenario: the scenario (the recordings to compare with).
        riders: the simulated riders (primary first), e.g. :func:`sfm_rider_ids`.
        time_shift_s: the primary's time shift [s] (the others are not shifted).
    Returns:
        DataFrame: steps_active (steps present), mean_speed_mps while present,
        max_deviation_m from its own (shifted) recording at the same time,
        min_rider_distance_m (centres, to any other of ``riders`` present at the same
        step), min_ego_distance_m (centres), ego_contact (the contact latch: the
        ego-rider collision for the primary, the ego-contact latch for the others).
    """
    rows = []
    primary = riders[0] if riders else None
    cats = {a.agent_id: a.category for a in scenario.agents}
    for cfg, g in frame.groupby("config", sort=False):
        act = g[g["active"] & g["agent_id"].isin(riders)]
        ego = g[g["agent_id"] == EGO_ID][["t_s", "x_m", "y_m"]]
        for rid in riders:
            r = act[act["agent_id"] == rid]
            if r.empty:
                continue
            tr = scenario.track(rid)
            shift = time_shift_s if rid == primary else 0.0
            t_rec = r["t_s"].to_numpy() - shift
            rx = np.interp(t_rec, tr["t_s"], tr["x_m"])
            ry = np.interp(t_rec, tr["t_s"], tr["y_m"])
            x, y = r["x_m"].to_numpy(), r["y_m"].to_numpy()
            others = act[act["agent_id"] != rid][["t_s", "x_m", "y_m"]]
            pairs = r[["t_s", "x_m", "y_m"]].merge(others, on="t_s", suffixes=("", "_o"))
            d_r = np.hypot(pairs["x_m"] - pairs["x_m_o"], pairs["y_m"] - pairs["y_m_o"])
            with_ego = r[["t_s", "x_m", "y_m"]].merge(ego, on="t_s", suffixes=("", "_e"))
            d_e = np.hypot(with_ego["x_m"] - with_ego["x_m_e"], with_ego["y_m"] - with_ego["y_m_e"])
            rows.append(
                {
                    "config": str(cfg),
                    "rider": rid,
                    "category": cats.get(rid, ""),
                    "primary": rid == primary,
                    "steps_active": len(r),
                    "mean_speed_mps": float(r["speed_mps"].mean()),
                    "max_deviation_m": float(np.hypot(x - rx, y - ry).max()),
                    "min_rider_distance_m": float(d_r.min()) if len(d_r) else float("nan"),
                    "min_ego_distance_m": float(d_e.min()) if len(d_e) else float("nan"),
                    "ego_contact": bool(r["collided"].any()),
                }
            )
    return pd.DataFrame(rows, columns=list(RIDER_TABLE_COLUMNS))
