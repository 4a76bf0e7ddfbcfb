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


def _binned(
    results: pd.DataFrame, spec: SweepSpec, x: str, y: str, value: str, bins: int | None
) -> dict[str, np.ndarray]:
    from vei.experiments.boundary import binned_risk

    if bins is None:
        bins = int(np.clip(np.sqrt(len(results) / 10.0), 4, 25))

    def edges(name: str) -> np.ndarray:
        p = spec.param(name)
        if p.num is not None and p.num >= 2:
            return _centre_edges(np.linspace(p.min, p.max, p.num))
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
    variant per bin per other setting), other designs use ``bins`` equal bins per axis
    (default: about 10 variants per bin, 4 to 25 bins per axis). The heatmap is the mean
    safety index per bin, the boundary the 0.5 level of the collision share (marching
    squares, linear interpolation; :func:`vei.experiments.boundary.share_boundary`).

    Returns:
        None when there is no plane or results lack safety_index / collision; else
        {'x', 'y', 'binned', 'segments', 'crossings'} (what was drawn) after writing the
        PNG at ``path``.
    """
    from vei.experiments.boundary import share_boundary
    from vei.report.riskmap import write_risk_map

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
    from vei.experiments.boundary import share_boundary
    from vei.report.riskmap import write_risk_map

    axes = plane_axes(results, spec, x, y)
    if axes is None or not {value, "collision"} <= set(results.columns):
        return None
    x, y = axes
    results, flagged = _unflagged(results, x, y)
    binned = _binned(results, spec, x, y, "collision", bins)  # the boundary: every variant
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
