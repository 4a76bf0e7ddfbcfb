"""``interp='auto'``: the interpolation chosen per track by its keyframe spacing, and the
check of the riders' reconstructed speeds.

The paper annotates at about 1 FPS and interpolates with a cubic spline through every
keyframe. Through dense keyframes (a 30 Hz camera, inD/SinD at 25 Hz, Argoverse 2 at
10 Hz) an interpolating spline differentiates the position jitter: with 0.25 m of noise
per axis, the speed of a rider at 4 m/s on a curve is off by 0.4 m/s RMS at 1 Hz, 0.8 m/s
at 2 Hz, 1.8 m/s at 5 Hz, 3.8 m/s at 10 Hz and 14 m/s at 30 Hz (10 seeds, 20 s;
``benchmarks.recon_research.dense``), and on the shared recordings annotated at 30 Hz
cubic rider speeds reach 20-100 m/s where their positions move at 1-7 m/s. The
noise-aware smoothing spline (``'smoothing'``, :mod:`vei.recon.interpolate`) stays within
0.14-0.21 m/s at every one of these rates.

Rule (:func:`choose_method`): a track whose median keyframe spacing is at least
:data:`DENSE_SPACING_S` (0.5 s, i.e. 2 Hz or sparser, less 1 ms for frame times that
round) keeps the paper's ``'cubic'``, so the paper's 1 FPS reconstructions are unchanged
bit for bit; a denser track gets ``'smoothing'``. At the threshold cubic's speed error is
0.8 m/s (0.25 m noise), a fifth of a rider's speed, and it doubles with every halving of
the spacing. A track with one keyframe has no spacing and keeps ``'cubic'`` (a single
point either way).

:func:`implausible_speeds` lists every rider whose reconstructed speed exceeds the
plausibility limit (ReconstructionConfig.max_speed_mps, 12 m/s: a fast cyclist), whatever
the method; :func:`vei.recon.pipeline.reconstruct` warns about each
(:class:`ImplausibleSpeedWarning`) and records them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.types import RIDER_CATEGORIES

#: Median keyframe spacing [s] from which a track counts as sparse (keeps 'cubic').
DENSE_SPACING_S = 0.5
#: Tolerance [s] on the spacing: keyframes picked from camera frames at 2 Hz are
#: 0.5 s apart up to the rounding of the frame times.
SPACING_TOL_S = 1e-3
#: Method of sparse tracks (the paper's) and of dense tracks.
SPARSE_METHOD = "cubic"
DENSE_METHOD = "smoothing"


def median_spacing(t_key_s: npt.ArrayLike) -> float | None:
    """Median time between consecutive keyframes [s]; None for fewer than 2 keyframes.

    Args:
        t_key_s: [K] strictly increasing keyframe times [s].
    """
    t = np.asarray(t_key_s, dtype=np.float64).ravel()
    if t.size < 2:
        return None
    return float(np.median(np.diff(t)))


def choose_method(
    t_key_s: npt.ArrayLike, dense_spacing_s: float = DENSE_SPACING_S
) -> tuple[str, float | None]:
    """The ``'auto'`` method of one track: (method, median keyframe spacing [s] or None).

    Args:
        t_key_s: [K] strictly increasing keyframe times [s].
        dense_spacing_s: a median spacing below this (less SPACING_TOL_S) [s] is dense.
    Returns:
        ('smoothing', spacing) for a dense track, else ('cubic', spacing).
    """
    spacing = median_spacing(t_key_s)
    return (DENSE_METHOD if is_dense(spacing, dense_spacing_s) else SPARSE_METHOD), spacing


def is_dense(spacing_s: float | None, dense_spacing_s: float = DENSE_SPACING_S) -> bool:
    """Whether a median keyframe spacing [s] (None: < 2 keyframes) counts as dense."""
    return spacing_s is not None and spacing_s < dense_spacing_s - SPACING_TOL_S


def resolve(
    interp: str, t_key_s: npt.ArrayLike, dense_spacing_s: float = DENSE_SPACING_S
) -> tuple[str, float | None]:
    """The method to fit a track with: ``interp`` itself, or for ``'auto'`` the choice of
    :func:`choose_method`; with the track's median keyframe spacing [s] (None with fewer
    than 2 keyframes)."""
    if interp == "auto":
        return choose_method(t_key_s, dense_spacing_s)
    return interp, median_spacing(t_key_s)


def rule_text(dense_spacing_s: float) -> str:
    """One sentence describing the 'auto' rule (recorded in scenario.json)."""
    return (
        f"per track: '{SPARSE_METHOD}' (the paper's spline) where the median keyframe "
        f"spacing is >= {dense_spacing_s:g} s, '{DENSE_METHOD}' (noise-aware) where it is "
        "denser"
    )


def summary(interp: str, dense_spacing_s: float, tracks: list[dict]) -> dict | None:
    """What 'auto' chose (scenario.json ``extra.reconstruction.auto_interp``); None for
    any other ``interp``.

    Args:
        interp: the configured method.
        dense_spacing_s: the threshold [s].
        tracks: per-track records (agent_id, median_keyframe_spacing_s, method).
    Returns:
        {rule, dense_spacing_s, smoothing: [agent ids of dense tracks], cubic: [agent ids
        of sparse tracks]} (a track with too few keyframes for its method was fitted
        'linear': its record's method says so).
    """
    if interp != "auto":
        return None
    dense = [is_dense(t["median_keyframe_spacing_s"], dense_spacing_s) for t in tracks]
    return {
        "rule": rule_text(dense_spacing_s),
        "dense_spacing_s": float(dense_spacing_s),
        DENSE_METHOD: [t["agent_id"] for t, d in zip(tracks, dense, strict=True) if d],
        SPARSE_METHOD: [t["agent_id"] for t, d in zip(tracks, dense, strict=True) if not d],
    }


class ImplausibleSpeedWarning(UserWarning):
    """A rider's reconstructed speed exceeds the plausibility limit."""


@dataclass(frozen=True)
class SpeedWarning:
    """A rider whose reconstructed speed exceeds the limit.

    Attributes:
        agent_id, category: the rider.
        method: the interpolation that produced it.
        max_speed_mps: its highest reconstructed speed [m/s], reached at t_s [s].
        limit_mps: the plausibility limit [m/s].
        median_spacing_s: median time between its keyframes [s] (None: < 2 keyframes).
    """

    agent_id: str
    category: str
    method: str
    max_speed_mps: float
    t_s: float
    limit_mps: float
    median_spacing_s: float | None

    def message(self) -> str:
        """What happened, and the way out."""
        spacing = (
            f" through keyframes {self.median_spacing_s:.3g} s apart"
            if self.median_spacing_s is not None
            else ""
        )
        if self.method == DENSE_METHOD:
            out = (
                "the smoothing reached its refit limit: raise --noise-m (ReconstructionConfig."
                "noise_m) if the keyframes are noisier, or check the track for a tracker swap"
            )
        else:
            out = (
                "an interpolating spline differentiates the keyframes' position jitter (the "
                "denser the keyframes, the more); reconstruct with --interp auto or --interp "
                "smoothing (ReconstructionConfig(interp=...)), which keep rider speeds plausible"
            )
        return (
            f"{self.agent_id} ({self.category}): reconstructed speed {self.max_speed_mps:.1f} m/s "
            f"at t = {self.t_s:.2f} s exceeds the plausible {self.limit_mps:g} m/s for a rider "
            f"(method {self.method}{spacing}); {out}"
        )

    def as_dict(self) -> dict:
        """Plain dict for scenario.json, with the message."""
        return {
            "agent_id": self.agent_id,
            "category": self.category,
            "method": self.method,
            "max_speed_mps": self.max_speed_mps,
            "t_s": self.t_s,
            "limit_mps": self.limit_mps,
            "median_keyframe_spacing_s": self.median_spacing_s,
            "message": self.message(),
        }


def implausible_speeds(
    trajectories: pd.DataFrame,
    tracks: list[dict],
    limit_mps: float,
    categories: tuple[str, ...] = RIDER_CATEGORIES,
) -> list[SpeedWarning]:
    """Riders whose reconstructed speed exceeds ``limit_mps``.

    Args:
        trajectories: the scenario's trajectories (agent_id, t_s [s], speed_mps [m/s]).
        tracks: per-track records of the reconstruction (agent_id, category, method and
            optionally median_keyframe_spacing_s).
        limit_mps: plausible maximum speed [m/s] of the categories checked.
        categories: the categories checked (riders).
    Returns:
        One SpeedWarning per offending track, in the order of ``tracks``.
    """
    out = []
    for info in tracks:
        if info["category"] not in categories:
            continue
        tr = trajectories[trajectories["agent_id"] == info["agent_id"]]
        if not len(tr):
            continue
        speed = tr["speed_mps"].to_numpy(dtype=np.float64)
        i = int(np.argmax(speed))
        if speed[i] > limit_mps:
            out.append(
                SpeedWarning(
                    agent_id=info["agent_id"],
                    category=info["category"],
                    method=info["method"],
                    max_speed_mps=float(speed[i]),
                    t_s=float(tr["t_s"].iloc[i]),
                    limit_mps=float(limit_mps),
                    median_spacing_s=info.get("median_keyframe_spacing_s"),
                )
            )
    return out
