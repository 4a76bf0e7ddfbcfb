"""World-frame interactions from a normalised recording: any car as the ego.

:func:`build_interaction` turns one car of a :class:`~vei.datasets.world_tracks.RecordingTracks`
into an interaction (format ``vei.interaction/1`` with ``frame = world``): the car's own
track as ``ego.csv`` (its centre, true heading and speed at the dataset's rate; t_s = 0 at
its first sample) and every rider (and with ``road_users='all'`` every other road user)
recorded while the car is as world-frame annotations: latitude / longitude / true heading
as the dataset gives them, never turned into ego-relative offsets. :func:`import_tracks`
writes one folder per chosen ego (``--ego all``: every car within reach of a rider).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from datetime import timedelta
from pathlib import Path

import numpy as np
import pandas as pd

from vei.datasets.world_tracks import (
    EgoChoice,
    Reach,
    RecordingTracks,
    egos_in_reach,
)
from vei.errors import InputError, NoRidersError
from vei.types import CATEGORIES, RIDER_CATEGORIES, Interaction, InteractionMeta

#: ``road_users`` choices: riders only (the default), or every mapped road user.
ROAD_USERS: tuple[str, ...] = ("riders", "all")
#: Gaps [s] in the ego's track longer than this split it (the tracker lost the car); the
#: ego is its longest stretch without one (a spline through a long gap is no car's path).
EGO_MAX_GAP_S = 1.0
#: An annotation at rate r uses the sample nearest to k / r if it lies this close [s]
#: (as vei import trafficmonitoring does).
ANNOTATION_MAX_GAP_S = 0.1


@dataclass(frozen=True)
class ImportedInteraction:
    """One interaction written by :func:`import_tracks`.

    Attributes:
        folder: the interaction folder.
        ego_id: the car's track id.
        riders: {category: number of annotated rider tracks}.
        annotated_tracks: number of annotated tracks (all categories).
        duration_s: the ego's span [s].
        min_gap_m: smallest same-time distance car-rider [m] (inf when none coexist).
    """

    folder: Path
    ego_id: str
    riders: dict[str, int]
    annotated_tracks: int
    duration_s: float
    min_gap_m: float


def _sample(track: pd.DataFrame, rate_hz: float | None, t0: float, t1: float) -> pd.DataFrame:
    """Samples of a track inside [t0, t1]; with a rate, those nearest to t0 + k / rate (within
    min(ANNOTATION_MAX_GAP_S, half a period); each sample's own time is kept)."""
    tr = track[(track["t_s"] >= t0 - 1e-9) & (track["t_s"] <= t1 + 1e-9)]
    if rate_hz is None or tr.empty:
        return tr
    tt = tr["t_s"].to_numpy()
    k0 = math.ceil((tt[0] - t0) * rate_hz - 1e-9)
    k1 = math.floor((tt[-1] - t0) * rate_hz + 1e-9)
    grid = t0 + np.arange(k0, k1 + 1) / rate_hz
    if grid.size == 0:
        return tr.iloc[:0]
    idx = (
        np.clip(np.searchsorted(tt, grid), 1, max(len(tt) - 1, 1))
        if len(tt) > 1
        else np.zeros(grid.size, int)
    )
    if len(tt) > 1:
        idx = np.where(np.abs(tt[idx - 1] - grid) <= np.abs(tt[idx] - grid), idx - 1, idx)
    tol = min(ANNOTATION_MAX_GAP_S, 0.5 / rate_hz)
    ok = np.abs(tt[idx] - grid) <= tol + 1e-9
    return tr.iloc[np.unique(idx[ok])]


def _longest_stretch(track: pd.DataFrame) -> pd.DataFrame:
    """The longest run of samples without a gap over EGO_MAX_GAP_S (ties: the first)."""
    t = track["t_s"].to_numpy()
    if len(t) < 2:
        return track
    cuts = np.flatnonzero(np.diff(t) > EGO_MAX_GAP_S) + 1
    parts = np.split(np.arange(len(t)), cuts)
    best = max(parts, key=lambda p: (t[p[-1]] - t[p[0]], -p[0]))
    return track.iloc[best]


def build_interaction(
    rec: RecordingTracks,
    ego_id: str,
    *,
    road_users: str = "riders",
    rate_hz: float | None = None,
) -> Interaction:
    """The world-frame interaction of ``rec`` with car ``ego_id`` as the ego.

    Args:
        rec: a normalised recording.
        ego_id: track id of the ego (any track of a class in ``rec.ego_classes``).
        road_users: 'riders' (e-scooters and cyclists: the classes mapped to them) or
            'all' (also vehicles and pedestrians).
            The ego is the car's longest stretch without a gap over EGO_MAX_GAP_S.
        rate_hz: annotation rate [Hz] (> 0, at most the dataset's); None = every sample.
            With a rate, ground_truth.csv holds the annotated tracks at the full rate.
    Returns:
        Interaction with meta.frame 'world'; ego [M rows] t_s (0 at the car's first
        sample), lat_deg, lon_deg, heading_deg, speed_mps; annotations t_s, track_id,
        category, lat_deg, lon_deg, heading_deg, length_m, width_m.
    Raises:
        InputError: unknown ego, not a car, a bad option; NoRidersError: no rider is
        recorded while the car is.
    """
    if road_users not in ROAD_USERS:
        raise InputError(
            f"road_users must be one of {', '.join(ROAD_USERS)}, got {road_users!r}",
            field="road_users",
        )
    if rate_hz is not None and not (
        isinstance(rate_hz, int | float)
        and math.isfinite(rate_hz)
        and 0 < rate_hz <= rec.rate_hz + 1e-9
    ):
        raise InputError(
            f"rate_hz must be in (0, {rec.rate_hz:g}] Hz (the dataset's rate), got {rate_hz!r}",
            field="rate_hz",
        )
    ego_id = str(ego_id)
    classes = rec.class_of()
    if ego_id not in classes:
        raise InputError(f"no track {ego_id!r} in recording {rec.recording}", field="--ego")
    if classes[ego_id] not in rec.ego_classes:
        raise InputError(
            f"track {ego_id} is a {classes[ego_id]!r}, not a car (ego classes: "
            f"{', '.join(sorted(rec.ego_classes))})",
            field="--ego",
        )
    ego = _longest_stretch(rec.track(ego_id))
    if len(ego) < 2:
        raise InputError(f"track {ego_id} has {len(ego)} sample(s); an ego needs 2", field="--ego")
    t0, t1 = float(ego["t_s"].iloc[0]), float(ego["t_s"].iloc[-1])
    kept = RIDER_CATEGORIES if road_users == "riders" else CATEGORIES
    others = rec.tracks[(rec.tracks["track_id"] != ego_id) & rec.tracks["category"].isin(kept)]
    ann_parts, gt_parts = [], []
    for _tid, track in others.groupby("track_id", sort=False):
        samples = _sample(track, rate_hz, t0, t1)
        if samples.empty:
            continue
        ann_parts.append(samples)
        if rate_hz is not None:
            gt_parts.append(track)
    ann = pd.concat(ann_parts, ignore_index=True) if ann_parts else others.iloc[:0]
    if not ann["category"].isin(RIDER_CATEGORIES).any():
        raise NoRidersError(
            f"no e-scooter or cyclist is recorded while car {ego_id} is "
            f"([{t0:.2f}, {t1:.2f}] s of recording {rec.recording})"
        )
    shift = lambda df: df.assign(t_s=np.round(df["t_s"].to_numpy() - t0, 9))  # noqa: E731
    ego_tab = shift(ego)[["t_s", "lat_deg", "lon_deg", "heading_deg", "speed_mps"]]
    annotations = shift(ann)[
        ["t_s", "track_id", "category", "lat_deg", "lon_deg", "heading_deg", "length_m", "width_m"]
    ]
    gt = None
    if gt_parts:
        gt = shift(pd.concat(gt_parts, ignore_index=True))[
            ["t_s", "track_id", "category", "lat_deg", "lon_deg"]
        ]
    by_class = ann.drop_duplicates("track_id").groupby(["source_class", "category"]).size()
    mapping = ", ".join(f"{n} {c} -> {k}" for (c, k), n in by_class.items())
    notes = (
        f"{rec.notes} World frame: annotations are each road user's own latitude/longitude and "
        f"true heading (no ego-relative offsets); the ego is car track {ego_id} "
        f"({classes[ego_id]}), its box centre"
        + (", its longest stretch without a gap over 1 s" if len(ego) < len(rec.track(ego_id)) else "")
        + f", t_s = 0 at its first sample (recording time {t0:.3f} s). "
        f"Annotated tracks by dataset class: {mapping}. "
        + (f"Annotations at {rate_hz:g} Hz, ground truth at {rec.rate_hz:g} Hz." if rate_hz
           else f"Annotations at the dataset's {rec.rate_hz:g} Hz.")
    )  # fmt: skip
    origin = rec.origin_deg
    meta = InteractionMeta(
        id=f"{rec.recording}__ego{ego_id}",
        source=rec.source,
        start_time_utc=rec.start_time_utc + timedelta(seconds=t0),
        y_axis="left",
        annotation_rate_hz=float(rate_hz) if rate_hz else float(rec.rate_hz),
        notes=notes.strip(),
        frame="world",
        origin_lat_deg=None if origin is None else float(origin[0]),
        origin_lon_deg=None if origin is None else float(origin[1]),
    )
    return Interaction(meta=meta, ego=ego_tab.reset_index(drop=True), annotations=annotations,
                       ground_truth=gt)  # fmt: skip


def import_tracks(
    rec: RecordingTracks,
    out: str | Path,
    *,
    ego: str = "all",
    road_users: str = "riders",
    rate_hz: float | None = None,
    reach: Reach | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[ImportedInteraction]:
    """Write the interactions of one recording under ``out`` (one folder per ego,
    ``<recording>__ego<id>``, replaced if it exists); returns what was written.

    Args:
        ego: 'all' (every car within reach of a rider: :func:`egos_in_reach`) or one
            track id (any car; refused with NoRidersError when no rider is recorded with it).
        road_users, rate_hz: see :func:`build_interaction`.
        reach: the reach rule for ``ego='all'``.
    """
    from vei.io.interaction import write_interaction

    out = Path(out)
    if ego == "all":
        choices = egos_in_reach(rec, reach)
    else:
        choices = [EgoChoice(str(ego), (), math.inf, math.nan)]
    written = []
    for choice in choices:
        inter = build_interaction(rec, choice.ego_id, road_users=road_users, rate_hz=rate_hz)
        folder = out / inter.meta.id
        write_interaction(inter, folder)
        if rec.map_writer is not None and rec.origin_deg is not None:
            rec.map_writer(folder, rec.origin_deg)
        ann = inter.annotations
        riders = ann[ann["category"].isin(RIDER_CATEGORIES)]
        counts = riders.drop_duplicates("track_id")["category"].value_counts().to_dict()
        written.append(
            ImportedInteraction(
                folder=folder,
                ego_id=choice.ego_id,
                riders={c: int(counts.get(c, 0)) for c in RIDER_CATEGORIES},
                annotated_tracks=int(ann["track_id"].nunique()),
                duration_s=float(inter.ego["t_s"].iloc[-1]),
                min_gap_m=choice.min_gap_m,
            )
        )
        if progress is not None:
            progress(f"wrote {folder}")
    return written
