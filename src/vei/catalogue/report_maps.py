"""The maps of the catalogue's HTML report, binned (issue 35): at most 15 x 15 cells each.

- :func:`risk_map`: an encounter's sweep, mean safety index per cell and the variants
  marked (at most MAX_MAP_POINTS of them);
- :func:`probability_map`: an encounter's risk estimate, P(collision | cell) from its
  final sample;
- :func:`catalogue_map`: the index page's map, P(collision | cell) over the sweeps of every
  encounter of the catalogue.

A probability map has three kinds of cell, drawn in colours far apart: known with
P > 0 (``z``, a red scale), known with P = 0 (``zero``: the 95 % interval is within +-0.1
and no sample collides) and not known (``unknown``: the interval is wider, or no
sample). Before issue 35 the known P = 0 cells were the white end of the red scale under
a light grey veil, nearly the grey of the cells not known.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

#: Most sweep variants marked on an encounter's risk map (the heatmap is binned to at most
#: 15 x 15 cells; the markers are every variant up to this many, else an evenly spaced
#: subset of them).
MAX_MAP_POINTS = 2000
#: Cells per axis of the report's maps: at most this many.
MAX_CELLS_PER_AXIS = 15
#: The plane of the report's sweep maps (catalogue.parquet columns).
X_COLUMN, Y_COLUMN = "p.time_shift_s", "p.ego.cruise_speed_mps"
X_LABEL, Y_LABEL = "time-shift offset to the automatic shift [s]", "ego cruise speed [m/s]"


def thin(points: dict[str, np.ndarray], limit: int = MAX_MAP_POINTS) -> dict[str, np.ndarray]:
    """``points`` (equal-length arrays [N]) cut to at most ``limit`` evenly spaced rows."""
    n = len(points["x"])
    if n <= limit:
        return points
    idx = np.unique(np.linspace(0, n - 1, limit).round().astype(int))
    return {k: np.asarray(v)[idx] for k, v in points.items()}


def risk_map(rows: pd.DataFrame) -> dict[str, Any] | None:
    """An encounter's sweep map: mean safety index and collision share per cell over the
    time-shift offset x ego cruise speed (3 to 15 cells per axis, about 6 variants each),
    the variants marked (collisions; flagged ``seen_too_late`` runs apart, never coloured).

    Args:
        rows: the encounter's catalogue rows (``kind`` 'sweep' are used).
    Returns:
        None without a sweep over the plane; else {'x' [Kx], 'y' [Ky], 'z', 'share',
        'count', 'count_si' [Ky, Kx], labels, 'n', 'n_flagged', 'points'}.
    """
    x, y = X_COLUMN, Y_COLUMN
    sw = rows[rows["kind"] == "sweep"]
    if len(sw) < 4 or x not in sw or y not in sw or sw[x].isna().all() or sw[y].isna().all():
        return None
    from vei.metrics.seen import flagged_mask

    flag = flagged_mask(sw)  # never coloured by: marked (points.flagged)
    xs_all, ys_all = sw[x].to_numpy(float), sw[y].to_numpy(float)
    n = int(np.clip(np.sqrt(len(sw) / 6.0), 3, MAX_CELLS_PER_AXIS))
    xe = np.linspace(xs_all.min(), xs_all.max(), n + 1)
    ye = np.linspace(ys_all.min(), ys_all.max(), n + 1)
    coll_all = sw["collision"].astype(bool).to_numpy()
    sw = sw[~flag]
    xs, ys = sw[x].to_numpy(float), sw[y].to_numpy(float)
    si = sw["safety_index"].to_numpy(float)
    fin = np.isfinite(si)  # NaN: the shifted rider never met the ego in the simulated span
    num, _, _ = np.histogram2d(xs[fin], ys[fin], bins=[xe, ye], weights=si[fin])
    n_si, _, _ = np.histogram2d(xs[fin], ys[fin], bins=[xe, ye])
    cnt, _, _ = np.histogram2d(xs, ys, bins=[xe, ye])
    col, _, _ = np.histogram2d(
        xs, ys, bins=[xe, ye], weights=sw["collision"].astype(float).to_numpy()
    )
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(n_si > 0, num / n_si, np.nan)
        share = np.where(cnt > 0, col / cnt, np.nan)
    return {
        "x": 0.5 * (xe[:-1] + xe[1:]),
        "y": 0.5 * (ye[:-1] + ye[1:]),
        "z": mean.T,
        "share": share.T,
        "count": cnt.T,
        "count_si": n_si.T,
        "x_label": X_LABEL,
        "y_label": Y_LABEL,
        "n": int(len(sw)),
        "n_flagged": int(flag.sum()),
        "points": thin({"x": xs_all, "y": ys_all, "collision": coll_all, "flagged": flag}),
    }


def cells(grid: dict[str, np.ndarray], x_label: str, y_label: str, note: str) -> dict[str, Any]:
    """The report's form of :func:`vei.sweep.riskmap.probability_grid`'s result: 'z'
    (known P > 0, else NaN), 'zero' (1 where known P = 0), 'unknown' (1 where not known),
    each [Ky, Kx] and exactly one of them finite per cell; 'text' (hover) per cell."""
    p, known = np.asarray(grid["p"], float), np.asarray(grid["known"], bool)
    lo, hi = grid["lo"], grid["hi"]
    zero = known & (p == 0.0)
    text = [
        [
            (
                f"P {p[j, i]:.3f} [{lo[j, i]:.3f}, {hi[j, i]:.3f}]"
                if np.isfinite(p[j, i])
                else "no sample"
            )
            + ("" if known[j, i] else " (not known)")
            for i in range(p.shape[1])
        ]
        for j in range(p.shape[0])
    ]
    return {
        "x": grid["x_centres"],
        "y": grid["y_centres"],
        "z": np.where(known & ~zero, p, np.nan),
        "zero": np.where(zero, 1.0, np.nan),
        "unknown": np.where(known, np.nan, 1.0),
        "text": text,
        "x_label": x_label,
        "y_label": y_label,
        "note": note,
    }


def probability_map(path: Path, doc: dict[str, Any]) -> dict[str, Any] | None:
    """P(collision | cell) over the first two varied quantities from the risk estimate's
    final sample of its first planner (``path``: its samples.parquet; ``doc``: risk.json),
    weighted where importance sampling drew it; cells whose 95 % CI is wider than +-0.1
    not known. None without two quantities or with fewer than 50 samples."""
    from vei.sweep.riskmap import probability_grid

    dims = [d for d in doc.get("dimensions", []) if not d.startswith("rider.")]
    planners = doc.get("planners") or []
    if len(dims) < 2 or not planners or not path.is_file():
        return None
    x, y = (
        ("time_shift_s", "ego.cruise_speed_mps")
        if {"time_shift_s", "ego.cruise_speed_mps"} <= set(dims)
        else dims[:2]
    )
    s = pd.read_parquet(path, columns=[x, y, "failure", "weight", "in_estimate", "policy"])
    s = s[s["in_estimate"] & (s["policy"] == planners[0]["policy"])]
    if len(s) < 50:
        return None
    xs, ys = s[x].to_numpy(float), s[y].to_numpy(float)
    nb = int(np.clip(np.sqrt(len(s) / 100.0), 3, 12))
    xe = np.linspace(xs.min(), xs.max(), nb + 1)
    ye = np.linspace(ys.min(), ys.max(), nb + 1)
    g = probability_grid(xs, ys, s["failure"].to_numpy(bool), xe, ye,
                         weights=s["weight"].to_numpy(float))  # fmt: skip
    out = cells(g, x, y, f"{len(s)} samples of {planners[0]['policy']}")
    out.update(policy=planners[0]["policy"], n=int(len(s)))
    return out


def catalogue_map(rows: pd.DataFrame) -> dict[str, Any] | None:
    """The index page's map: P(collision | cell) over the time-shift offset x ego cruise
    speed from the sweep variants of every encounter (runs flagged ``seen_too_late`` left
    out), 3 to 15 cells per axis (about 100 variants each), its 95 % Wilson interval, cells
    known within +-0.1 (:func:`cells`). It reads "P(collision | these settings) over the
    catalogue's encounters as the sweeps draw them", not a population probability.

    Args:
        rows: catalogue.parquet (every encounter's rows).
    Returns:
        None without sweep rows over the plane; else :func:`cells` plus 'n' (variants) and
        'n_encounters'.
    """
    from vei.metrics.seen import flagged_mask
    from vei.sweep.riskmap import probability_grid

    x, y = X_COLUMN, Y_COLUMN
    if "kind" not in rows or x not in rows or y not in rows:
        return None
    sw = rows[(rows["kind"] == "sweep") & rows[x].notna() & rows[y].notna()]
    sw = sw[~flagged_mask(sw)]
    if len(sw) < 4:
        return None
    xs, ys = sw[x].to_numpy(float), sw[y].to_numpy(float)
    nb = int(np.clip(np.sqrt(len(sw) / 100.0), 3, MAX_CELLS_PER_AXIS))
    xe = np.linspace(xs.min(), xs.max(), nb + 1)
    ye = np.linspace(ys.min(), ys.max(), nb + 1)
    if xe[0] == xe[-1] or ye[0] == ye[-1]:
        return None
    g = probability_grid(xs, ys, sw["collision"].astype(bool).to_numpy(), xe, ye)
    n_enc = int(sw["encounter_id"].nunique()) if "encounter_id" in sw else 1
    out = cells(g, X_LABEL, Y_LABEL, f"{len(sw):,} sweep variants of {n_enc:,} encounters")
    out.update(n=int(len(sw)), n_encounters=n_enc)
    return out
