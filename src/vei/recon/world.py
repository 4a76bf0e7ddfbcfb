"""Ego pose over time and annotations -> world plane (paper Section III-B, step 5).

The ego's GPS fixes are projected into the local plane and interpolated there with a cubic
spline (position); its heading comes from the GPS ``heading_deg`` field where given, else
from the course (direction of motion of the position spline; held through stops), and is
interpolated on the circle (unwrapped, then linear). Annotations (x forward, lateral y per
``interaction.meta.y_axis``; 'right' is negated to ISO 8855 'left' here, as is the relative
yaw) are laid out from the ego's position along its *true* heading on the ellipsoid by
:meth:`vei.geo.frame.LocalFrame.ego_relative_to_world`.

A world-frame interaction (``meta.frame == 'world'``: drone and infrastructure datasets,
every car of them a possible ego) already holds each road user's own latitude/longitude and
true heading: those are projected into the plane directly (:func:`world_annotations`), with
no ego-relative step in between.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy.interpolate import CubicSpline

from vei.errors import InputError
from vei.geo.frame import LocalFrame, wrap_angle
from vei.types import Interaction

FloatArray = npt.NDArray[np.float64]

#: Below this speed [m/s] the ego's course (direction of motion) is not trusted.
COURSE_MIN_SPEED_MPS = 0.5


@dataclass(frozen=True)
class EgoTrack:
    """The ego's GPS track in one plane, with continuous pose queries.

    Attributes:
        frame: the plane.
        t_s: [M] fix times [s]; x_m, y_m: [M] plane position [m].
        bearing_deg: [M] true heading [deg clockwise from north], unwrapped (continuous).
        heading_source: 'gps' (heading_deg field), 'course', or 'gps+course' (gaps filled).
        speed_mps: [M] speed [m/s] from the GPS field, NaN where absent.
    """

    frame: LocalFrame
    t_s: FloatArray
    x_m: FloatArray
    y_m: FloatArray
    bearing_deg: FloatArray
    heading_source: str
    speed_mps: FloatArray

    @property
    def t_start_s(self) -> float:
        return float(self.t_s[0])

    @property
    def t_end_s(self) -> float:
        return float(self.t_s[-1])

    def _spline(self) -> CubicSpline | None:
        if self.t_s.size < 4:
            return None
        return CubicSpline(self.t_s, np.column_stack([self.x_m, self.y_m]), axis=0)

    def position(self, t_s: npt.ArrayLike) -> FloatArray:
        """Plane position [N, 2] (m) at times t_s [N] within the GPS span (cubic spline)."""
        t = np.clip(np.asarray(t_s, dtype=np.float64).ravel(), self.t_s[0], self.t_s[-1])
        spline = self._spline()
        if spline is None:
            return np.column_stack(
                [np.interp(t, self.t_s, self.x_m), np.interp(t, self.t_s, self.y_m)]
            )
        return spline(t)

    def velocity(self, t_s: npt.ArrayLike) -> FloatArray:
        """Plane velocity [N, 2] (m/s) at t_s [N] (derivative of the position spline)."""
        t = np.clip(np.asarray(t_s, dtype=np.float64).ravel(), self.t_s[0], self.t_s[-1])
        spline = self._spline()
        if spline is None:
            return np.column_stack(
                [np.gradient(self.x_m, self.t_s), np.gradient(self.y_m, self.t_s)]
            )[np.clip(np.searchsorted(self.t_s, t), 0, self.t_s.size - 1)]
        return spline(t, 1)

    def bearing(self, t_s: npt.ArrayLike) -> FloatArray:
        """True heading [N] (deg clockwise from north, in [0, 360)) at t_s, interpolated on the circle."""
        t = np.asarray(t_s, dtype=np.float64).ravel()
        return np.mod(np.interp(t, self.t_s, self.bearing_deg), 360.0)

    def latlon(self, t_s: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(lat_deg [N], lon_deg [N]) of the interpolated position at t_s."""
        xy = self.position(t_s)
        return self.frame.to_latlon(xy[:, 0], xy[:, 1])

    def yaw(self, t_s: npt.ArrayLike) -> FloatArray:
        """Plane yaw [N] (rad, CCW from +x) at t_s (heading converted with meridian convergence)."""
        lat, lon = self.latlon(t_s)
        return self.frame.bearing_to_yaw(self.bearing(t_s), lat, lon)

    def speed(self, t_s: npt.ArrayLike) -> FloatArray:
        """Speed [N] (m/s): the GPS speed field where given (interpolated), else |velocity|."""
        t = np.asarray(t_s, dtype=np.float64).ravel()
        out = np.linalg.norm(self.velocity(t), axis=1)
        ok = np.isfinite(self.speed_mps)
        if ok.sum() >= 2:
            field_speed = np.interp(t, self.t_s[ok], self.speed_mps[ok])
            if ok.all():
                return field_speed
            # Use the field only between fixes that both have it.
            idx = np.clip(np.searchsorted(self.t_s, t, side="right") - 1, 0, self.t_s.size - 1)
            nxt = np.clip(idx + 1, 0, self.t_s.size - 1)
            use = ok[idx] & ok[nxt]
            out = np.where(use, field_speed, out)
        return out


