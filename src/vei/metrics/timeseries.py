"""Build a metrics :class:`vei.types.Trace` from a long-format run time series.

Every backend (the built-in engine, CARLA, ...) writes the same long table with
:data:`vei.types.TIMESERIES_COLUMNS` (one row per agent per step); this turns the rows of
the ego and one other road user into the arrays the metrics take, so metrics never depend
on a backend.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from vei.errors import InputError
from vei.types import EGO_ID, Trace

_NEEDED = (
    "config",
    "variant",
    "t_s",
    "agent_id",
    "x_m",
    "y_m",
    "yaw_rad",
    "speed_mps",
    "accel_mps2",
    "active",
    "collided",
)


def trace_from_timeseries(
    frame: pd.DataFrame,
    *,
    other_id: str,
    ego_dims_m: tuple[float, float],
    other_dims_m: tuple[float, float],
    ego_id: str = EGO_ID,
) -> tuple[Trace, list[tuple[str, int]]]:
    """Trace of the ego and ``other_id`` for every run (config, variant) in ``frame``.

    Args:
        frame: long time series (TIMESERIES_COLUMNS); every run on the same time grid.
        other_id: agent_id of the road user to score against (the primary threat).
        ego_dims_m, other_dims_m: (length, width) footprints [m].
        ego_id: agent_id of the ego.
    Returns:
        (trace with B = number of runs, [(config, variant)] in order of first appearance).
        Steps where the other has no row, or ``active`` is False, are inactive (NaN
        position); its velocity vector is speed * (cos yaw, sin yaw).
    """
    missing = [c for c in _NEEDED if c not in frame.columns]
    if missing:
        raise InputError(f"time series lacks column(s) {', '.join(missing)}", field=missing[0])
    runs = list(
        dict.fromkeys(zip(frame["config"].astype(str), frame["variant"].astype(int), strict=True))
    )
    if not runs:
        raise InputError("time series is empty")
    t = np.unique(frame["t_s"].to_numpy(dtype=np.float64))
    n_t, n_b = t.size, len(runs)
    run_index = {r: i for i, r in enumerate(runs)}

    def grid(agent: str) -> dict[str, np.ndarray]:
        rows = frame[frame["agent_id"].astype(str) == agent]
        bi = np.array(
            [
                run_index[(c, int(v))]
                for c, v in zip(rows["config"].astype(str), rows["variant"], strict=True)
            ],
            dtype=int,
        )
        ti = np.searchsorted(t, rows["t_s"].to_numpy(dtype=np.float64))
        present = np.zeros((n_b, n_t), dtype=bool)
        present[bi, ti] = True
        out = {"present": present}
        for col in ("x_m", "y_m", "yaw_rad", "speed_mps", "accel_mps2"):
            arr = np.full((n_b, n_t), np.nan)
            arr[bi, ti] = rows[col].to_numpy(dtype=np.float64)
            out[col] = arr
        for col in ("active", "collided"):
            arr = np.zeros((n_b, n_t), dtype=bool)
            arr[bi, ti] = rows[col].to_numpy(dtype=bool)
            out[col] = arr
        return out

    ego = grid(ego_id)
    if not ego["present"].all():
        b, k = np.argwhere(~ego["present"])[0]
        raise InputError(
            f"time series has no ego row for run {runs[b]} at t = {t[k]:.3f} s", field="agent_id"
        )
    oth = grid(other_id)
    if not oth["present"].any():
        raise InputError(f"time series has no rows of agent {other_id!r}", field="agent_id")
    active = oth["present"] & oth["active"]
    other_xy = np.stack([oth["x_m"], oth["y_m"]], axis=-1)
    other_xy[~active] = np.nan
    yaw, speed, vel = _heading_velocity(oth["yaw_rad"], oth["speed_mps"])
    trace = Trace(
        t_s=t,
        ego_xy_m=np.stack([ego["x_m"], ego["y_m"]], axis=-1),
        ego_yaw_rad=ego["yaw_rad"],
        ego_speed_mps=ego["speed_mps"],
        ego_accel_mps2=np.nan_to_num(ego["accel_mps2"]),
        other_xy_m=other_xy,
        other_yaw_rad=yaw,
        other_speed_mps=speed,
        other_vel_mps=vel,
        other_active=active,
        collided=np.logical_or.accumulate(oth["collided"], axis=1),
        ego_length_m=float(ego_dims_m[0]),
        ego_width_m=float(ego_dims_m[1]),
        other_length_m=float(other_dims_m[0]),
        other_width_m=float(other_dims_m[1]),
    )
    return trace, runs


def _heading_velocity(
    yaw_rad: np.ndarray, speed_mps: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(yaw, speed, [..., 2] velocity = speed * (cos yaw, sin yaw)), NaN yaw/speed -> 0."""
    yaw = np.where(np.isfinite(yaw_rad), yaw_rad, 0.0)
    speed = np.where(np.isfinite(speed_mps), speed_mps, 0.0)
    return yaw, speed, speed[..., None] * np.stack([np.cos(yaw), np.sin(yaw)], axis=-1)


def as_timeseries_trace(trace: Trace) -> Trace:
    """The trace that :func:`trace_from_timeseries` builds from ``trace``'s own time series.

    A long time series carries each agent's pose, speed and yaw, not a velocity vector,
    so a trace read from one (``vei run``, ``vei casestudy``, any backend) scores the
    rider's velocity as speed * (cos yaw, sin yaw). The engine's trace
    (:meth:`vei.sim.result.SimResult.to_trace`) holds the integrator's velocity vector,
    which differs from that on the rider's first simulated step (the recorded speed and
    yaw it starts from) by up to ~0.1 m/s. Scoring the engine's trace through this
    function gives metrics bit-identical to a run scored from its time series -- what a
    sweep does, so that ``vei run`` of a sweep variant reproduces the sweep's table.

    Args:
        trace: B runs (e.g. an engine trace).
    Returns:
        Trace with other_yaw / other_speed NaN -> 0, other_vel = speed * heading, other_xy
        NaN where inactive, and ``collided`` latched; every other field as given.
    """
    active = np.asarray(trace.other_active, dtype=bool)
    yaw, speed, vel = _heading_velocity(
        np.asarray(trace.other_yaw_rad, dtype=np.float64),
        np.asarray(trace.other_speed_mps, dtype=np.float64),
    )
    other_xy = np.array(trace.other_xy_m, dtype=np.float64)
    other_xy[~active] = np.nan
    return replace(
        trace,
        ego_accel_mps2=np.nan_to_num(np.asarray(trace.ego_accel_mps2, dtype=np.float64)),
        other_xy_m=other_xy,
        other_yaw_rad=yaw,
        other_speed_mps=speed,
        other_vel_mps=vel,
        collided=np.logical_or.accumulate(np.asarray(trace.collided, dtype=bool), axis=1),
    )
