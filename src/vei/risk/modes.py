"""Failure modes: where in the variation collisions happen, and of which kind.

Two views of the (weighted) final sample of a planner:

- **Kinds** of collision (vei.metrics.severity): who struck whom and where
  (``striking`` x ``impact_side``, e.g. car-hits-rider / front), plus collisions without
  an approach (the rider appears in contact). Each kind's share of P(collision) and its
  mean impact speed.
- **Regions** of the variation: a small classification tree (CART, Gini impurity,
  importance-weighted, depth <= 3, leaves holding >= 2 % of the sample weight) over the
  varied quantities in their physical units splits the sample into boxes; each leaf that
  holds collisions is a rule such as ``time_shift_s in [-0.41, 0.37] and
  ego.cruise_speed_mps > 6.2`` with its share of P(collision) and P(collision | region).
  The tree is a description of the sample, not a model: its boxes are where the
  estimator found the collisions.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

MAX_DEPTH = 3
MIN_LEAF_SHARE = 0.02
MIN_MODE_SHARE = 0.01


@dataclass(frozen=True)
class Region:
    """One leaf of the tree that holds collisions.

    Attributes:
        bounds: {quantity: (low, high)} (-inf / inf where unbounded).
        share: its share of P(collision). p_collision: P(collision | region).
        probability: P(region) under the variation. n: samples in it.
    """

    bounds: dict[str, tuple[float, float]]
    share: float
    p_collision: float
    probability: float
    n: int

    def rule(self) -> str:
        """'a in [x, y] and b > z' (the whole variation when no bound)."""
        parts = []
        for name, (lo, hi) in self.bounds.items():
            if math.isfinite(lo) and math.isfinite(hi):
                parts.append(f"{name} in [{lo:.3g}, {hi:.3g}]")
            elif math.isfinite(lo):
                parts.append(f"{name} > {lo:.3g}")
            elif math.isfinite(hi):
                parts.append(f"{name} <= {hi:.3g}")
        return " and ".join(parts) if parts else "anywhere in the variation"

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (infinite bounds as None)."""

        def c(v: float) -> float | None:
            return v if math.isfinite(v) else None

        return {
            "rule": self.rule(),
            "bounds": {k: [c(lo), c(hi)] for k, (lo, hi) in self.bounds.items()},
            "share_of_p_collision": self.share,
            "p_collision_in_region": self.p_collision,
            "p_region": self.probability,
            "n_samples": self.n,
        }


def _best_split(
    x: np.ndarray, y: np.ndarray, w: np.ndarray, min_w: float
) -> tuple[int, float, float] | None:
    """(column, threshold, impurity decrease) of the best weighted Gini split, or None."""
    total = w.sum()
    pos = (w * y).sum()
    parent = total * (1 - (pos / total) ** 2 - (1 - pos / total) ** 2) if total > 0 else 0.0
    best = None
    for j in range(x.shape[1]):
        order = np.argsort(x[:, j], kind="stable")
        xs, ws, ys = x[order, j], w[order], y[order]
        cw, cp = np.cumsum(ws), np.cumsum(ws * ys)
        lw, lp = cw[:-1], cp[:-1]
        rw, rp = total - lw, pos - lp
        ok = (xs[1:] > xs[:-1]) & (lw >= min_w) & (rw >= min_w)
        if not ok.any():
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            gl = lw * (1 - (lp / lw) ** 2 - (1 - lp / lw) ** 2)
            gr = rw * (1 - (rp / rw) ** 2 - (1 - rp / rw) ** 2)
        gain = np.where(ok, parent - gl - gr, -np.inf)
        i = int(np.argmax(gain))
        if best is None or gain[i] > best[2]:
            best = (j, 0.5 * (xs[i] + xs[i + 1]), float(gain[i]))
    return best if best is not None and best[2] > 1e-12 * total else None


