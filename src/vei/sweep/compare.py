"""Policies compared in a sweep: every variant's verdict against the no-avoidance variant
of the same design point, and a summary per policy."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from vei.errors import InputError
from vei.metrics.config import MetricsConfig
from vei.metrics.severity import VERDICTS, verdict


def policy_verdicts(
    results: pd.DataFrame,
    design: Sequence[str],
    *,
    reference: str = "none",
    mitigation_share: float = MetricsConfig.mitigation_share,
) -> pd.DataFrame:
    """``results`` with a 'verdict' column: each row against the row of policy
    ``reference`` at the same design point (same scenario and ``design`` columns).

    Args:
        results: sweep results with columns 'ego.policy', 'collision', 'impact_speed_mps' and
            ``design`` (e.g. the spec's parameter names except 'ego.policy', plus
            'scenario_id' and a rider-sample column when present).
        design: the columns that identify a design point.
        reference: the no-avoidance policy (default 'none' = the PID cruise).
        mitigation_share: see :func:`vei.metrics.severity.verdict`.
    Returns:
        a copy of ``results`` plus 'verdict': 'reference' on the ``reference`` policy's own
        rows, else 'avoided' / 'mitigated' / 'not-mitigated'; '' where the design point
        has no ``reference`` row.

    Raises:
        InputError: a needed column is missing, or a design point holds two rows of one
            policy.
    """
    need = {"ego.policy", "collision", "impact_speed_mps", *design}
    missing = sorted(need - set(results.columns))
    if missing:
        raise InputError(f"sweep results lack column(s) {', '.join(missing)}", field=missing[0])
    key = list(design)
    if results.duplicated([*key, "ego.policy"]).any():
        raise InputError(
            "two rows of one policy at the same design point: add the column that tells them apart to design"
        )
    ref = results[results["ego.policy"].astype(str) == reference][
        [*key, "collision", "impact_speed_mps"]
    ].rename(columns={"collision": "_ref_collision", "impact_speed_mps": "_ref_speed"})
    merged = results.reset_index(drop=True).merge(ref, on=key, how="left", sort=False)
    has = merged["_ref_collision"].notna().to_numpy()
    v = verdict(
        merged["collision"].to_numpy(bool),
        merged["impact_speed_mps"].to_numpy(float),
        merged["_ref_collision"].fillna(False).to_numpy(bool),
        merged["_ref_speed"].to_numpy(float),
        mitigation_share,
    )
    out = merged.drop(columns=["_ref_collision", "_ref_speed"])
    v = np.where(out["ego.policy"].astype(str).to_numpy() == reference, "reference", v)
    out["verdict"] = np.where(has, v, "").astype(object)
    return out


def policy_summary(with_verdicts: pd.DataFrame) -> pd.DataFrame:
    """One row per policy: variants, collisions, mean / max impact speed over the
    collisions with an approach [m/s], mean injury risk, the count of each verdict, and
    (where the results have the flag) the runs and collisions seen too late."""
    rows = []
    for pol, g in with_verdicts.groupby("ego.policy", sort=True):
        hit = g["collision"].to_numpy(bool)
        speed = g["impact_speed_mps"].to_numpy(float)
        speed = speed[hit & np.isfinite(speed)]
        row = {
            "ego.policy": pol,
            "variants": len(g),
            "collisions": int(hit.sum()),
            "mean_impact_speed_mps": float(speed.mean()) if speed.size else float("nan"),
            "max_impact_speed_mps": float(speed.max()) if speed.size else float("nan"),
            "mean_injury_risk": float(np.nanmean(g["injury_risk"]))
            if "injury_risk" in g
            else float("nan"),
        }
        for name in (*VERDICTS, "reference"):
            row[name] = int((g["verdict"] == name).sum())
        if "seen_too_late" in g:  # counted apart: no planner could have reacted
            flag = g["seen_too_late"].fillna(False).to_numpy(bool)
            row["seen_too_late"] = int(flag.sum())
            row["collisions_seen_too_late"] = int((flag & hit).sum())
        rows.append(row)
    return pd.DataFrame(rows)
