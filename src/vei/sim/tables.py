"""Recorded tracks as uniform time tables (engine inputs)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.errors import InputError
from vei.models.ego import uniform_grid_index

FloatArray = npt.NDArray[np.float64]


# --------------------------------------------------------------------------------------
# Uniform time tables
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TimeTable:
    """A recorded track resampled on a uniform time grid ``t0_s + i * dt_s``.

    Attributes:
        t0_s: time of the first sample [s] (recording time, before any shift).
        dt_s: sample spacing [s].
        data: [M, C] samples, columns named by ``columns``.
        columns: column names.
    """

    t0_s: float
    dt_s: float
    data: FloatArray
    columns: tuple[str, ...]

    def __post_init__(self) -> None:
        d = np.asarray(self.data, dtype=np.float64)
        slope = np.zeros_like(d)
        if d.shape[0] > 1:
            slope[:-1] = np.diff(d, axis=0)
        object.__setattr__(
            self, "_cols", {c: np.ascontiguousarray(d[:, j]) for j, c in enumerate(self.columns)}
        )
        object.__setattr__(
            self,
            "_slopes",
            {c: np.ascontiguousarray(slope[:, j]) for j, c in enumerate(self.columns)},
        )

    def index(self, t_s: npt.ArrayLike) -> tuple[npt.NDArray[np.intp], FloatArray]:
        """Sample index and weight of times t (clamped): t lies between samples i and i + 1."""
        return uniform_grid_index(t_s, self.t0_s, self.dt_s, self.data.shape[0])

    def values_at(self, i: npt.NDArray[np.intp], w: FloatArray, *names: str) -> list[FloatArray]:
        """Linearly interpolated named columns at (i, w) from :meth:`index`."""
        cols = self._cols  # type: ignore[attr-defined]
        slopes = self._slopes  # type: ignore[attr-defined]
        return [cols[n][i] + w * slopes[n][i] for n in names]

    @property
    def t_end_s(self) -> float:
        """Time of the last sample [s]."""
        return self.t0_s + (self.data.shape[0] - 1) * self.dt_s

    def col(self, name: str) -> int:
        """Index of a column."""
        return self.columns.index(name)

    def lookup(self, t_s: npt.ArrayLike) -> FloatArray:
        """Linear interpolation at times t (clamped to the first / last sample).

        Args:
            t_s: [B] recording times [s].
        Returns:
            [B, C] interpolated samples.
        """
        i, w = self.index(t_s)
        return np.stack(self.values_at(i, w, *self.columns), axis=-1)


def recorded_column(table: TimeTable, name: str, span_s: tuple[float, float]) -> FloatArray:
    """[M'] a column of a track's table over the samples inside ``span_s`` (recording
    time [s]): the recorded ones of a continued track (vei.continuation)."""
    col = table.data[:, table.col(name)]
    t = table.t0_s + np.arange(col.size) * table.dt_s
    return col[(t >= span_s[0] - 1e-6) & (t <= span_s[1] + 1e-6)]


def _uniform_track(df: Any, cols: Sequence[str], where: str) -> tuple[float, float, FloatArray]:
    t = df["t_s"].to_numpy(dtype=np.float64)
    if t.size == 0:
        raise InputError("track has no samples", path=where)
    if np.any(np.diff(t) <= 0):
        raise InputError("track times must be strictly increasing", path=where, field="t_s")
    vals = np.stack([df[c].to_numpy(dtype=np.float64) for c in cols], axis=1)
    if t.size == 1:
        return float(t[0]), 1.0, vals
    dt = float(np.median(np.diff(t)))
    n = int(round((t[-1] - t[0]) / dt)) + 1
    grid = t[0] + np.arange(n) * dt
    if n == t.size and np.allclose(grid, t, atol=1e-6):
        return float(t[0]), dt, vals
    out = np.stack([np.interp(grid, t, vals[:, j]) for j in range(vals.shape[1])], axis=1)
    return float(t[0]), dt, out