def ego_track(interaction: Interaction, frame: LocalFrame) -> EgoTrack:
    """Project the ego's GPS track into ``frame`` and settle its heading.

    Args:
        interaction: ego columns t_s, lat_deg, lon_deg, heading_deg (may be NaN), speed_mps.
        frame: the plane.
    Returns:
        EgoTrack (arrays of the M fixes).
    Raises:
        InputError: fewer than 2 fixes, or no heading field and the ego never moves.
    """
    ego = interaction.ego
    path = None if interaction.root is None else interaction.root / "ego.csv"
    if len(ego) < 2:
        raise InputError("the ego track needs at least 2 GPS fixes", path=path)
    t = ego["t_s"].to_numpy(dtype=np.float64)
    x, y = frame.to_xy(
        ego["lat_deg"].to_numpy(dtype=np.float64), ego["lon_deg"].to_numpy(dtype=np.float64)
    )
    heading = (
        ego["heading_deg"].to_numpy(dtype=np.float64)
        if "heading_deg" in ego
        else np.full(t.size, np.nan)
    )
    speed = (
        ego["speed_mps"].to_numpy(dtype=np.float64)
        if "speed_mps" in ego
        else np.full(t.size, np.nan)
    )
    have = np.isfinite(heading)
    if have.all():
        source = "gps"
        bearing = heading
    else:
        course = _course_bearing(frame, t, x, y)
        if course is None and not have.any():
            raise InputError(
                "ego.csv has no heading_deg and the ego never moves faster than "
                f"{COURSE_MIN_SPEED_MPS} m/s, so its heading is unknown",
                path=path,
                field="heading_deg",
            )
        if course is None:
            bearing = _fill_nearest(heading)
            source = "gps"
        else:
            bearing = np.where(have, heading, course)
            source = "gps+course" if have.any() else "course"
    bearing = np.degrees(np.unwrap(np.radians(bearing)))
    return EgoTrack(frame, t, x, y, bearing, source, speed)


def _course_bearing(
    frame: LocalFrame, t: FloatArray, x: FloatArray, y: FloatArray
) -> FloatArray | None:
    """Course [deg clockwise from north] from the positions; held through stops; None if never moving.

    Velocity by central differences of the fixes (a spline would ring around a stop and
    point backwards there)."""
    v = np.column_stack([np.gradient(x, t), np.gradient(y, t)])
    moving = np.hypot(v[:, 0], v[:, 1]) >= COURSE_MIN_SPEED_MPS
    if not moving.any():
        return None
    yaw = np.arctan2(v[:, 1], v[:, 0])
    bearing = frame.yaw_to_bearing(yaw, x, y)
    bearing[~moving] = np.nan
    return _fill_nearest(bearing)


def _fill_nearest(values: FloatArray) -> FloatArray:
    """Replace NaN by the nearest finite value (by index)."""
    ok = np.flatnonzero(np.isfinite(values))
    idx = np.arange(values.size)
    pos = np.clip(np.searchsorted(ok, idx), 0, ok.size - 1)
    left = ok[np.clip(pos - 1, 0, ok.size - 1)]
    right = ok[pos]
    nearest = np.where(np.abs(idx - left) <= np.abs(right - idx), left, right)
    return values[nearest]


def lateral_to_left(y_m: npt.ArrayLike, y_axis: str) -> FloatArray:
    """Annotation lateral offsets [m] -> ISO 8855 y-left (negated when the input's y points right)."""
    y = np.asarray(y_m, dtype=np.float64)
    if y_axis == "left":
        return y
    if y_axis == "right":
        return -y
    raise InputError(f"y_axis must be 'left' or 'right', got {y_axis!r}", field="y_axis")


