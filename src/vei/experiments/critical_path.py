"""The spatial step of making a recording critical: ``--make-critical timing+path``.

The paper makes a recording critical by timing alone (:mod:`vei.sim.timeshift`).
On most real recordings the rider's path never comes near the car's, so no shift makes
them meet. ``timing+path`` first applies the *smallest* change of the rider's recorded
path that makes the paths meet, then the time shift on the changed path, and reports the
change's size: a measure of how close the recorded encounter came to a crash.

The changes considered (rigid: the rider's speed profile, timing and shape are kept):

- **offset**: the whole path translated by ``offset_m`` along the direction from its
  point of closest approach P to the nearest point Q of the ego front's path (positive =
  towards it). Where the paths run side by side this is a lateral offset; where the rider
  stops short of the road (its path ends at P) it moves the route onward. Its components
  across and along the rider's heading at P are reported (``lateral_m``,
  ``longitudinal_m``);
- **rotation**: the whole path rotated by ``rotation_deg`` (counter-clockwise positive)
  about P.

"The paths meet" means the changed rider path passes within ``tolerance_m`` of the path
that the ego's front centre drives under ``replay`` (the ego alone, as in the time
shift's search). Each kind is searched outwards from zero on a grid (``offset_step_m``,
``rotation_step_deg``) in both directions up to the search limits; the smallest success
of each kind is kept. The chosen change is the one of smaller *normalised size*
``|offset| / PLAUSIBLE_OFFSET_M`` vs ``|rotation| / PLAUSIBLE_ROTATION_DEG`` (offset on
ties). It is *plausible* when its normalised size is at most 1: the bounds are the 90 %
quantiles of how far (3.9 m) and at what angle (19.4 deg) real riders' routes lie from the
nearest other rider's route on the same stretch, measured on the nine shared TrafficMonitoring
recordings (:mod:`vei.experiments.rider_spread`). Larger changes are still applied (so the
study runs) but flagged implausible on the terminal and in summary.json.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

from vei.config import CaseConfig, SimConfig
from vei.errors import InputError
from vei.sim.timeshift import EgoFront, TimeShiftResult, ego_front, find_time_shift
from vei.types import Scenario

#: Plausible lateral offset of a rider's route [m] (90 % quantile of real nearest-route
#: distances on the shared recordings; vei.experiments.rider_spread, recomputed in tests).
PLAUSIBLE_OFFSET_M = 3.9
#: Plausible rotation of a rider's route [deg] (90 % quantile of nearest-route angles).
PLAUSIBLE_ROTATION_DEG = 19.4
#: Modes of ``--make-critical``.
MAKE_CRITICAL_MODES: tuple[str, ...] = ("timing", "timing+path")


@dataclass(frozen=True)
class PathSearch:
    """Search settings of :func:`find_path_perturbation` (validated).

    Attributes:
        tolerance_m: the changed rider path must pass this close to the ego front's path [m].
        offset_step_m, max_offset_m: offset grid step and search limit [m].
        rotation_step_deg, max_rotation_deg: rotation grid step and search limit [deg].
        plausible_offset_m, plausible_rotation_deg: the plausibility bounds (normalisers).
    """

    tolerance_m: float = 0.2
    offset_step_m: float = 0.05
    max_offset_m: float = 30.0
    rotation_step_deg: float = 0.1
    max_rotation_deg: float = 60.0
    plausible_offset_m: float = PLAUSIBLE_OFFSET_M
    plausible_rotation_deg: float = PLAUSIBLE_ROTATION_DEG

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not (isinstance(v, int | float) and np.isfinite(v) and v > 0):
                raise InputError(f"PathSearch.{f.name} must be a finite number > 0, got {v!r}")


@dataclass(frozen=True)
class PathPerturbation:
    """The change applied to the rider's path (see the module doc).

    Attributes:
        kind: 'none' (timing alone meets), 'offset', 'rotation', or 'failed' (nothing
            within the search limits).
        offset_m: lateral offset [m] (0 unless 'offset'). rotation_deg: rotation [deg].
        pivot_x_m, pivot_y_m: P, the rider's point of closest approach to the ego's path.
        dir_x, dir_y: unit offset direction (P towards Q).
        lateral_m, longitudinal_m: the offset's components across (positive = left) and
            along the rider's heading at P [m].
        path_distance_m: closest approach of the recorded rider path to the ego front's path [m].
        size: normalised size (max of |offset| / plausible_offset, |rotation| / plausible_rotation).
        plausible: size <= 1.
        best_offset_m, best_rotation_deg: the smallest success of each kind (NaN: none).
        plausible_offset_m, plausible_rotation_deg: the bounds used.
    """

    kind: str
    offset_m: float
    rotation_deg: float
    pivot_x_m: float
    pivot_y_m: float
    dir_x: float
    dir_y: float
    lateral_m: float
    longitudinal_m: float
    path_distance_m: float
    size: float
    plausible: bool
    best_offset_m: float
    best_rotation_deg: float
    plausible_offset_m: float
    plausible_rotation_deg: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields (NaN -> None)."""
        out: dict[str, Any] = {}
        for k, v in dataclasses.asdict(self).items():
            out[k] = None if isinstance(v, float) and not np.isfinite(v) else v
        return out

    def message(self, rider_id: str) -> str:
        """One line for the terminal."""
        if self.kind == "none":
            return f"make critical (timing+path): {rider_id}'s recorded path already meets the ego's; no change"
        if self.kind == "failed":
            return (
                f"make critical (timing+path): NO offset up to the search limit or rotation makes "
                f"{rider_id}'s path meet the ego's (closest approach {self.path_distance_m:.2f} m)"
            )
        what = (
            f"offset {self.offset_m:+.2f} m towards the ego's path (lateral {self.lateral_m:+.2f} m, "
            f"along its heading {self.longitudinal_m:+.2f} m)"
            if self.kind == "offset"
            else f"rotation {self.rotation_deg:+.1f} deg about its closest approach"
        )
        verdict = "within" if self.plausible else "OUTSIDE"
        return (
            f"make critical (timing+path): {rider_id}'s path changed: {what} (closest approach "
            f"{self.path_distance_m:.2f} m; normalised size {self.size:.2f}, {verdict} the plausible "
            f"bounds {self.plausible_offset_m:g} m / {self.plausible_rotation_deg:g} deg)"
        )


