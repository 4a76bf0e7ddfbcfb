"""Projected grids of datasets (UTM zones, UTM-translated local frames) <-> WGS84.

Drone and infrastructure datasets give positions in a projected grid: the inD family in a
UTM zone translated to a local origin (``xCenter + xUtmOrigin``), Argoverse 2 in a UTM zone
translated to a city origin. :class:`UtmGrid` converts such grid coordinates to latitude /
longitude (pyproj, WGS84) and a heading measured in the grid (counter-clockwise from grid
east) to a true bearing. Grid north differs from true north by the meridian convergence
(about 1.8 deg at Ingolstadt, 2-3 deg at Aachen near the zone edge): the bearing is
measured numerically on the ellipsoid, as :class:`vei.geo.frame.LocalFrame` does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import numpy.typing as npt
from pyproj import Geod, Transformer

from vei.errors import InputError

FloatArray = npt.NDArray[np.float64]

_GEOD = Geod(ellps="WGS84")
#: Step used to measure the true bearing of a grid direction [m]; curvature is negligible.
_PROBE_M = 1.0


def utm_zone_of(lat_deg: float, lon_deg: float) -> tuple[int, bool]:
    """(zone 1..60, south) of the standard UTM zone holding (lat, lon) [deg] (no Norway /
    Svalbard exceptions: none of the supported datasets lies there)."""
    if not (math.isfinite(lat_deg) and math.isfinite(lon_deg)):
        raise InputError(f"cannot choose a UTM zone for ({lat_deg}, {lon_deg})")
    zone = int((lon_deg + 180.0) // 6.0) % 60 + 1
    return zone, lat_deg < 0.0


@dataclass(frozen=True)
class UtmGrid:
    """A UTM zone (WGS84), optionally translated: grid (x, y) = (easting, northing) - origin.

    Attributes:
        zone: UTM zone number, 1..60.
        south: southern-hemisphere zone (false northing 10,000 km).
        x_origin_m, y_origin_m: easting / northing [m] of the local origin (0 for plain UTM).
    """

    zone: int
    south: bool = False
    x_origin_m: float = 0.0
    y_origin_m: float = 0.0

    def __post_init__(self) -> None:
        if (
            isinstance(self.zone, bool)
            or not isinstance(self.zone, int)
            or not 1 <= self.zone <= 60
        ):
            raise InputError(f"UTM zone must be an integer in 1..60, got {self.zone!r}")
        for name in ("x_origin_m", "y_origin_m"):
            if not math.isfinite(getattr(self, name)):
                raise InputError(f"{name} must be finite, got {getattr(self, name)!r}")

    @property
    def crs(self) -> str:
        """PROJ string of the (untranslated) zone."""
        south = " +south" if self.south else ""
        return f"+proj=utm +zone={self.zone}{south} +ellps=WGS84 +datum=WGS84 +units=m +no_defs"

    @cached_property
    def _inv(self) -> Transformer:
        return Transformer.from_crs(self.crs, "EPSG:4326", always_xy=True)

    @cached_property
    def _fwd(self) -> Transformer:
        return Transformer.from_crs("EPSG:4326", self.crs, always_xy=True)

    def to_latlon(self, x_m: npt.ArrayLike, y_m: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Grid x, y [m] (any equal shapes) -> WGS84 latitude, longitude [deg] (same shape)."""
        e = np.asarray(x_m, dtype=np.float64) + self.x_origin_m
        n = np.asarray(y_m, dtype=np.float64) + self.y_origin_m
        lon, lat = self._inv.transform(e, n)
        return np.asarray(lat, dtype=np.float64), np.asarray(lon, dtype=np.float64)

    def to_xy(
        self, lat_deg: npt.ArrayLike, lon_deg: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """WGS84 latitude, longitude [deg] -> grid x, y [m] (same shape)."""
        e, n = self._fwd.transform(
            np.asarray(lon_deg, dtype=np.float64), np.asarray(lat_deg, dtype=np.float64)
        )
        return (
            np.asarray(e, dtype=np.float64) - self.x_origin_m,
            np.asarray(n, dtype=np.float64) - self.y_origin_m,
        )

    def yaw_to_bearing(
        self, yaw_rad: npt.ArrayLike, x_m: npt.ArrayLike, y_m: npt.ArrayLike
    ) -> FloatArray:
        """Grid yaw [rad, CCW from grid east] at grid point (x, y) -> true bearing [deg,
        clockwise from true north, in [0, 360)] (shapes broadcast)."""
        yaw, x, y = np.broadcast_arrays(
            np.asarray(yaw_rad, dtype=np.float64),
            np.asarray(x_m, dtype=np.float64),
            np.asarray(y_m, dtype=np.float64),
        )
        lat1, lon1 = self.to_latlon(x, y)
        lat2, lon2 = self.to_latlon(x + _PROBE_M * np.cos(yaw), y + _PROBE_M * np.sin(yaw))
        az, _, _ = _GEOD.inv(lon1, lat1, lon2, lat2)
        return np.mod(np.asarray(az, dtype=np.float64), 360.0)

    def bearing_to_yaw(
        self, bearing_deg: npt.ArrayLike, lat_deg: npt.ArrayLike, lon_deg: npt.ArrayLike
    ) -> FloatArray:
        """True bearing [deg, clockwise from north] at (lat, lon) -> grid yaw [rad, CCW from
        grid east, in (-pi, pi]] (the inverse of :meth:`yaw_to_bearing`)."""
        b, lat, lon = np.broadcast_arrays(
            np.asarray(bearing_deg, dtype=np.float64),
            np.asarray(lat_deg, dtype=np.float64),
            np.asarray(lon_deg, dtype=np.float64),
        )
        lon2, lat2, _ = _GEOD.fwd(lon, lat, b, np.full(b.shape, _PROBE_M))
        x1, y1 = self.to_xy(lat, lon)
        x2, y2 = self.to_xy(np.asarray(lat2), np.asarray(lon2))
        return np.arctan2(y2 - y1, x2 - x1)
