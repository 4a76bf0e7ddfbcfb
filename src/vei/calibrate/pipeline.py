"""`vei calibrate riders`: tracks -> fits -> profile, report and figures in one folder.

Outputs in ``out``:

- ``riders_profile.json``: the rider profile (:mod:`vei.calibrate.profile`);
- ``fit_report.json`` and ``fit_report.md``: tracks kept / dropped (with the reason),
  per-track fits, populations, the vehicle repulsion and its identifiability, speed and
  acceleration quantiles model vs data;
- ``speed_accel_distributions.png``: histograms model vs data per category.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from vei.calibrate.figures import distribution_summary, plot_distributions, simulate_tracks
from vei.calibrate.fit import FIT_HORIZON_S, NEAR_VEHICLE_M, fit_tracks, vehicle_values
from vei.calibrate.profile import POP_PARAMETERS, build_profile, write_profile
from vei.calibrate.tracks import (
    MAX_GAP_S,
    MIN_DURATION_S,
    MIN_MOVING_S,
    MIN_PATH_M,
    MOVING_MPS,
    SMOOTH_WINDOW_S,
    load_scenes,
)
from vei.datasets.trafficmonitoring import DATASET_COMMIT, DATASET_REPO
from vei.errors import InputError
from vei.io.atomic import write_json, write_text

CATEGORIES: tuple[str, ...] = ("escooter", "cyclist", "all")
PROFILE_FILE = "riders_profile.json"
REPORT_JSON = "fit_report.json"
REPORT_MD = "fit_report.md"
FIGURE_FILE = "speed_accel_distributions.png"


@dataclass(frozen=True)
class CalibrationRun:
    """What :func:`calibrate_riders` wrote and found.

    Attributes:
        out: output folder. profile: the profile mapping. report: the report mapping.
        elapsed_s: wall time of the whole calibration [s].
    """

    out: Path
    profile: dict[str, Any]
    report: dict[str, Any]
    elapsed_s: float


def _finite_or_none(obj: Any) -> Any:
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite_or_none(v) for v in obj]
    return obj


def calibrate_riders(
    root: str | Path,
    out: str | Path,
    *,
    category: str = "all",
    horizon_s: float = FIT_HORIZON_S,
    scenarios: Sequence[str] | None = None,
    bootstrap: int = 20,
    figures: bool = True,
) -> CalibrationRun:
    """Fit the social-force rider to every kept rider track of a TrafficMonitoring root.

    Args:
        root: dataset root (holds ``data/measurements``). out: output folder.
        category: 'escooter', 'cyclist' or 'all' (both, fitted per track, populations per
            category and pooled).
        horizon_s: closed-loop rollout length of the fit [s] (0.5 to 10).
        scenarios: subset of scenario names (default: all of the root).
        bootstrap: resamples of the vehicle-repulsion interval. figures: write the PNG.
    Returns:
        The CalibrationRun. InputError when no track survives the filter.
    """
    t0 = time.perf_counter()
    if category not in CATEGORIES:
        raise InputError(
            f"expected one of {', '.join(CATEGORIES)}, got {category!r}", field="--category"
        )
    if not (0.5 <= horizon_s <= 10.0):
        raise InputError(f"expected 0.5 <= horizon <= 10 s, got {horizon_s}", field="--horizon-s")
    scenes = load_scenes(root, list(scenarios) if scenarios else None)
    by_name = {s.scenario: s for s in scenes}
    tracks = [t for s in scenes for t in s.riders if category == "all" or t.category == category]
    if not tracks:
        what = "rider" if category == "all" else category
        raise InputError(
            f"no {what} track passes the filter in the scenario(s) "
            f"{', '.join(s.scenario for s in scenes)}: nothing to fit",
            path=root,
        )
    result = fit_tracks(tracks, by_name, horizon_s=horizon_s, bootstrap=bootstrap)
    source = {
        "dataset": f"github.com/{DATASET_REPO}@{DATASET_COMMIT}",
        "scenarios": [s.scenario for s in scenes],
        "category": category,
        "fit_horizon_s": horizon_s,
        "filter": (
            f"split at gaps > {MAX_GAP_S:g} s; Savitzky-Golay {SMOOTH_WINDOW_S:g} s; keep segments "
            f">= {MIN_DURATION_S:g} s long, >= {MIN_PATH_M:g} m travelled, >= {MIN_MOVING_S:g} s "
            f"above {MOVING_MPS:g} m/s"
        ),
        "vehicles": "every moving vehicle track (instrumented car included), nearest 3 per window",
    }
    profile = _finite_or_none(build_profile(result, source))
    outp = Path(out)
    write_profile(outp / PROFILE_FILE, profile)
    a, b = vehicle_values(result.vehicle)
    fits = {f.key: f for f in result.tracks}
    sims = simulate_tracks(tracks, fits, by_name, a, b)
    cats = {t.key: t.category for t in tracks}
    dists = {
        c: distribution_summary(sims, [k for k in sims if cats[k] == c])
        for c in sorted(set(cats.values()))
    }
    if figures and sims:
        plot_distributions(sims, cats, outp / FIGURE_FILE)
    elapsed = time.perf_counter() - t0
    report = _finite_or_none(
        {
            "source": source,
            "n_tracks": len(result.tracks),
            "dropped": {k: v for s in scenes for k, v in s.dropped.items()},
            "tracks": profile["tracks"],
            "populations": profile["populations"],
            "vehicle_repulsion": profile["vehicle_repulsion"],
            "distributions": dists,
            "elapsed_s": elapsed,
        }
    )
    write_json(outp / REPORT_JSON, report)
    write_text(outp / REPORT_MD, format_report(report))
    return CalibrationRun(outp, profile, report, elapsed)


def _num(v: Any, fmt: str = ".2f") -> str:
    return "-" if v is None else format(v, fmt)


def format_report(report: dict[str, Any]) -> str:
    """The fit report as Markdown (what the CLI prints, too)."""
    lines = [
        "# Rider calibration",
        "",
        f"Source: {report['source']['dataset']}; fit horizon {report['source']['fit_horizon_s']:g} s.",
        f"Filter: {report['source']['filter']}.",
        "",
        f"## Per-track fits ({report['n_tracks']} tracks)",
        "",
        "| track | category | s | v0 m/s | median m/s | tau s | look-ahead m | vmax m/s | amax m/s2 | ADE@fit m | near car |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for t in report["tracks"]:
        lines.append(
            f"| {t['key']} | {t['category']} | {t['duration_s']:.1f} | {t['v0_mps']:.2f} | "
            f"{t['median_moving_speed_mps']:.2f} | {t['tau_s']:.2f} | {t['lookahead_m']:.2f} | "
            f"{t['max_speed_mps']:.2f} | {t['max_accel_mps2']:.2f} | {t['ade_fit_m']:.2f} | "
            f"{'yes' if t['near_vehicle'] else 'no'} |"
        )
    lines += ["", "## Populations (median [5 %, 95 %])", ""]
    lines.append("| population | n | " + " | ".join(POP_PARAMETERS) + " | covariance |")
    lines.append("|---|---|" + "---|" * len(POP_PARAMETERS) + "---|")
    for name, pop in report["populations"].items():
        q = pop["quantiles"]
        cells = " | ".join(
            f"{pop['median'][p]:.2f} [{q['0.05'][p]:.2f}, {q['0.95'][p]:.2f}]"
            for p in POP_PARAMETERS
        )
        lines.append(f"| {name} | {pop['n_tracks']} | {cells} | {pop['covariance_from']} |")
    v = report["vehicle_repulsion"]
    lines += [
        "",
        "## Vehicle repulsion (pooled)",
        "",
        f"Windows with a moving vehicle within {NEAR_VEHICLE_M:g} m: {v['n_windows']} from {v['n_tracks']} tracks.",
        f"Fitted A = {_num(v['fitted_a_veh_n'], '.0f')} N (90 % bootstrap {_num(v['a_ci_n'][0], '.0f')}-"
        f"{_num(v['a_ci_n'][1], '.0f')}), b = {_num(v['fitted_b_veh_per_m'])} 1/m "
        f"({_num(v['b_ci_per_m'][0])}-{_num(v['b_ci_per_m'][1])}).",
        f"ADE of those windows with the force {_num(v['ade_with_m'])} m, without {_num(v['ade_without_m'])} m.",
        (
            "Identified: the profile uses the fitted A and b."
            if v["identified"]
            else "Not identified (too few close encounters, or the force does not cut their error by "
            "5 %): the profile keeps the paper's A = 100 N, b = 3.5 1/m."
        ),
        "",
        "## Speed and |acceleration|, model vs data (closed loop over the fit windows)",
        "",
        "| category | quantity | 5 % | 25 % | 50 % | 75 % | 95 % |",
        "|---|---|---|---|---|---|---|",
    ]
    for cat, d in report["distributions"].items():
        for name in ("data_speed", "model_speed", "data_accel", "model_accel"):
            q = d[name]
            if q:
                lines.append(
                    f"| {cat} | {name} | "
                    + " | ".join(f"{q[k]:.2f}" for k in ("0.05", "0.25", "0.5", "0.75", "0.95"))
                    + " |"
                )
    if report["dropped"]:
        lines += ["", f"## Dropped tracks ({len(report['dropped'])})", ""]
        lines += [f"- {k}: {r}" for k, r in report["dropped"].items()]
    return "\n".join(lines) + "\n"