def transform_xy_yaw(
    x_m: np.ndarray,
    y_m: np.ndarray,
    yaw_rad: np.ndarray,
    *,
    pivot: tuple[float, float],
    rotation_rad: float,
    shift: tuple[float, float],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rotate positions by rotation_rad about pivot, then translate by shift; yaw + rotation.

    Args:
        x_m, y_m, yaw_rad: [N]. pivot: (x, y) [m]. rotation_rad: [rad]. shift: (dx, dy) [m].
    Returns:
        (x_m, y_m, yaw_rad) [N].
    """
    c, s = np.cos(rotation_rad), np.sin(rotation_rad)
    dx, dy = np.asarray(x_m) - pivot[0], np.asarray(y_m) - pivot[1]
    return (
        pivot[0] + c * dx - s * dy + shift[0],
        pivot[1] + s * dx + c * dy + shift[1],
        np.asarray(yaw_rad) + rotation_rad,
    )


def perturb_rider(scenario: Scenario, rider_id: str, pert: PathPerturbation) -> Scenario:
    """The scenario with the rider's trajectory (and keyframes) moved by ``pert``.

    Records the perturbation in ``extra['criticality']['perturbation']``.
    """
    rot = np.deg2rad(pert.rotation_deg)
    shift = (pert.offset_m * pert.dir_x, pert.offset_m * pert.dir_y)
    pivot = (pert.pivot_x_m, pert.pivot_y_m)

    def move(df: pd.DataFrame) -> pd.DataFrame:
        if df is None or not len(df) or "agent_id" not in df.columns:
            return df
        m = (df["agent_id"] == rider_id).to_numpy()
        if not m.any():
            return df
        out = df.copy()
        x, y, yaw = transform_xy_yaw(
            out.loc[m, "x_m"].to_numpy(dtype=float),
            out.loc[m, "y_m"].to_numpy(dtype=float),
            out.loc[m, "yaw_rad"].to_numpy(dtype=float),
            pivot=pivot,
            rotation_rad=rot,
            shift=shift,
        )
        out.loc[m, "x_m"], out.loc[m, "y_m"], out.loc[m, "yaw_rad"] = x, y, yaw
        return out

    extra = dict(scenario.extra)
    crit = dict(extra.get("criticality", {}))
    crit["perturbation"] = pert.as_dict()
    extra["criticality"] = crit
    return dataclasses.replace(
        scenario,
        trajectories=move(scenario.trajectories),
        keyframes=move(scenario.keyframes),
        extra=extra,
    )


def _dense_path(x: np.ndarray, y: np.ndarray, spacing_m: float) -> np.ndarray:
    """Points along the polyline (x, y) no further than spacing_m apart, [K, 2]."""
    seg = np.hypot(np.diff(x), np.diff(y))
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        return np.column_stack([x[:1], y[:1]])
    g = np.linspace(0.0, s[-1], int(np.ceil(s[-1] / spacing_m)) + 1)
    return np.column_stack([np.interp(g, s, x), np.interp(g, s, y)])


def _polyline_distance(
    tree: cKDTree, poly: np.ndarray, pts: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Distance [N] of points to the polyline ``poly`` [K, 2] (its vertices in ``tree``) and
    the foot points [N, 2]: nearest vertex, then the two segments that share it."""
    _, k = tree.query(pts)
    foot = poly[k].copy()
    best = np.hypot(*(pts - foot).T)
    for a_i, b_i in ((np.maximum(k - 1, 0), k), (k, np.minimum(k + 1, len(poly) - 1))):
        a, b = poly[a_i], poly[b_i]
        ab = b - a
        den = np.einsum("ij,ij->i", ab, ab)
        t = np.clip(np.einsum("ij,ij->i", pts - a, ab) / np.where(den > 0, den, 1.0), 0.0, 1.0)
        q = a + t[:, None] * ab
        d = np.hypot(*(pts - q).T)
        better = d < best
        best = np.where(better, d, best)
        foot[better] = q[better]
    return best, foot


def _first_success(values: np.ndarray, dist: np.ndarray, tol: float) -> float:
    ok = np.flatnonzero(dist <= tol + 1e-9)
    return float(np.round(values[ok[0]], 6)) if ok.size else float("nan")


def find_path_perturbation(
    scenario: Scenario,
    *,
    sim: SimConfig | None = None,
    case: CaseConfig | str = "replay",
    search: PathSearch | None = None,
    front: EgoFront | None = None,
) -> tuple[PathPerturbation, Scenario, TimeShiftResult]:
    """The smallest rider-path change that makes the paths meet, and the time shift on it.

    Args:
        scenario: the scenario (its primary threat is the rider changed).
        sim, case: as :func:`vei.sim.timeshift.find_time_shift`.
        search: search settings. front: a precomputed ego_front (optional).
    Returns:
        (perturbation, the changed scenario (unchanged for kinds 'none' / 'failed'), the
        time shift found on it).
    """
    cfg = search or PathSearch()
    f = front or ego_front(scenario, sim=sim, case=case)
    rider_id = f.rider_id
    ego_pts = _dense_path(f.fx_m, f.fy_m, 0.5 * cfg.tolerance_m)
    tree = cKDTree(ego_pts)
    rx, ry = f.recorded_xy()  # the recorded route (its continuations are extrapolations)
    rpts = _dense_path(rx, ry, 0.5 * cfg.tolerance_m)
    d0, foot0 = _polyline_distance(tree, ego_pts, rpts)
    k0 = int(np.argmin(d0))
    path_d = float(d0[k0])
    px, py = rpts[k0]
    # Rider heading at P: chord of the dense path around it (1 m either side).
    h = max(1, int(round(1.0 / (0.5 * cfg.tolerance_m))))
    a, b = rpts[max(k0 - h, 0)], rpts[min(k0 + h, len(rpts) - 1)]
    heading = float(np.arctan2(b[1] - a[1], b[0] - a[0])) if np.any(a != b) else 0.0
    qx, qy = foot0[k0]
    if path_d > 0:
        nx, ny = (qx - px) / path_d, (qy - py) / path_d
    else:
        nx, ny = -np.sin(heading), np.cos(heading)

    base = dict(
        pivot_x_m=float(px),
        pivot_y_m=float(py),
        dir_x=float(nx),
        dir_y=float(ny),
        path_distance_m=path_d,
        plausible_offset_m=cfg.plausible_offset_m,
        plausible_rotation_deg=cfg.plausible_rotation_deg,
    )
    first = find_time_shift(scenario, front=f)
    if first.paths_meet:
        pert = PathPerturbation(
            kind="none", offset_m=0.0, rotation_deg=0.0, size=0.0, plausible=True,
            lateral_m=0.0, longitudinal_m=0.0,
            best_offset_m=0.0, best_rotation_deg=0.0, **base,
        )  # fmt: skip
        return pert, scenario, first

    def min_dist(xy: np.ndarray) -> float:
        d, _ = tree.query(xy, distance_upper_bound=cfg.tolerance_m + cfg.tolerance_m)
        near = np.isfinite(d)  # only points near a vertex can be within the tolerance
        return float(_polyline_distance(tree, ego_pts, xy[near])[0].min()) if near.any() else np.inf

    mags = np.arange(cfg.offset_step_m, cfg.max_offset_m + 1e-9, cfg.offset_step_m)
    offsets = np.ravel(np.column_stack([mags, -mags]))  # +d, -d, +2d, ... (outwards)
    d_off = np.array([min_dist(rpts + o * np.array([nx, ny])) for o in offsets])
    best_off = _first_success(offsets, d_off, cfg.tolerance_m)
    rmags = np.arange(cfg.rotation_step_deg, cfg.max_rotation_deg + 1e-9, cfg.rotation_step_deg)
    rots = np.ravel(np.column_stack([rmags, -rmags]))
    rel = rpts - np.array([px, py])
    d_rot = np.empty(rots.size)
    for i, r in enumerate(np.deg2rad(rots)):
        c, s = np.cos(r), np.sin(r)
        d_rot[i] = min_dist(
            np.column_stack(
                [px + c * rel[:, 0] - s * rel[:, 1], py + s * rel[:, 0] + c * rel[:, 1]]
            )
        )
    best_rot = _first_success(rots, d_rot, cfg.tolerance_m)
    n_off = abs(best_off) / cfg.plausible_offset_m if np.isfinite(best_off) else np.inf
    n_rot = abs(best_rot) / cfg.plausible_rotation_deg if np.isfinite(best_rot) else np.inf
    if not (np.isfinite(n_off) or np.isfinite(n_rot)):
        pert = PathPerturbation(
            kind="failed", offset_m=0.0, rotation_deg=0.0, size=float("inf"), plausible=False,
            lateral_m=0.0, longitudinal_m=0.0,
            best_offset_m=best_off, best_rotation_deg=best_rot, **base,
        )  # fmt: skip
        return pert, scenario, first
    use_offset = n_off <= n_rot
    size = float(min(n_off, n_rot))
    off = float(best_off) if use_offset else 0.0
    ch, sh = np.cos(heading), np.sin(heading)
    pert = PathPerturbation(
        lateral_m=float(off * (-sh * nx + ch * ny)),
        longitudinal_m=float(off * (ch * nx + sh * ny)),
        kind="offset" if use_offset else "rotation",
        offset_m=off,
        rotation_deg=0.0 if use_offset else float(best_rot),
        size=size,
        plausible=bool(size <= 1.0),
        best_offset_m=best_off,
        best_rotation_deg=best_rot,
        **base,
    )
    moved = perturb_rider(scenario, rider_id, pert)
    # The ego's run-up depends on where the paths meet (EgoConfig.run_up_m='auto'), so
    # its motion is simulated again on the changed scenario.
    shifted = find_time_shift(moved, sim=sim, case=case)
    return pert, moved, shifted


def make_critical(
    scenario: Scenario,
    *,
    time_shift: str | float = "auto",
    mode: str = "timing",
    sim: SimConfig | None = None,
    case: CaseConfig | str = "replay",
    search: PathSearch | None = None,
) -> tuple[Scenario, float, dict[str, Any], dict[str, Any]]:
    """Choose the rider's time shift (and, for 'timing+path', its path change) honestly.

    Args:
        scenario: the scenario (its primary threat is the rider).
        time_shift: 'auto' or seconds. A given shift is evaluated (miss distance) and
            refused (InputError) when it keeps the rider out of the simulated span.
        mode: 'timing' (the paper: shift only) or 'timing+path' (needs time_shift 'auto').
        sim, case, search: as :func:`find_path_perturbation`.
    Returns:
        (scenario to run (changed for timing+path), shift [s], time-shift info for
        summary.json ({'mode': 'auto'|'given', ...TimeShiftResult.as_dict()}),
        criticality {'make_critical', 'paths_meet', 'miss_distance_m', 'message',
        'perturbation' (dict or None), 'perturbation_message'}).
    """
    from vei.errors import ConfigError
    from vei.sim.timeshift import evaluate_time_shift, parse_time_shift

    if mode not in MAKE_CRITICAL_MODES:
        raise ConfigError(
            f"--make-critical must be one of {', '.join(MAKE_CRITICAL_MODES)}; got {mode!r}"
        )
    shift = parse_time_shift(time_shift)
    pert = None
    if mode == "timing+path":
        if shift != "auto":
            raise ConfigError(
                "--make-critical timing+path chooses the time shift itself; use --time-shift auto"
            )
        pert, scenario, found = find_path_perturbation(scenario, sim=sim, case=case, search=search)
        info = {"mode": "auto", **found.as_dict()}
    elif shift == "auto":
        found = find_time_shift(scenario, sim=sim, case=case)
        info = {"mode": "auto", **found.as_dict()}
    else:
        found = evaluate_time_shift(scenario, float(shift), sim=sim, case=case)
        info = {"mode": "given", **found.as_dict()}
    crit: dict[str, Any] = {
        "make_critical": mode,
        "paths_meet": found.paths_meet,
        "miss_distance_m": found.miss_distance_m,
        "message": found.message(),
        "perturbation": None if pert is None else pert.as_dict(),
        "perturbation_message": None if pert is None else pert.message(found.rider_id),
    }
    return scenario, float(found.time_shift_s), info, crit
