"""The local world frame: a transverse-Mercator plane centred on the interaction.

x east, y north, metres; yaw in radians counter-clockwise from +x. The projection string
is the one SUMO netconvert writes into an OpenDRIVE ``geoReference`` (and CARLA reads), so
maps and trajectories share one plane.

Conversions between planar frames always go through geographic coordinates: an ego-relative
offset measured against the car's *true* heading is laid out on the ellipsoid (geodesic
forward problem, pyproj.Geod) and only then projected. Grid north of the plane differs from
true north away from the central meridian (meridian convergence); yaw conversions account
for it numerically.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import numpy.typing as npt
from pyproj import Geod, Transformer

from vei.errors import InputError

FloatArray = npt.NDArray[np.float64]

_GEOD = Geod(ellps="WGS84")
#: Step used to measure the grid direction of a true bearing [m]; curvature is negligible.
_BEARING_PROBE_M = 1.0


def _as_float_array(values: npt.ArrayLike) -> FloatArray:
    return np.asarray(values, dtype=np.float64)


@dataclass(frozen=True)
class LocalFrame:
    """Local transverse-Mercator plane with its origin at (origin_lat_deg, origin_lon_deg).

    Attributes:
        origin_lat_deg: latitude of the origin [deg], in [-90, 90].
        origin_lon_deg: longitude of the origin [deg], in [-180, 180].
    """

    origin_lat_deg: float
    origin_lon_deg: float

    def __post_init__(self) -> None:
        if not (-90.0 <= self.origin_lat_deg <= 90.0) or not math.isfinite(self.origin_lat_deg):
            raise InputError(f"origin latitude {self.origin_lat_deg} outside [-90, 90] deg")
        if not (-180.0 <= self.origin_lon_deg <= 180.0) or not math.isfinite(self.origin_lon_deg):
            raise InputError(f"origin longitude {self.origin_lon_deg} outside [-180, 180] deg")

    @property
    def proj_string(self) -> str:
        """PROJ string of the plane, as written into OpenDRIVE geoReference and scenario.json."""
        return (
            f"+proj=tmerc +lat_0={self.origin_lat_deg:.10f} +lon_0={self.origin_lon_deg:.10f} "
            "+k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs"
        )

    @classmethod
    def from_proj_string(cls, proj: str) -> LocalFrame:
        """Parse a ``+proj=tmerc +lat_0=.. +lon_0=..`` string (as written by :attr:`proj_string`
        or by SUMO netconvert) back into a frame. Other parameters must be the defaults."""
        if "+proj=tmerc" not in proj:
            raise InputError(f"expected a '+proj=tmerc' projection string, got {proj!r}")
        lat = re.search(r"\+lat_0=(-?[0-9.eE+-]+)", proj)
        lon = re.search(r"\+lon_0=(-?[0-9.eE+-]+)", proj)
        if lat is None or lon is None:
            raise InputError(f"projection string lacks +lat_0/+lon_0: {proj!r}")
        for key, default in (("k", 1.0), ("x_0", 0.0), ("y_0", 0.0)):
            m = re.search(rf"\+{key}=(-?[0-9.eE+-]+)", proj)
            if m is not None and float(m.group(1)) != default:
                raise InputError(f"projection string has +{key}={m.group(1)}; vei needs {default}")
        return cls(float(lat.group(1)), float(lon.group(1)))

    @cached_property
    def _fwd(self) -> Transformer:
        return Transformer.from_crs("EPSG:4326", self.proj_string, always_xy=True)

    @cached_property
    def _inv(self) -> Transformer:
        return Transformer.from_crs(self.proj_string, "EPSG:4326", always_xy=True)

    def to_xy(
        self, lat_deg: npt.ArrayLike, lon_deg: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """WGS84 latitude/longitude [deg] (any shape) -> plane x east, y north [m] (same shape)."""
        x, y = self._fwd.transform(_as_float_array(lon_deg), _as_float_array(lat_deg))
        return _as_float_array(x), _as_float_array(y)

    def to_latlon(self, x_m: npt.ArrayLike, y_m: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Plane x, y [m] (any shape) -> WGS84 latitude, longitude [deg] (same shape)."""
        lon, lat = self._inv.transform(_as_float_array(x_m), _as_float_array(y_m))
        return _as_float_array(lat), _as_float_array(lon)

    def bearing_to_yaw(
        self, bearing_deg: npt.ArrayLike, lat_deg: npt.ArrayLike, lon_deg: npt.ArrayLike
    ) -> FloatArray:
        """True bearing [deg, clockwise from true north] at (lat, lon) -> plane yaw [rad, CCW from +x].

        Exact for meridian convergence: the bearing is laid out on the ellipsoid for 1 m and
        the projected direction measured. Result in (-pi, pi].
        """
        bearing = _as_float_array(bearing_deg)
        lat = np.broadcast_to(_as_float_array(lat_deg), bearing.shape)
        lon = np.broadcast_to(_as_float_array(lon_deg), bearing.shape)
        lon2, lat2, _ = _GEOD.fwd(lon, lat, bearing, np.full(bearing.shape, _BEARING_PROBE_M))
        x1, y1 = self.to_xy(lat, lon)
        x2, y2 = self.to_xy(np.asarray(lat2), np.asarray(lon2))
        return np.arctan2(y2 - y1, x2 - x1)

    def yaw_to_bearing(
        self, yaw_rad: npt.ArrayLike, x_m: npt.ArrayLike, y_m: npt.ArrayLike
    ) -> FloatArray:
        """Plane yaw [rad] at plane point (x, y) -> true bearing [deg, clockwise from north, [0, 360)]."""
        yaw = _as_float_array(yaw_rad)
        x = np.broadcast_to(_as_float_array(x_m), yaw.shape)
        y = np.broadcast_to(_as_float_array(y_m), yaw.shape)
        lat1, lon1 = self.to_latlon(x, y)
        lat2, lon2 = self.to_latlon(
            x + _BEARING_PROBE_M * np.cos(yaw), y + _BEARING_PROBE_M * np.sin(yaw)
        )
        az, _, _ = _GEOD.inv(lon1, lat1, lon2, lat2)
        return np.mod(np.asarray(az, dtype=np.float64), 360.0)

    def ego_relative_to_world(
        self,
        ego_lat_deg: npt.ArrayLike,
        ego_lon_deg: npt.ArrayLike,
        ego_bearing_deg: npt.ArrayLike,
        x_fwd_m: npt.ArrayLike,
        y_left_m: npt.ArrayLike,
    ) -> tuple[FloatArray, FloatArray]:
        """Ego-relative offsets (ISO 8855: x forward, y left) -> plane x, y [m].

        Args (all broadcast to one shape):
            ego_lat_deg, ego_lon_deg: ego reference point [deg].
            ego_bearing_deg: ego true heading [deg, clockwise from true north].
            x_fwd_m, y_left_m: offset of the object in the ego frame [m].
        Returns:
            (x_m, y_m) in this plane.
        """
        x_fwd, y_left, bearing, lat, lon = np.broadcast_arrays(
            _as_float_array(x_fwd_m),
            _as_float_array(y_left_m),
            _as_float_array(ego_bearing_deg),
            _as_float_array(ego_lat_deg),
            _as_float_array(ego_lon_deg),
        )
        dist = np.hypot(x_fwd, y_left)
        # y left is a counter-clockwise angle; bearings turn clockwise.
        az = bearing - np.degrees(np.arctan2(y_left, x_fwd))
        lon2, lat2, _ = _GEOD.fwd(lon, lat, az, dist)
        return self.to_xy(np.asarray(lat2), np.asarray(lon2))


