"""World-frame track datasets, normalised: what the inD family, SinD and Argoverse 2 share.

Each format module (:mod:`vei.datasets.ind`, :mod:`vei.datasets.sind`,
:mod:`vei.datasets.av2`) reads and validates its own files and returns one
:class:`RecordingTracks` per recording: every road user's samples in WGS84 with its true
heading, speed and footprint, its dataset class and the vei category that class maps to.
This module decides which cars become egos (:func:`egos_in_reach`, the *reach* rule) and
builds the world-frame interactions (:mod:`vei.datasets.world_import`).

**Reach** (docs/datasets.md): a car comes within reach of a rider when, while both are
recorded, (a) their centres come within ``gap_m`` (30 m) at the same time, or (b) the
rider's route passes within ``path_m`` (5 m) of the car's route with the two there at most
``pet_s`` (30 s) apart. (a): the paper's TTC = distance / car speed reaches its 2 s
attention threshold at 30 m for a car at 15 m/s (54 km/h, above the urban limit), so every
rider that ever enters a car's TTC attention zone in town is in reach; (b) is the
catalogue's route clause (docs/catalogue.md): riders that a time shift turns into a
conflict. A car whose route is shorter than ``MIN_EGO_PATH_M`` (parked, waiting the whole
recording) is never an ego: its "interaction" would have no driving to simulate.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy.spatial import cKDTree

from vei.errors import ConfigError
from vei.types import RIDER_CATEGORIES

FloatArray = npt.NDArray[np.float64]

#: Columns of :attr:`RecordingTracks.tracks`.
TRACK_COLUMNS: tuple[str, ...] = (
    "t_s",  # s since the recording's t = 0
    "track_id",  # str
    "source_class",  # the dataset's class label
    "category",  # vei category, '' where the class is not imported
    "lat_deg",
    "lon_deg",
    "heading_deg",  # true heading, clockwise from north; NaN unknown
    "speed_mps",  # NaN unknown
    "length_m",  # NaN unknown
    "width_m",
)
#: Reach defaults (see the module docstring).
REACH_GAP_M = 30.0
REACH_PATH_M = 5.0
REACH_PET_S = 30.0
#: A car whose route is shorter than this [m] is never an ego.
MIN_EGO_PATH_M = 10.0
#: Rate [Hz] at which the reach test samples the tracks (enough for 30 m at urban speeds).
REACH_RATE_HZ = 5.0


@dataclass(frozen=True)
class Reach:
    """The reach rule (validated on construction; ConfigError).

    Attributes:
        gap_m: same-time centre distance [m] that puts a rider in reach (> 0).
        path_m: route distance [m] of the route clause (>= 0; 0 disables it).
        pet_s: largest time between car and rider at the routes' closest point [s] (>= 0).
    """

    gap_m: float = REACH_GAP_M
    path_m: float = REACH_PATH_M
    pet_s: float = REACH_PET_S

    def __post_init__(self) -> None:
        for name in ("gap_m", "path_m", "pet_s"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ConfigError(f"reach: {name} must be a finite number, got {v!r}")
            if v < 0 or (name == "gap_m" and v <= 0):
                raise ConfigError(
                    f"reach: {name} must be {'> 0' if name == 'gap_m' else '>= 0'}, got {v!r}"
                )


@dataclass(frozen=True)
class RecordingTracks:
    """One recording of a world-frame dataset, normalised by its format module.

    Attributes:
        dataset: format name ('ind', 'sind', 'av2').
        recording: recording id (used in folder names).
        source: what interaction.json's 'source' says (dataset, recording, files).
        tracks: [N rows] TRACK_COLUMNS, sorted by (track_id, t_s), times strictly
            increasing per track.
        ego_classes: dataset classes a chosen ego may have (cars).
        rate_hz: the dataset's sampling rate [Hz].
        start_time_utc: time of t_s = 0 (a placeholder where the dataset has no date:
            docs/datasets.md).
        notes: provenance text for interaction.json (frames, units, what was converted).
        origin_deg: (lat, lon) of the plane the interactions must use, or None (the
            reconstruction then centres its plane on the data).
        map_writer: None, or f(folder, (lat, lon)) that writes the recording's road map as
            ``map.xodr`` into an interaction folder, in the tmerc plane at that origin.
    """

    dataset: str
    recording: str
    source: str
    tracks: pd.DataFrame = field(repr=False)
    ego_classes: frozenset[str]
    rate_hz: float
    start_time_utc: datetime
    notes: str = ""
    origin_deg: tuple[float, float] | None = None
    map_writer: Callable[[Path, tuple[float, float]], Path] | None = field(default=None, repr=False)

    def track(self, track_id: str) -> pd.DataFrame:
        """The samples of one track (sorted by t_s)."""
        return self.tracks[self.tracks["track_id"] == str(track_id)]

    def class_of(self) -> dict[str, str]:
        """{track_id: dataset class} (the first sample's)."""
        first = self.tracks.drop_duplicates("track_id")
        return dict(zip(first["track_id"], first["source_class"], strict=True))

    def category_of(self) -> dict[str, str]:
        """{track_id: vei category ('' = not imported)}."""
        first = self.tracks.drop_duplicates("track_id")
        return dict(zip(first["track_id"], first["category"], strict=True))


def normalised_table(
    *,
    t_s: npt.ArrayLike,
    track_id: npt.ArrayLike,
    source_class: npt.ArrayLike,
    class_to_category: dict[str, str | None],
    lat_deg: npt.ArrayLike,
    lon_deg: npt.ArrayLike,
    heading_deg: npt.ArrayLike,
    speed_mps: npt.ArrayLike,
    length_m: npt.ArrayLike,
    width_m: npt.ArrayLike,
) -> pd.DataFrame:
    """Assemble a TRACK_COLUMNS table from per-sample arrays [N] (sizes <= 0 -> NaN = unknown,
    as the inD family writes 0 for road users without a box); sorted by (track_id, t_s)."""
    cls = np.asarray(source_class, dtype=object).astype(str)
    cat = np.array([class_to_category.get(c) or "" for c in cls], dtype=object)
    sizes = {}
    for name, v in (("length_m", length_m), ("width_m", width_m)):
        a = np.asarray(v, dtype=np.float64).copy()
        a[~(a > 0)] = np.nan
        sizes[name] = a
    df = pd.DataFrame(
        {
            "t_s": np.asarray(t_s, dtype=np.float64),
            "track_id": np.asarray(track_id, dtype=object).astype(str),
            "source_class": cls,
            "category": cat,
            "lat_deg": np.asarray(lat_deg, dtype=np.float64),
            "lon_deg": np.asarray(lon_deg, dtype=np.float64),
            "heading_deg": np.asarray(heading_deg, dtype=np.float64),
            "speed_mps": np.asarray(speed_mps, dtype=np.float64),
            **sizes,
        }
    )
    return df.sort_values(["track_id", "t_s"], kind="stable").reset_index(drop=True)


# ----------------------------------------------------------------------------- reach


@dataclass(frozen=True)
class EgoChoice:
    """A car within reach of riders.

    Attributes:
        ego_id: the car's track id.
        riders: track ids of the riders in reach, sorted.
        min_gap_m: smallest same-time centre distance to any rider [m] (inf if none coexists).
        path_m: route length of the car [m].
    """

    ego_id: str
    riders: tuple[str, ...]
    min_gap_m: float
    path_m: float


def _resampled(tr: pd.DataFrame, step_s: float) -> tuple[FloatArray, FloatArray]:
    """(t [K], plane xy [K, 2]) of a track thinned to about one sample per step_s."""
    t = tr["t_s"].to_numpy(dtype=np.float64)
    xy = tr[["x_m", "y_m"]].to_numpy(dtype=np.float64)
    if t.size < 2:
        return t, xy
    keep = np.unique(np.searchsorted(t, np.arange(t[0], t[-1] + 1e-9, step_s)).clip(0, t.size - 1))
    keep = np.union1d(keep, [t.size - 1])
    return t[keep], xy[keep]


def _route_length(xy: FloatArray) -> float:
    return float(np.sum(np.hypot(*np.diff(xy, axis=0).T))) if len(xy) > 1 else 0.0


def egos_in_reach(rec: RecordingTracks, reach: Reach | None = None) -> list[EgoChoice]:
    """The cars of ``rec`` (class in ego_classes, route >= MIN_EGO_PATH_M) that come within
    reach of at least one rider (category in RIDER_CATEGORIES), sorted by track id
    (numerically where the ids are numbers). See the module docstring for the rule."""
    from vei.geo.frame import LocalFrame

    rule = reach or Reach()
    tr = rec.tracks
    if tr.empty:
        return []
    plane = LocalFrame(float(tr["lat_deg"].median()), float(tr["lon_deg"].median()))
    x, y = plane.to_xy(tr["lat_deg"].to_numpy(), tr["lon_deg"].to_numpy())
    tr = tr.assign(x_m=x, y_m=y)
    step = 1.0 / REACH_RATE_HZ
    riders = {
        tid: _resampled(g, step)
        for tid, g in tr[tr["category"].isin(RIDER_CATEGORIES)].groupby("track_id", sort=True)
    }
    cars = tr[tr["source_class"].isin(rec.ego_classes)]
    out = []
    for tid, g in cars.groupby("track_id", sort=False):
        t_car, xy_car = _resampled(g, step)
        path = _route_length(g[["x_m", "y_m"]].to_numpy(dtype=np.float64))
        if path < MIN_EGO_PATH_M or t_car.size < 2:
            continue
        tree = cKDTree(xy_car)
        found, best = [], math.inf
        for rid, (t_r, xy_r) in riders.items():
            inside = (t_r >= t_car[0]) & (t_r <= t_car[-1])
            if inside.sum() < 1:
                continue
            # (a) same-time distance, the car interpolated at the rider's samples
            tt = t_r[inside]
            cx = np.interp(tt, t_car, xy_car[:, 0])
            cy = np.interp(tt, t_car, xy_car[:, 1])
            gap = float(np.min(np.hypot(xy_r[inside, 0] - cx, xy_r[inside, 1] - cy)))
            best = min(best, gap)
            hit = gap <= rule.gap_m
            if not hit and rule.path_m > 0:
                # (b) routes within path_m, there within pet_s of each other
                for i, near in enumerate(tree.query_ball_point(xy_r, rule.path_m)):
                    if near and np.min(np.abs(t_car[near] - t_r[i])) <= rule.pet_s:
                        hit = True
                        break
            if hit:
                found.append(rid)
        if found:
            out.append(EgoChoice(str(tid), tuple(sorted(found, key=_id_key)), best, path))
    return sorted(out, key=lambda e: _id_key(e.ego_id))


def _id_key(track_id: str) -> tuple[int, float, str]:
    """Sort key: numeric ids by value, then the rest by text."""
    try:
        return (0, float(track_id), "")
    except ValueError:
        return (1, 0.0, track_id)
