"""Time synchronisation of GPS and annotations; active road users per simulation frame.

Both the ego's GPS fixes and the annotations carry ``t_s``, seconds since the
interaction's ``start_time_utc`` (paper Section III-B, step 4). Synchronising means: every
annotation must lie inside the GPS span (the ego pose is interpolated there, never
extrapolated), each annotation is paired with the GPS fixes around it, and each simulation
frame k / rate_hz knows which tracked road users are present (between their first and last
keyframe).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.errors import InputError
from vei.types import Interaction

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class SyncReport:
    """Summary of the time synchronisation.

    Attributes:
        gps_rate_hz: median GPS fix rate [Hz].
        annotation_rate_hz: median rate of annotations within a track [Hz] (NaN if no
            track has two annotations).
        max_gap_to_gps_fix_s: largest time from an annotation to its nearest GPS fix [s].
        t_start_s, t_end_s: span of the GPS track [s].
    """

    gps_rate_hz: float
    annotation_rate_hz: float
    max_gap_to_gps_fix_s: float
    t_start_s: float
    t_end_s: float

    def as_dict(self) -> dict[str, float | None]:
        """JSON-ready dict (NaN -> None)."""
        d = {
            "gps_rate_hz": self.gps_rate_hz,
            "annotation_rate_hz": self.annotation_rate_hz,
            "max_gap_to_gps_fix_s": self.max_gap_to_gps_fix_s,
            "t_start_s": self.t_start_s,
            "t_end_s": self.t_end_s,
        }
        return {k: (None if not np.isfinite(v) else float(v)) for k, v in d.items()}


def synchronise(interaction: Interaction, tolerance_s: float = 1e-6) -> SyncReport:
    """Check that annotations fall inside the GPS span and summarise the two clocks.

    Args:
        interaction: ego (t_s [M]) and annotations (t_s, track_id).
        tolerance_s: annotations up to this far outside the GPS span are accepted [s].
    Returns:
        SyncReport.
    Raises:
        InputError: naming annotations.csv, the (1-based) row and field t_s, for an
            annotation outside the GPS span, or for an empty ego track.
    """
    ego_t = interaction.ego["t_s"].to_numpy(dtype=np.float64)
    root = interaction.root
    if ego_t.size < 2:
        raise InputError(
            "need at least 2 GPS fixes", path=None if root is None else root / "ego.csv"
        )
    ann = interaction.annotations
    ann_t = ann["t_s"].to_numpy(dtype=np.float64)
    bad = np.flatnonzero((ann_t < ego_t[0] - tolerance_s) | (ann_t > ego_t[-1] + tolerance_s))
    if bad.size:
        i = int(bad[0])
        raise InputError(
            f"annotation at t_s={ann_t[i]:.3f} s (track {ann['track_id'].iloc[i]}) is outside the "
            f"GPS span [{ego_t[0]:.3f}, {ego_t[-1]:.3f}] s",
            path=None if root is None else root / "annotations.csv",
            row=i + 1,
            field="t_s",
        )
    if ann_t.size:
        pos = np.clip(np.searchsorted(ego_t, ann_t), 1, ego_t.size - 1)
        gap = np.minimum(np.abs(ann_t - ego_t[pos - 1]), np.abs(ego_t[pos] - ann_t))
        max_gap = float(gap.max())
    else:
        max_gap = float("nan")
    dts = []
    for _, grp in ann.groupby("track_id", sort=False):
        tt = np.sort(grp["t_s"].to_numpy(dtype=np.float64))
        dts.append(np.diff(tt))
    all_dt = np.concatenate(dts) if dts else np.zeros(0)
    ann_rate = float(1.0 / np.median(all_dt)) if all_dt.size else float("nan")
    return SyncReport(
        gps_rate_hz=float(1.0 / np.median(np.diff(ego_t))),
        annotation_rate_hz=ann_rate,
        max_gap_to_gps_fix_s=max_gap,
        t_start_s=float(ego_t[0]),
        t_end_s=float(ego_t[-1]),
    )


def active_matrix(
    t_grid_s: npt.ArrayLike, t_start_s: npt.ArrayLike, t_end_s: npt.ArrayLike, tol_s: float = 1e-6
) -> npt.NDArray[np.bool_]:
    """Which agents are present at each frame.

    Args:
        t_grid_s: [T] frame times [s].
        t_start_s, t_end_s: [N] first / last keyframe time of each agent [s].
    Returns:
        [T, N] bool, True where t_start - tol <= t <= t_end + tol.
    """
    t = np.asarray(t_grid_s, dtype=np.float64)[:, None]
    a = np.asarray(t_start_s, dtype=np.float64)[None, :]
    b = np.asarray(t_end_s, dtype=np.float64)[None, :]
    return (t >= a - tol_s) & (t <= b + tol_s)


def active_per_frame(trajectories: pd.DataFrame, categories: tuple[str, ...]) -> pd.DataFrame:
    """Number of agents of the given categories present at each frame of a scenario.

    Args:
        trajectories: scenario trajectories (columns t_s, agent_id, category).
        categories: categories to count (e.g. RIDER_CATEGORIES).
    Returns:
        DataFrame with columns t_s, n_active (int), one row per distinct t_s of the
        trajectories, sorted.
    """
    t_all = trajectories["t_s"].to_numpy(dtype=np.float64)
    frames, inverse = np.unique(np.round(t_all, 9), return_inverse=True)
    sel = trajectories["category"].isin(categories).to_numpy()
    counts = np.bincount(inverse[sel], minlength=frames.size)
    return pd.DataFrame({"t_s": frames, "n_active": counts.astype(np.int64)})