def wrap_angle(angle_rad: npt.ArrayLike) -> FloatArray:
    """Wrap angles [rad] to (-pi, pi]."""
    a = _as_float_array(angle_rad)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


@dataclass(frozen=True)
class Bounds:
    """Geographic bounding box [deg] (south <= north, west <= east; no antimeridian crossing)."""

    south_deg: float
    west_deg: float
    north_deg: float
    east_deg: float

    def __post_init__(self) -> None:
        if not (-90 <= self.south_deg <= self.north_deg <= 90):
            raise InputError(
                f"invalid latitude bounds: south={self.south_deg}, north={self.north_deg}"
            )
        if not (-180 <= self.west_deg <= self.east_deg <= 180):
            raise InputError(
                f"invalid longitude bounds: west={self.west_deg}, east={self.east_deg}"
            )

    @classmethod
    def around(
        cls, lat_deg: npt.ArrayLike, lon_deg: npt.ArrayLike, margin_m: float = 50.0
    ) -> Bounds:
        """Smallest box holding all finite points, grown by ``margin_m`` metres on each side."""
        lat = _as_float_array(lat_deg).ravel()
        lon = _as_float_array(lon_deg).ravel()
        ok = np.isfinite(lat) & np.isfinite(lon)
        if not ok.any():
            raise InputError("no finite coordinates to bound")
        lat, lon = lat[ok], lon[ok]
        if margin_m < 0:
            raise InputError(f"margin_m must be >= 0, got {margin_m}")
        s, n, w, e = lat.min(), lat.max(), lon.min(), lon.max()
        dlat = margin_m / 111_132.0
        mid = math.radians((s + n) / 2.0)
        dlon = margin_m / (111_320.0 * max(math.cos(mid), 1e-6))
        return cls(
            max(s - dlat, -90.0), max(w - dlon, -180.0), min(n + dlat, 90.0), min(e + dlon, 180.0)
        )

    @property
    def center(self) -> tuple[float, float]:
        """(lat_deg, lon_deg) of the box centre."""
        return (self.south_deg + self.north_deg) / 2.0, (self.west_deg + self.east_deg) / 2.0

    def as_dict(self) -> dict[str, float]:
        """{'south_deg', 'west_deg', 'north_deg', 'east_deg'} for JSON."""
        return {
            "south_deg": self.south_deg,
            "west_deg": self.west_deg,
            "north_deg": self.north_deg,
            "east_deg": self.east_deg,
        }

    @classmethod
    def from_dict(cls, d: dict[str, float]) -> Bounds:
        return cls(
            float(d["south_deg"]), float(d["west_deg"]), float(d["north_deg"]), float(d["east_deg"])
        )

    def as_sw_ne(self) -> str:
        """'S,W,N,E' as the CLI's --bbox takes it (and Overpass uses)."""
        return f"{self.south_deg:.7f},{self.west_deg:.7f},{self.north_deg:.7f},{self.east_deg:.7f}"