def failure_regions(rows: pd.DataFrame, names: Sequence[str], weighted: bool) -> list[Region]:
    """The tree's leaves that hold collisions, largest share of P(collision) first.

    Args:
        rows: a final sample (``failure``, ``weight`` and the quantities ``names``).
        names: the varied quantities (physical columns) to split on.
        weighted: use the importance weights (else every sample weighs 1).
    """
    names = [n for n in names if n in rows.columns]
    if not names or rows.empty or "failure" not in rows or not rows["failure"].any():
        return []
    x = rows[names].to_numpy(np.float64)
    y = rows["failure"].to_numpy(np.float64)
    w = rows["weight"].to_numpy(np.float64) if weighted else np.ones(len(rows))
    p_total = float((w * y).sum())
    min_w = MIN_LEAF_SHARE * float(w.sum())
    leaves: list[Region] = []

    def grow(idx: np.ndarray, depth: int, bounds: dict[str, tuple[float, float]]) -> None:
        split = None
        if depth < MAX_DEPTH and 0 < y[idx].sum() < len(idx):
            split = _best_split(x[idx], y[idx], w[idx], min_w)
        if split is None:
            wf = float((w[idx] * y[idx]).sum())
            if wf > 0:
                pw = float(w[idx].sum())
                leaves.append(Region(dict(bounds), wf / p_total, wf / pw, pw / len(rows), len(idx)))
            return
        j, t, _ = split
        name = names[j]
        lo, hi = bounds.get(name, (-math.inf, math.inf))
        left = idx[x[idx, j] <= t]
        right = idx[x[idx, j] > t]
        grow(left, depth + 1, {**bounds, name: (lo, min(hi, t))})
        grow(right, depth + 1, {**bounds, name: (max(lo, t), hi)})

    grow(np.arange(len(rows)), 0, {})
    return sorted(leaves, key=lambda r: -r.share)


def failure_kinds(rows: pd.DataFrame, weighted: bool) -> list[dict[str, Any]]:
    """Shares of P(collision) by kind (striking / impact side; without approach),
    largest first; kinds under MIN_MODE_SHARE are summed into 'other'. [] for a sample
    without failures (or without rows: a run that found no failure)."""
    if rows.empty or "failure" not in rows:
        return []
    fail = rows["failure"].to_numpy(bool)
    if not fail.any():
        return []
    w = rows["weight"].to_numpy(np.float64) if weighted else np.ones(len(rows))
    sub = rows.loc[fail].copy()
    sub["_w"] = w[fail]

    def label(r: pd.Series) -> str:
        if bool(r.get("no_approach", False)):
            return "no approach (the rider appears in contact)"
        striking = str(r.get("striking", "") or "?")
        side = str(r.get("impact_side", "") or "?")
        return f"{striking}, {side}"

    sub["_kind"] = sub.apply(label, axis=1) if len(sub) else []
    total = float(sub["_w"].sum())
    out = []
    for kind, g in sub.groupby("_kind", sort=False):
        speed = (
            g["impact_speed_mps"].to_numpy(np.float64) if "impact_speed_mps" in g else np.array([])
        )
        ok = np.isfinite(speed)
        out.append({
            "kind": str(kind),
            "share_of_p_collision": float(g["_w"].sum()) / total,
            "n_samples": len(g),
            "mean_impact_speed_mps": float(np.average(speed[ok], weights=g["_w"].to_numpy()[ok]))
            if ok.any() else None,
        })  # fmt: skip
    out.sort(key=lambda m: -m["share_of_p_collision"])
    major = [m for m in out if m["share_of_p_collision"] >= MIN_MODE_SHARE]
    minor = [m for m in out if m["share_of_p_collision"] < MIN_MODE_SHARE]
    if minor:
        major.append({
            "kind": "other",
            "share_of_p_collision": sum(m["share_of_p_collision"] for m in minor),
            "n_samples": sum(m["n_samples"] for m in minor),
            "mean_impact_speed_mps": None,
        })  # fmt: skip
    return major
