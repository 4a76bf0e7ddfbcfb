"""The default variation's figures, recomputed from a TrafficMonitoring dataset.

- :func:`cruise_speed_spread`: the car's speed spread while moving, per INS drive: the
  coefficient of variation of the speed above 0.5 m/s (the threshold of the recorded
  'median-moving' cruise speed) around that drive's median. The default used the median
  over the drives until issue 31; it now uses the spread *between* encounters
  (vei.calibrate.variation, ``vei calibrate variation``).
- :func:`arrival_offsets`: the signed arrival offsets of every car-rider pair whose paths
  the roadside camera saw cross (closest approach of the two paths within
  ``crossing_m``): rider time at the crossing minus the car's. Their spread over the whole
  recordings, with no peak near 0, is what the uniform arrival-offset default rests on.

A test checks these figures on the shared data.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

#: Speed above which the car counts as moving [m/s] (vei.models.ego.median_moving_speed_mps).
MOVING_MPS = 0.5


@dataclass(frozen=True)
class CruiseSpread:
    """Per-drive speed spread of the INS drives.

    Attributes:
        drives: INS file names. n_samples: moving samples per drive. median_mps: each
            drive's median moving speed. cv: each drive's coefficient of variation.
    """

    drives: tuple[str, ...]
    n_samples: tuple[int, ...]
    median_mps: tuple[float, ...]
    cv: tuple[float, ...]

    @property
    def median_cv(self) -> float:
        """The median over the drives of the per-drive CV (the default's value)."""
        return float(np.median(self.cv))


def cruise_speed_spread(root: str | Path) -> CruiseSpread:
    """The speed spread of every INS drive of a TrafficMonitoring root (module docstring)."""
    from vei.datasets.trafficmonitoring_files import CAR_DATA_DIR, INS_SUFFIX, read_ins

    files = sorted((Path(root) / CAR_DATA_DIR).glob(f"*{INS_SUFFIX}"))
    names, ns, meds, cvs = [], [], [], []
    for f in files:
        v = read_ins(f).speed_mps
        mv = v[v > MOVING_MPS]
        if mv.size < 2:
            continue
        med = float(np.median(mv))
        names.append(f.name)
        ns.append(int(mv.size))
        meds.append(med)
        cvs.append(float(np.std(mv / med)))
    return CruiseSpread(tuple(names), tuple(ns), tuple(meds), tuple(cvs))


@dataclass(frozen=True)
class ArrivalOffsets:
    """Signed arrival offsets at the crossings of car and rider paths.

    Attributes:
        offsets_s: [K] rider time minus car time at the crossing [s].
        n_riders: rider segments considered. n_vehicles: moving vehicles considered.
    """

    offsets_s: FloatArray
    n_riders: int
    n_vehicles: int


def arrival_offsets(root: str | Path, crossing_m: float = 1.5) -> ArrivalOffsets:
    """Signed arrival offsets of every car-rider path crossing seen by the roadside camera
    of a TrafficMonitoring root (module docstring)."""
    from vei.calibrate.tracks import load_scenes

    offsets: list[float] = []
    n_r = n_v = 0
    for scene in load_scenes(root):
        veh = scene.vehicles
        n_v += len(veh.ids)
        for r in scene.riders:
            n_r += 1
            for j in range(len(veh.ids)):
                act = veh.active[:, j]
                if not act.any():
                    continue
                vx, vy = veh.x_m[act, j], veh.y_m[act, j]
                tv = np.flatnonzero(act) * veh.dt_s
                d = np.hypot(r.x_m[:, None] - vx[None, :], r.y_m[:, None] - vy[None, :])
                i, k = np.unravel_index(int(np.argmin(d)), d.shape)
                if d[i, k] <= crossing_m:
                    offsets.append(float(r.t_s[i] - tv[k]))
    return ArrivalOffsets(np.asarray(offsets, dtype=np.float64), n_r, n_v)
