"""Maps of a finished sweep over two range parameters: the risk map (mean safety index,
collision boundary) and the severity map (mean injury risk of the rider, same boundary)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.sweep.spec import SweepSpec


def plane_axes(
    results: pd.DataFrame, spec: SweepSpec, x: str | None = None, y: str | None = None
) -> tuple[str, str] | None:
    """The (x, y) parameters of a sweep's maps: the given ones, else time shift x ego
    cruise speed when both are ranges, else the first two ranges in PARAMETERS order;
    None when the spec has fewer than two range parameters or results lack x or y."""
    ranges = [p.name for p in spec.parameters if p.is_range and p.min != p.max]
    ranges += [n for n, d in getattr(spec, "variation", ()) if not d.is_fixed]  # issue 23
    if x is None or y is None:
        if len(ranges) < 2:
            return None
        x, y = (
            ("time_shift_s", "ego.cruise_speed_mps")
            if {"time_shift_s", "ego.cruise_speed_mps"} <= set(ranges)
            else (ranges[0], ranges[1])
        )
    if not {x, y} <= set(results.columns):
        return None
    return x, y


#: Most cells per axis of any sweep picture: a map is drawn from at most
#: MAX_BINS_PER_AXIS^2 = 400 cells whatever the number of variants (issue 35.0).
MAX_BINS_PER_AXIS = 20


def default_bins(n_rows: int) -> int:
    """Equal bins per axis for ``n_rows`` variants: about 10 variants per bin, 4 to
    MAX_BINS_PER_AXIS (20)."""
    return int(np.clip(np.sqrt(n_rows / 10.0), 4, MAX_BINS_PER_AXIS))


def grid_edges(values: np.ndarray, max_bins: int = MAX_BINS_PER_AXIS) -> np.ndarray:
    """Cell edges for an equally spaced grid axis ``values`` [K] (increasing): one cell
    per value (edges half a step beyond the ends) when K <= ``max_bins``, else
    ``max_bins`` equal cells over the same span, each holding about K / max_bins values
    (10,000 time-shift values -> 20 cells of 500). Returns [min(K, max_bins) + 1]."""
    e = _centre_edges(np.asarray(values, float))
    if len(values) <= max_bins:
        return e
    return np.linspace(e[0], e[-1], max_bins + 1)


def _binned(
    results: pd.DataFrame, spec: SweepSpec, x: str, y: str, value: str, bins: int | None
) -> dict[str, np.ndarray]:
    from vei.sweep.lattice import binned_risk

    if bins is None:
        bins = default_bins(len(results))

    def edges(name: str) -> np.ndarray:
        if name not in {p.name for p in spec.parameters}:  # a variation's: the data's span
            v = results[name].to_numpy(float)
            return np.linspace(v.min(), v.max(), bins + 1)
        p = spec.param(name)
        if p.num is not None and p.num >= 2:
            return grid_edges(np.linspace(p.min, p.max, p.num))
        return np.linspace(p.min, p.max, bins + 1)

    return binned_risk(
        results[x].to_numpy(float),
        results[y].to_numpy(float),
        results["collision"].to_numpy(bool),
        results[value].to_numpy(float),
        edges(x),
        edges(y),
    )


def sweep_risk_map(
    results: pd.DataFrame,
    spec: SweepSpec,
    path: str | Path,
    *,
    x: str | None = None,
    y: str | None = None,
    bins: int | None = None,
) -> dict[str, Any] | None:
    """Risk map of a finished sweep over two range parameters (:func:`plane_axes`).

    Variants are binned in the (x, y) plane: a grid design's own values are the bins (one
    variant per bin per other setting) up to MAX_BINS_PER_AXIS values per axis, beyond
    that MAX_BINS_PER_AXIS equal bins of consecutive values (:func:`grid_edges`); other
    designs use ``bins`` equal bins per axis (default: about 10 variants per bin, 4 to
    MAX_BINS_PER_AXIS bins per axis). At most 400 cells are drawn whatever the number of
    variants. The heatmap is the mean
    safety index per bin, the boundary the 0.5 level of the collision share (marching
    squares, linear interpolation; :func:`vei.sweep.lattice.share_boundary`).

    Returns:
        None when there is no plane or results lack safety_index / collision; else
        {'x', 'y', 'binned', 'segments', 'crossings'} (what was drawn) after writing the
        PNG at ``path``.
    """
    from vei.report.riskmap import write_risk_map
    from vei.sweep.lattice import share_boundary

    axes = plane_axes(results, spec, x, y)
    if axes is None or not {"safety_index", "collision"} <= set(results.columns):
        return None
    x, y = axes
    results, flagged = _unflagged(results, x, y)
    binned = _binned(results, spec, x, y, "safety_index", bins)
    segments, crossings = share_boundary(binned)
    n_sc = results["scenario_id"].nunique() if "scenario_id" in results else 1
    write_risk_map(
        path,
        x_centres=binned["x_centres"],
        y_centres=binned["y_centres"],
        value=binned["value"],
        segments=segments,
        x_label=x,
        y_label=y,
        title=f"mean safety index of {len(results)} variants ({n_sc} scenario(s)); "
        "boundary: collision share 0.5" + _flag_note(flagged),
        **flagged,
    )
    return {"x": x, "y": y, "binned": binned, "segments": segments, "crossings": crossings}


def sweep_severity_map(
    results: pd.DataFrame,
    spec: SweepSpec,
    path: str | Path,
    *,
    value: str = "injury_risk",
    x: str | None = None,
    y: str | None = None,
    bins: int | None = None,
) -> dict[str, Any] | None:
    """Severity map of a finished sweep: the mean of ``value`` per bin over the same plane
    and bins as :func:`sweep_risk_map`, with the same collision boundary.

    ``value`` 'injury_risk' (default: the rider's injury probability, 0 for a variant
    without collision, so a bin's mean is the expected risk per encounter) or
    'impact_speed_mps' (mean over the bin's *collisions*; bins without one are blank).
    Variants whose value is NaN (a collision without an approach: the rider appeared in
    contact, vei.metrics.severity) are left out of the mean, not of the boundary.
    The colour scale runs from 0 (green) to the largest bin value (red).

    Returns:
        None when there is no plane or results lack ``value`` / collision; else {'x', 'y',
        'value', 'binned', 'segments'} after writing the PNG at ``path``.
    """
    from vei.report.riskmap import write_risk_map
    from vei.sweep.lattice import share_boundary

    axes = plane_axes(results, spec, x, y)
    if axes is None or not {value, "collision"} <= set(results.columns):
        return None
    x, y = axes
    results, flagged = _unflagged(results, x, y)
    # One binning for the boundary (every unflagged variant) and the value (the rows that
    # have one): the bin count follows the sweep, never the rows left after dropping NaNs.
    bins = default_bins(len(results)) if bins is None else bins
    binned = _binned(results, spec, x, y, "collision", bins)
    v = results[value].to_numpy(float)
    keep = np.isfinite(v)
    if value != "injury_risk":  # a mean over the collisions only
        keep &= results["collision"].to_numpy(bool)
    rows = results[keep]
    binned["value"] = (
        _binned(rows, spec, x, y, value, bins)["value"]
        if len(rows)
        else np.full_like(binned["value"], np.nan)
    )
    segments, _ = share_boundary(binned)
    finite = binned["value"][np.isfinite(binned["value"])]
    vmax = float(finite.max()) if finite.size and finite.max() > 0 else 1.0
    label = "mean injury risk" if value == "injury_risk" else f"mean {value} of collisions"
    n_sc = results["scenario_id"].nunique() if "scenario_id" in results else 1
    write_risk_map(
        path,
        x_centres=binned["x_centres"],
        y_centres=binned["y_centres"],
        value=binned["value"],
        segments=segments,
        x_label=x,
        y_label=y,
        value_label=label,
        vmin=0.0,
        vmax=vmax,
        cmap="RdYlGn_r",
        title=f"{label} of {len(results)} variants ({n_sc} scenario(s)); "
        "boundary: collision share 0.5" + _flag_note(flagged),
        **flagged,
    )
    return {"x": x, "y": y, "value": value, "binned": binned, "segments": segments}


def _unflagged(results: pd.DataFrame, x: str, y: str) -> tuple[pd.DataFrame, dict[str, np.ndarray]]:
    """(the rows not flagged ``seen_too_late``, {'flagged_x', 'flagged_y'}: where the
    flagged ones lie). A map never colours by a run no planner could have reacted to
    (vei.metrics.seen): it marks them instead."""
    from vei.metrics.seen import flagged_mask

    flag = flagged_mask(results)
    if not flag.any():
        return results, {}
    pts = {
        "flagged_x": results[x].to_numpy(float)[flag],
        "flagged_y": results[y].to_numpy(float)[flag],
    }
    return results[~flag], pts


def _flag_note(flagged: dict[str, np.ndarray]) -> str:
    n = len(flagged.get("flagged_x", ()))
    return f"\n{n} run(s) seen too late: marked +, not coloured" if n else ""


def _centre_edges(c: np.ndarray) -> np.ndarray:
    mid = 0.5 * (c[:-1] + c[1:])
    return np.concatenate([[c[0] - (mid[0] - c[0])], mid, [c[-1] + (c[-1] - mid[-1])]])


def sweep_severity_maps(
    results: pd.DataFrame, spec: SweepSpec, out_dir: str | Path
) -> dict[str, Path]:
    """The severity maps a sweep writes: ``severity_map.png``, or one
    ``severity_map_<policy>.png`` per value when the sweep varies ``ego.policy`` (one
    map per policy, so that e.g. paper-cap and aeb are compared side by side).

    Returns {label: path} of the maps written ('' for the single map).
    """
    import re

    out = Path(out_dir)
    written: dict[str, Path] = {}
    if "ego.policy" in results.columns and results["ego.policy"].nunique() > 1:
        for pol, rows in results.groupby("ego.policy", sort=True):
            safe = re.sub(r"[^A-Za-z0-9_.-]+", "_", str(pol)).strip("_") or "policy"
            path = out / f"severity_map_{safe}.png"
            if sweep_severity_map(rows, spec, path) is not None:
                written[str(pol)] = path
        return written
    if sweep_severity_map(results, spec, out / "severity_map.png") is not None:
        written[""] = out / "severity_map.png"
    return written


#: A cell's probability is shown when its 95 % interval is at most this wide on each side.
MAX_HALF_WIDTH = 0.1


def wilson_interval(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score interval (95 % with the default z) of k successes in n trials (Wilson
    1927); (0, 1) for n < 1. vei.risk.estimators uses this one."""
    import math

    if n < 1:
        return 0.0, 1.0
    p = k / n
    den = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, centre - half), min(1.0, centre + half)


def wilson_intervals(
    p: np.ndarray, n: np.ndarray, z: float = 1.959963984540054
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`wilson_interval` of many cells at once: p [...] observed shares, n [...]
    (effective) sample sizes, both rounded as the scalar form rounds them (k = max(1,
    round(n)) trials, round(p k) successes). Returns (lo, hi), arrays shaped like p."""
    k = np.maximum(1.0, np.round(np.asarray(n, float)))
    q = np.round(np.asarray(p, float) * k) / k
    den = 1.0 + z * z / k
    centre = (q + z * z / (2 * k)) / den
    half = z * np.sqrt(q * (1 - q) / k + z * z / (4 * k * k)) / den
    return np.maximum(0.0, centre - half), np.minimum(1.0, centre + half)


def probability_grid(
    x: np.ndarray,
    y: np.ndarray,
    failure: np.ndarray,
    x_edges: np.ndarray,
    y_edges: np.ndarray,
    *,
    weights: np.ndarray | None = None,
    max_half_width: float = MAX_HALF_WIDTH,
) -> dict[str, np.ndarray]:
    """P(collision | cell) over a plane, with its 95 % Wilson interval, and which cells it
    is known in.

    Args:
        x, y: [N] sample coordinates. failure: [N] bool. x_edges [Kx + 1], y_edges
            [Ky + 1]: the cells. weights: [N] importance weights (None: 1); a cell's
            estimate is then sum(w f) / sum(w), its interval Wilson's on the effective
            sample size (sum w)^2 / sum w^2.
        max_half_width: a cell is *known* when its interval's half-width is at most this.
    Returns:
        {'x_centres' [Kx], 'y_centres' [Ky], 'p', 'lo', 'hi', 'n' (effective samples),
        'known' (bool)}: arrays [Ky, Kx]; p is NaN in empty cells.
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    f = np.asarray(failure, bool).astype(float)
    w = np.ones_like(x) if weights is None else np.asarray(weights, float)
    bins = [np.asarray(x_edges, float), np.asarray(y_edges, float)]
    sw, _, _ = np.histogram2d(x, y, bins=bins, weights=w)
    sw2, _, _ = np.histogram2d(x, y, bins=bins, weights=w * w)
    swf, _, _ = np.histogram2d(x, y, bins=bins, weights=w * f)
    with np.errstate(invalid="ignore", divide="ignore"):
        p = np.where(sw > 0, swf / sw, np.nan).T
        n = np.where(sw2 > 0, sw * sw / sw2, 0.0).T
    lo, hi = wilson_intervals(np.where(n > 0, p, 0.0), n)
    lo, hi = np.where(n > 0, lo, np.nan), np.where(n > 0, hi, np.nan)
    known = np.isfinite(p) & ((hi - lo) / 2 <= max_half_width)
    xe, ye = bins
    return {
        "x_centres": 0.5 * (xe[:-1] + xe[1:]),
        "y_centres": 0.5 * (ye[:-1] + ye[1:]),
        "p": p,
        "lo": lo,
        "hi": hi,
        "n": n,
        "known": known,
    }


def sweep_probability_map(
    results: pd.DataFrame,
    spec: SweepSpec,
    path: str | Path,
    *,
    x: str | None = None,
    y: str | None = None,
    bins: int | None = None,
) -> dict[str, Any] | None:
    """probability_map.png of a finished sweep: P(collision | cell) over the plane of
    :func:`plane_axes`, drawn only in cells whose 95 % interval is within +-MAX_HALF_WIDTH;
    the others are hatched as not known. The cells are those of :func:`sweep_risk_map`.

    Note the sweep's design, not a variation model, decides how often each cell is
    sampled: the map reads "P(collision | the parameters in this cell, the others as the
    sweep draws them)". ``vei risk`` draws the same map from the variation.

    Returns None when there is no plane; else the grid after writing the PNG.
    """
    from vei.report.riskmap import write_probability_map

    axes = plane_axes(results, spec, x, y)
    if axes is None or "collision" not in results.columns:
        return None
    x, y = axes
    binned = _binned(results, spec, x, y, "collision", bins)
    xe, ye = _centre_edges(binned["x_centres"]), _centre_edges(binned["y_centres"])
    grid = probability_grid(
        results[x].to_numpy(float), results[y].to_numpy(float),
        results["collision"].to_numpy(bool), xe, ye,
    )  # fmt: skip
    write_probability_map(path, grid=grid, x_label=x, y_label=y,
                          title=f"P(collision | cell) of {len(results)} sweep variants")  # fmt: skip
    return {"x": x, "y": y, "grid": grid}


def write_sample_probability_map(
    path: str | Path,
    x: np.ndarray,
    y: np.ndarray,
    failure: np.ndarray,
    *,
    weights: np.ndarray | None = None,
    x_label: str = "x",
    y_label: str = "y",
    title: str = "",
) -> dict[str, np.ndarray] | None:
    """probability_map.png of samples [N] (e.g. ``vei risk``'s, importance-weighted): cells
    over the samples' span with about 100 samples each (3 to 12 per axis), P(collision |
    cell) where known (:func:`probability_grid`). None (nothing written) under 50 samples."""
    from vei.report.riskmap import write_probability_map

    x, y = np.asarray(x, float), np.asarray(y, float)
    if len(x) < 50:
        return None
    nb = int(np.clip(np.sqrt(len(x) / 100.0), 3, 12))
    xe = np.linspace(x.min(), x.max(), nb + 1)
    ye = np.linspace(y.min(), y.max(), nb + 1)
    grid = probability_grid(x, y, failure, xe, ye, weights=weights)
    write_probability_map(path, grid=grid, x_label=x_label, y_label=y_label, title=title)
    return grid
