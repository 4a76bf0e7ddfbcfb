"""Scenario reconstruction: interaction -> world-frame scenario at the simulation rate.

The paper's Section III-B, steps 1 and 4-8 (steps 2-3, the map, are attached later by
``vei.maps``):

1. **Bounds** of the ego's GPS track and of every annotated road user (laid out in a
   provisional plane around the ego's median position), grown by ``margin_m``.
   The **origin** of the local tmerc plane is the centre of these bounds.
4. **Time sync** (:mod:`vei.recon.sync`): annotations inside the GPS span; active agents.
5. **Ego-relative -> world** (:mod:`vei.recon.world`), honouring the declared y axis. A
   world-frame interaction (``meta.frame == 'world'``) skips it: its annotations' own
   latitude/longitude are projected into the plane directly, and a declared plane origin
   (``meta.origin_lat_deg/_lon_deg``) replaces the centre of the bounds.
6. **Keyframes** per track (:mod:`vei.recon.keyframes`).
7. **Interpolation** to the grid k / rate_hz over each agent's own span (never past its
   first/last keyframe): positions by ``interp`` (:mod:`vei.recon.interpolate`; ``'auto'``
   chooses per track by its keyframe spacing, :mod:`vei.recon.auto_interp`), yaw by
   SLERP of the keyframe yaws. The ego: its GPS track by cubic spline, yaw from its
   heading, speed from the GPS speed field (else the spline's).
8. **Primary threat** among e-scooters and cyclists (:mod:`vei.recon.threat`).

With ground truth, each track's reconstruction error (RMSE, p95, max [m], world plane, at
the ground-truth timestamps inside the track's keyframe span, the interpolant evaluated
at exactly those times) goes to ``scenario.extra['reconstruction_error']``.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd
from pyproj import Geod

from vei.errors import ConfigError
from vei.geo.frame import Bounds, LocalFrame
from vei.recon import auto_interp
from vei.recon import smoother as smoother_mod
from vei.recon import threat as threat_mod
from vei.recon.accuracy import evaluate as _evaluate_accuracy
from vei.recon.calibration import POSTERIOR_STD_INFLATION
from vei.recon.interpolate import (
    INTERP_METHODS,
    KinematicLimits,
    SmoothingParams,
    fit_track_segmented,
    slerp_yaw,
    time_grid,
)
from vei.recon.keyframes import build_keyframes
from vei.recon.sync import active_per_frame, synchronise
from vei.recon.world import annotations_to_world, ego_track, lateral_to_left
from vei.types import (
    DEFAULT_DIMENSIONS_M,
    EGO_CATEGORY,
    EGO_ID,
    RIDER_CATEGORIES,
    TRAJECTORY_COLUMNS,
    AgentInfo,
    Interaction,
    Scenario,
)

_GEOD = Geod(ellps="WGS84")
#: Values of ReconstructionConfig.interp: 'auto' (chosen per track) and INTERP_METHODS.
RECON_INTERP: tuple[str, ...] = ("auto", *INTERP_METHODS)


@dataclass(frozen=True)
class ReconstructionConfig:
    """Settings of :func:`reconstruct` (validated on construction; ConfigError).

    Attributes:
        rate_hz: simulation rate [Hz] of the output trajectories (paper: CARLA at 20 Hz).
        interp: position interpolation, one of RECON_INTERP: 'auto' (default: per track
            'cubic' where its median keyframe spacing is >= auto_dense_spacing_s, the
            paper's ~1 FPS, else 'smoothing'; vei.recon.auto_interp), 'cubic' (the
            paper's), 'linear', 'smoothing' (noise-aware smoothing spline), 'kalman' (RTS
            smoother of the same motion model with its posterior uncertainty; see
            noise_estimate).
        auto_dense_spacing_s: 'auto' only: median keyframe spacing [s] below which a track
            is dense and smoothed (default 0.5 s: 2 Hz or sparser keeps the cubic).
        noise_estimate: 'kalman' only: 'ml' (default) estimates the keyframe noise sigma and
            the acceleration density q by maximum likelihood over the recording's own
            keyframes (:func:`vei.recon.smoother.estimate_noise`); 'fixed' uses noise_m and
            accel_psd_m2ps3.
        ego_path: 'spline' (default: a cubic spline through the GPS fixes, heading from the
            INS) or 'kalman' (RTS smoother with constant acceleration + white jerk over the
            GPS positions and INS velocities, noise by maximum likelihood on the ego's own
            fixes; heading from the smoothed velocity while moving: curvature and heading
            are continuous).
        margin_m: margin around the trajectories' bounds [m] (room for the map).
        noise_m: keyframe position noise, 1 sigma per axis [m] ('smoothing'). Default 0.25 m:
            the camera tracks of the trafficmonitoring data jitter by 0.1-0.3 m.
        accel_psd_m2ps3: rider acceleration spectral density q [m^2/s^3] ('smoothing');
            lam = noise_m^2 / q. 1.0 lets a rider change speed by ~1 m/s within ~1 s.
        max_speed_mps, max_accel_mps2: rider plausibility limits ('smoothing' smooths more
            while they are exceeded).
        max_gap_s: keyframes further apart than this [s] split a track (the tracker lost
            the road user); each part is interpolated on its own and the gap bridged by a
            cubic Hermite curve (a straight line for 'linear'). Default 2.5 s: at the paper's
            1 FPS, two or more missing annotations split, a single one does not.
        min_move_m: keyframe displacement below which the direction of motion is not
            trusted (yaw held from a neighbour) [m].
        corridor_half_width_m: half-width of the ego's path corridor for the primary
            threat [m] (ego half width 0.93 + rider half width 0.3 + 0.77 m of slack).
        posterior_std_inflation: 'kalman' only: factor c on the rider posterior's standard
            deviation (its covariance times c^2): the reported std, the 95 % band and the
            spread of posterior samples (vei.recon.samples) scale with it, the mean does
            not. 'calibrated' (default): POSTERIOR_STD_INFLATION (1.461, fitted on the
            shared recordings' camera, vei.recon.calibration) with noise_estimate 'ml',
            and 1.0 with 'fixed' (no fitted factor for a hand-set noise) or when no track
            has enough keyframes to estimate the noise. A number > 0 (finite) is used as
            it is in both cases: 1.0 = the model's own covariance; for data from another
            sensor, fit one with vei.recon.calibration.fit_inflation on its ground truth.
    """

    rate_hz: float = 20.0
    interp: str = "auto"
    auto_dense_spacing_s: float = auto_interp.DENSE_SPACING_S
    noise_estimate: str = "ml"
    ego_path: str = "spline"
    margin_m: float = 50.0
    noise_m: float = 0.25
    accel_psd_m2ps3: float = 1.0
    max_speed_mps: float = 12.0
    max_accel_mps2: float = 4.0
    max_gap_s: float = 2.5
    min_move_m: float = 0.5
    corridor_half_width_m: float = 2.0
    posterior_std_inflation: float | str = "calibrated"

    def __post_init__(self) -> None:
        if self.interp not in RECON_INTERP:
            raise ConfigError(
                f"interp must be one of {', '.join(RECON_INTERP)}; got {self.interp!r}"
            )
        if self.noise_estimate not in ("ml", "fixed"):
            raise ConfigError(
                f"noise_estimate must be 'ml' or 'fixed'; got {self.noise_estimate!r}"
            )
        if self.ego_path not in ("spline", "kalman"):
            raise ConfigError(f"ego_path must be 'spline' or 'kalman'; got {self.ego_path!r}")
        positive = (
            "rate_hz",
            "noise_m",
            "accel_psd_m2ps3",
            "max_speed_mps",
            "max_accel_mps2",
            "max_gap_s",
            "auto_dense_spacing_s",
        )
        for name in positive:
            v = getattr(self, name)
            if not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
                raise ConfigError(f"{name} must be a finite number > 0; got {v!r}")
        for name in ("margin_m", "min_move_m", "corridor_half_width_m"):
            v = getattr(self, name)
            if not isinstance(v, int | float) or not math.isfinite(v) or v < 0:
                raise ConfigError(f"{name} must be a finite number >= 0; got {v!r}")
        if self.rate_hz > 1000:
            raise ConfigError(f"rate_hz must be <= 1000; got {self.rate_hz}")
        c = self.posterior_std_inflation
        if c != "calibrated" and (
            isinstance(c, bool) or not isinstance(c, int | float) or not math.isfinite(c) or c <= 0
        ):
            raise ConfigError(
                f"posterior_std_inflation must be 'calibrated' or a finite number > 0; got {c!r}"
            )

    def std_inflation(self, noise_estimate: str) -> float:
        """The factor on the rider posterior's std for a noise of kind ``noise_estimate``
        ('ml' or 'fixed'): the configured number, or for 'calibrated'
        POSTERIOR_STD_INFLATION ('ml') / 1.0 ('fixed')."""
        c = self.posterior_std_inflation
        if c != "calibrated":
            return float(c)
        return POSTERIOR_STD_INFLATION if noise_estimate == "ml" else 1.0

    @property
    def smoothing(self) -> SmoothingParams:
        """The noise model of 'smoothing'."""
        return SmoothingParams(
            noise_m=self.noise_m,
            accel_psd_m2ps3=self.accel_psd_m2ps3,
            limits=KinematicLimits(self.max_speed_mps, self.max_accel_mps2),
        )

    def as_dict(self) -> dict:
        """Plain dict of the settings (for scenario.json)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> ReconstructionConfig:
        """Build from a dict (YAML/JSON); unknown keys are a ConfigError."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise ConfigError(
                f"unknown reconstruction setting(s): {', '.join(unknown)}; known: {', '.join(sorted(names))}"
            )
        return cls(**d)


#: Named presets.
PRESETS: dict[str, ReconstructionConfig] = {
    "paper": ReconstructionConfig(interp="cubic"),
    "linear": ReconstructionConfig(interp="linear"),
    "noise-aware": ReconstructionConfig(interp="smoothing"),
    "probabilistic": ReconstructionConfig(interp="kalman", ego_path="kalman"),
}


def _dimensions(world: pd.DataFrame, track_id: str, category: str) -> tuple[float, float]:
    default_l, default_w = DEFAULT_DIMENSIONS_M.get(category, DEFAULT_DIMENSIONS_M["vehicle"])
    rows = world[world["track_id"] == track_id]
    length = rows["length_m"].median(skipna=True)
    width = rows["width_m"].median(skipna=True)
    return (
        float(length) if pd.notna(length) and length > 0 else default_l,
        float(width) if pd.notna(width) and width > 0 else default_w,
    )


def _peaks(t: np.ndarray, xy: np.ndarray) -> tuple[float, float]:
    """Peak speed [m/s] and acceleration magnitude [m/s^2] by finite differences of samples."""
    if t.size < 3:
        if t.size == 2:
            return float(np.linalg.norm(xy[1] - xy[0]) / (t[1] - t[0])), 0.0
        return 0.0, 0.0
    v = np.gradient(xy, t, axis=0)
    a = np.gradient(v, t, axis=0)
    return float(np.linalg.norm(v, axis=1).max()), float(np.linalg.norm(a, axis=1).max())


def _bounds(interaction: Interaction, margin_m: float) -> Bounds:
    """Bounds of the ego fixes and of every annotation (laid out on the ellipsoid from the
    ego's linearly interpolated fix; metre-level accuracy is all the bounds need)."""
    ego = interaction.ego
    ego_t = ego["t_s"].to_numpy(dtype=np.float64)
    ego_lat = ego["lat_deg"].to_numpy(dtype=np.float64)
    ego_lon = ego["lon_deg"].to_numpy(dtype=np.float64)
    ann = interaction.annotations
    lats, lons = [ego_lat], [ego_lon]
    if interaction.meta.frame == "world":
        lats.append(ann["lat_deg"].to_numpy(dtype=np.float64))
        lons.append(ann["lon_deg"].to_numpy(dtype=np.float64))
    elif len(ann):
        t = ann["t_s"].to_numpy(dtype=np.float64)
        lat = np.interp(t, ego_t, ego_lat)
        lon = np.interp(t, ego_t, ego_lon)
        gps_heading = (
            ego["heading_deg"].to_numpy(dtype=np.float64) if "heading_deg" in ego else None
        )
        if gps_heading is not None and np.isfinite(gps_heading).all():
            heading = np.interp(t, ego_t, np.degrees(np.unwrap(np.radians(gps_heading))))
        else:  # course needs a plane
            frame = LocalFrame(float(np.median(ego_lat)), float(np.median(ego_lon)))
            heading = ego_track(interaction, frame).bearing(t)
        x = ann["x_m"].to_numpy(dtype=np.float64)
        y = lateral_to_left(ann["y_m"].to_numpy(dtype=np.float64), interaction.meta.y_axis)
        az = heading - np.degrees(np.arctan2(y, x))
        lon2, lat2, _ = _GEOD.fwd(lon, lat, az, np.hypot(x, y))
        lats.append(np.asarray(lat2))
        lons.append(np.asarray(lon2))
    return Bounds.around(np.concatenate(lats), np.concatenate(lons), margin_m=margin_m)


def reconstruct(
    interaction: Interaction,
    config: ReconstructionConfig | None = None,
    *,
    threat: str | None = None,
) -> Scenario:
    """Reconstruct a world-frame scenario from an interaction.

    Args:
        interaction: ego GPS + ego-relative annotations (+ optional ground truth).
        config: settings (default ReconstructionConfig()).
        threat: the primary threat chosen by the user (agent id or the annotations' track
            id; :func:`vei.recon.threat.resolve_threat`); None = the module's rule.
    Returns:
        Scenario with trajectories (TRAJECTORY_COLUMNS; ego first, then every annotated
        track as '<category>_<track_id>') on t_s = k / rate_hz, keyframes (t_s, agent_id,
        source_track_id, category, x_m, y_m, yaw_rad, yaw_source), primary_threat, and extra:
        'reconstruction' (settings, origin rule, sync, ego heading source, per-track method,
        median keyframe spacing [s] and peak kinematics (peak_speed_mps / peak_accel_mps2 by
        finite differences of the rate_hz samples, what a simulator replaying them sees),
        active riders, 'auto_interp' (what interp='auto' chose; None otherwise),
        'speed_warnings' (riders above max_speed_mps)), 'threat' (criterion + per-rider
        figures) and, with ground truth, 'reconstruction_error'.
    Warns:
        ImplausibleSpeedWarning (vei.recon.auto_interp): per rider whose reconstructed
        speed exceeds max_speed_mps, naming it, the speed and the way out.
    Raises:
        InputError: annotations outside the GPS span, an unusable ego track.
    """
    cfg = config or ReconstructionConfig()
    sync = synchronise(interaction)

    # 1. bounds of the ego and of every annotation, origin at their centre.
    bounds = _bounds(interaction, cfg.margin_m)
    meta = interaction.meta
    origin = (meta.origin_lat_deg, meta.origin_lon_deg)
    if origin[0] is None or origin[1] is None:
        origin = bounds.center
    # Rounded as the PROJ string writes it, so LocalFrame.from_proj_string gives this frame.
    frame = LocalFrame(*(round(float(v), 10) for v in origin))

    # 4-5. ego and annotations in the final plane.
    ego = ego_track(interaction, frame)
    world = annotations_to_world(interaction, ego)
    keyframes = build_keyframes(world, min_move_m=cfg.min_move_m)

    # 7. ego at the simulation rate.
    t_ego = time_grid(ego.t_start_s, ego.t_end_s, cfg.rate_hz)
    ego_xy = ego.position(t_ego)
    ego_yaw = ego.yaw(t_ego)
    ego_speed = ego.speed(t_ego)
    ego_path_info = None
    if cfg.ego_path == "kalman":
        ego_xy, ego_yaw, ego_speed, ego_path_info = _smooth_ego(ego, t_ego, ego_xy, ego_yaw)
    frames = [
        pd.DataFrame(
            {
                "t_s": t_ego,
                "agent_id": EGO_ID,
                "source_track_id": None,
                "category": EGO_CATEGORY,
                "x_m": ego_xy[:, 0],
                "y_m": ego_xy[:, 1],
                "yaw_rad": ego_yaw,
                "speed_mps": ego_speed,
            }
        )
    ]
    agents = [AgentInfo(EGO_ID, EGO_CATEGORY, *DEFAULT_DIMENSIONS_M[EGO_CATEGORY], None)]
    interpolants: dict[str, object] = {}
    track_info: list[dict] = []
    dropped: list[str] = []
    noise = None
    primed: dict[str, object] = {}
    if cfg.interp == "kalman":
        noise = _rider_noise(keyframes, cfg)
        primed = _primed_kalman(keyframes, cfg, noise)
    for agent_id, kf in keyframes.groupby("agent_id", sort=True):
        tk = kf["t_s"].to_numpy(dtype=np.float64)
        xyk = kf[["x_m", "y_m"]].to_numpy(dtype=np.float64)
        category = str(kf["category"].iloc[0])
        track_id = str(kf["source_track_id"].iloc[0])
        grid = time_grid(tk[0], tk[-1], cfg.rate_hz)
        if grid.size == 0:
            dropped.append(str(agent_id))
            continue
        method, spacing = auto_interp.resolve(cfg.interp, tk, cfg.auto_dense_spacing_s)
        interp = primed.get(str(agent_id)) or fit_track_segmented(
            tk, xyk, method, cfg.smoothing, cfg.max_gap_s, noise
        )
        interpolants[str(agent_id)] = interp
        xy = interp.position(grid)
        vel = interp.velocity(grid)
        yaw = slerp_yaw(tk, kf["yaw_rad"].to_numpy(dtype=np.float64), grid)
        if interp.method == "kalman":  # yaw from the smoothed velocity where it moves
            moving = np.hypot(vel[:, 0], vel[:, 1]) >= KALMAN_YAW_MIN_SPEED_MPS
            yaw = np.where(moving, np.arctan2(vel[:, 1], vel[:, 0]), yaw)
        frames.append(
            pd.DataFrame(
                {
                    "t_s": grid,
                    "agent_id": str(agent_id),
                    "source_track_id": track_id,
                    "category": category,
                    "x_m": xy[:, 0],
                    "y_m": xy[:, 1],
                    "yaw_rad": yaw,
                    "speed_mps": np.hypot(vel[:, 0], vel[:, 1]),
                }
            )
        )
        length, width = _dimensions(world, track_id, category)
        agents.append(AgentInfo(str(agent_id), category, length, width, track_id))
        peak_v, peak_a = _peaks(grid, xy)
        track_info.append(
            {
                "agent_id": str(agent_id),
                "category": category,
                "n_keyframes": int(tk.size),
                "median_keyframe_spacing_s": spacing,
                "t_start_s": float(tk[0]),
                "t_end_s": float(tk[-1]),
                "method": interp.method,
                "lam": interp.lam,
                "peak_speed_mps": peak_v,
                "peak_accel_mps2": peak_a,
            }
        )
        if interp.method == "kalman":
            std = interp.std(grid)
            track_info[-1]["std_m"] = {"mean": float(std.mean()), "max": float(std.max())}
    trajectories = pd.concat(frames, ignore_index=True)[list(TRAJECTORY_COLUMNS)]
    implausible = auto_interp.implausible_speeds(trajectories, track_info, cfg.max_speed_mps)
    for w in implausible:
        warnings.warn(w.message(), auto_interp.ImplausibleSpeedWarning, stacklevel=2)
    # A track with no sample on the simulation grid is not an agent of the scenario.
    keyframes = keyframes[~keyframes["agent_id"].isin(dropped)].reset_index(drop=True)

    # 8. primary threat.
    figures = []
    for info in track_info:
        if info["category"] not in RIDER_CATEGORIES:
            continue
        tr = trajectories[trajectories["agent_id"] == info["agent_id"]]
        figures.append(
            threat_mod.threat_figures(
                info["agent_id"],
                tr["t_s"].to_numpy(),
                tr[["x_m", "y_m"]].to_numpy(),
                t_ego,
                ego_xy,
                ego_yaw,
                ego_speed,
                cfg.corridor_half_width_m,
                category=info["category"],
            )
        )
    primary = threat_mod.primary_threat(figures)

    active = active_per_frame(trajectories, RIDER_CATEGORIES)
    extra: dict = {
        "reconstruction": {
            "config": cfg.as_dict(),
            "origin_rule": (
                "the interaction's declared plane origin"
                if meta.origin_lat_deg is not None
                else "centre of the bounds of the ego GPS track and all annotated road users"
            ),
            "annotation_frame": (
                "world: each road user's own lat/lon projected into the plane directly (no "
                "ego-relative step)"
                if meta.frame == "world"
                else "ego: ego-relative offsets laid out from the ego pose on the ellipsoid"
            ),
            "sync": sync.as_dict(),
            "ego_heading_source": ego.heading_source,
            "y_axis": interaction.meta.y_axis,
            "max_active_riders": int(active["n_active"].max()) if len(active) else 0,
            "tracks": track_info,
            "dropped_tracks": dropped,
            "noise": None if noise is None else noise.as_dict(),
            "ego_path": ego_path_info,
            "auto_interp": auto_interp.summary(cfg.interp, cfg.auto_dense_spacing_s, track_info),
            "speed_warnings": [w.as_dict() for w in implausible],
        },
        "threat": {
            "criterion": (
                "riders (escooter, cyclist) whose path comes within corridor_half_width_m of "
                "the ego path conflict; primary = a conflicting rider, e-scooters before "
                "cyclists, then the smallest post-encroachment time (ties: min gap); without "
                "conflicts the rider with the smallest same-time gap to the ego (e-scooters "
                "first among equal gaps); --threat TRACK_ID overrides"
            ),
            "chosen_by": "rule",
            "corridor_half_width_m": cfg.corridor_half_width_m,
            "riders": [f.as_dict() for f in figures],
        },
        "source": interaction.meta.source,
    }
    if interaction.ground_truth is not None and len(interaction.ground_truth):
        extra["reconstruction_error"] = evaluate(
            interaction.ground_truth, frame, keyframes, interpolants
        )

    scenario = Scenario(
        id=interaction.meta.id,
        projection=frame.proj_string,
        origin_lat_deg=frame.origin_lat_deg,
        origin_lon_deg=frame.origin_lon_deg,
        start_time_utc=interaction.meta.start_time_utc,
        rate_hz=cfg.rate_hz,
        bounds=bounds.as_dict(),
        agents=tuple(agents),
        primary_threat=primary,
        trajectories=trajectories,
        keyframes=keyframes,
        maps={},
        extra=extra,
    )
    return threat_mod.with_threat(scenario, threat)


def evaluate(
    ground_truth: pd.DataFrame, frame: LocalFrame, keyframes: pd.DataFrame, interpolants: dict
) -> dict:
    """Per-track reconstruction error and calibration against world ground truth
    (:func:`vei.recon.accuracy.evaluate`: RMSE vs raw and vs Savitzky-Golay denoised
    ground truth, 95 % coverage for 'kalman')."""
    return _evaluate_accuracy(ground_truth, frame, keyframes, interpolants)


#: Below this smoothed speed [m/s] a 'kalman' track's yaw is SLERPed between keyframes.
KALMAN_YAW_MIN_SPEED_MPS = 0.5


def _rider_noise(keyframes: pd.DataFrame, cfg: ReconstructionConfig) -> smoother_mod.NoiseEstimate:
    """The 'kalman' noise: ML over every track's keyframes, or the configured values."""
    fixed = smoother_mod.NoiseEstimate(
        cfg.noise_m, cfg.accel_psd_m2ps3, std_inflation=cfg.std_inflation("fixed")
    )
    if cfg.noise_estimate == "fixed":
        return fixed
    tracks = [
        (g["t_s"].to_numpy(np.float64), g[["x_m", "y_m"]].to_numpy(np.float64))
        for _, g in keyframes.groupby("agent_id", sort=True)
    ]
    return smoother_mod.estimate_noise(tracks, default=fixed, std_inflation=cfg.std_inflation("ml"))


def _primed_kalman(keyframes: pd.DataFrame, cfg: ReconstructionConfig, noise) -> dict:
    """'kalman' interpolants of every track, their posteriors on the rate_hz grid computed
    in one batch (the per-track loop then reads them from the cache)."""
    out, grids = {}, []
    for agent_id, kf in keyframes.groupby("agent_id", sort=True):
        tk = kf["t_s"].to_numpy(dtype=np.float64)
        xyk = kf[["x_m", "y_m"]].to_numpy(dtype=np.float64)
        out[str(agent_id)] = fit_track_segmented(
            tk, xyk, "kalman", cfg.smoothing, cfg.max_gap_s, noise
        )
        grids.append(time_grid(tk[0], tk[-1], cfg.rate_hz))
    smoother_mod.prime(list(out.values()), grids)
    return out


def _smooth_ego(ego, t_ego: np.ndarray, xy_before: np.ndarray, yaw_before: np.ndarray):
    """Ego path by the RTS smoother (constant acceleration + white jerk) over the GPS
    positions and the INS velocity (speed along the heading, where both are given).

    Returns (xy [N, 2], yaw [N], speed [N], info): yaw from the smoothed velocity while
    moving faster than MOVING_MIN_SPEED_MPS, else the INS heading; info holds the noise
    estimate and the lateral acceleration of the path before / after (finite differences
    of the rate_hz samples, max |a_lat| and RMS, and the largest change of a_lat per
    second, which is large where the curvature jumps)."""
    t_fix = ego.t_s
    xy_fix = np.column_stack([ego.x_m, ego.y_m])
    vel_fix = None
    if np.all(np.isfinite(ego.speed_mps)):
        yaw_fix = ego.yaw(t_fix)
        vel_fix = ego.speed_mps[:, None] * np.column_stack([np.cos(yaw_fix), np.sin(yaw_fix)])
    if t_fix.size < 4 or t_ego.size < 3:
        return xy_before, yaw_before, ego.speed(t_ego), None
    xy, vel, _, noise = smoother_mod.smooth_ego(t_fix, xy_fix, vel_fix, t_ego)
    speed = np.hypot(vel[:, 0], vel[:, 1])
    moving = speed >= smoother_mod.MOVING_MIN_SPEED_MPS
    yaw = np.where(moving, np.arctan2(vel[:, 1], vel[:, 0]), yaw_before)

    def figures(path: np.ndarray) -> dict:
        lat = smoother_mod.lateral_accel(t_ego, path)
        ok = np.isfinite(lat)
        if not ok.any():
            return {
                "max_abs_lat_accel_mps2": None,
                "rms_lat_accel_mps2": None,
                "max_lat_jerk_mps3": None,
            }
        jerk = np.abs(np.diff(lat)) / np.diff(t_ego)
        return {
            "max_abs_lat_accel_mps2": float(np.max(np.abs(lat[ok]))),
            "rms_lat_accel_mps2": float(np.sqrt(np.mean(lat[ok] ** 2))),
            "max_lat_jerk_mps3": float(np.nanmax(jerk)) if np.isfinite(jerk).any() else None,
        }

    info = {
        "method": "kalman",
        "noise": noise.as_dict(),
        "shift_rms_m": float(np.sqrt(np.mean(np.sum((xy - xy_before) ** 2, axis=1)))),
        "before": figures(xy_before),
        "after": figures(xy),
    }
    return xy, yaw, speed, info