def annotations_to_world(interaction: Interaction, ego: EgoTrack) -> pd.DataFrame:
    """Every annotation in the world plane of ``ego.frame``.

    Args:
        interaction: annotations with t_s, track_id, category, x_m, y_m, yaw_deg (NaN if
            absent), length_m, width_m; meta.y_axis.
        ego: the ego track in the target plane.
    Returns:
        DataFrame sorted by (track_id, t_s), columns t_s, track_id, category, x_m, y_m
        (plane [m]), yaw_rad (plane yaw from the annotation's relative yaw, NaN where it
        has none), length_m, width_m, ego_x_m, ego_y_m (ego position at that time).
    """
    if interaction.meta.frame == "world":
        return world_annotations(interaction, ego)
    ann = interaction.annotations.sort_values(["track_id", "t_s"], kind="stable").reset_index(
        drop=True
    )
    t = ann["t_s"].to_numpy(dtype=np.float64)
    y_axis = interaction.meta.y_axis
    x_fwd = ann["x_m"].to_numpy(dtype=np.float64)
    y_left = lateral_to_left(ann["y_m"].to_numpy(dtype=np.float64), y_axis)
    ego_xy = ego.position(t)
    lat, lon = ego.frame.to_latlon(ego_xy[:, 0], ego_xy[:, 1])
    bearing = ego.bearing(t)
    wx, wy = ego.frame.ego_relative_to_world(lat, lon, bearing, x_fwd, y_left)
    if "yaw_deg" in ann:
        rel_left = lateral_to_left(ann["yaw_deg"].to_numpy(dtype=np.float64), y_axis)
    else:
        rel_left = np.full(t.size, np.nan)
    ego_yaw = ego.frame.bearing_to_yaw(bearing, lat, lon) if t.size else np.zeros(0)
    yaw = wrap_angle(ego_yaw + np.radians(rel_left))
    out = pd.DataFrame(
        {
            "t_s": t,
            "track_id": ann["track_id"].astype(str).to_numpy(),
            "category": ann["category"].astype(str).to_numpy(),
            "x_m": np.asarray(wx, dtype=np.float64).reshape(-1),
            "y_m": np.asarray(wy, dtype=np.float64).reshape(-1),
            "yaw_rad": np.asarray(yaw, dtype=np.float64).reshape(-1),
            "length_m": _col(ann, "length_m"),
            "width_m": _col(ann, "width_m"),
            "ego_x_m": ego_xy[:, 0],
            "ego_y_m": ego_xy[:, 1],
        }
    )
    return out


def world_annotations(interaction: Interaction, ego: EgoTrack) -> pd.DataFrame:
    """The annotations of a world-frame interaction in the plane of ``ego.frame``.

    Each row's own lat_deg / lon_deg is projected into the plane and its true heading
    (heading_deg, NaN where absent) turned into a plane yaw at that point (meridian
    convergence included); the ego is only sampled for ego_x_m / ego_y_m. Returns the same
    columns as :func:`annotations_to_world`.
    """
    ann = interaction.annotations.sort_values(["track_id", "t_s"], kind="stable").reset_index(
        drop=True
    )
    t = ann["t_s"].to_numpy(dtype=np.float64)
    lat = ann["lat_deg"].to_numpy(dtype=np.float64)
    lon = ann["lon_deg"].to_numpy(dtype=np.float64)
    x, y = ego.frame.to_xy(lat, lon)
    heading = _col(ann, "heading_deg")
    yaw = np.full(t.size, np.nan)
    ok = np.isfinite(heading)
    if ok.any():
        yaw[ok] = ego.frame.bearing_to_yaw(heading[ok], lat[ok], lon[ok])
    ego_xy = ego.position(t)
    return pd.DataFrame(
        {
            "t_s": t,
            "track_id": ann["track_id"].astype(str).to_numpy(),
            "category": ann["category"].astype(str).to_numpy(),
            "x_m": np.asarray(x, dtype=np.float64).reshape(-1),
            "y_m": np.asarray(y, dtype=np.float64).reshape(-1),
            "yaw_rad": yaw,
            "length_m": _col(ann, "length_m"),
            "width_m": _col(ann, "width_m"),
            "ego_x_m": ego_xy[:, 0],
            "ego_y_m": ego_xy[:, 1],
        }
    )


def _col(df: pd.DataFrame, name: str) -> FloatArray:
    if name in df:
        return df[name].to_numpy(dtype=np.float64)
    return np.full(len(df), np.nan)
