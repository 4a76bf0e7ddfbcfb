"""Sampled reconstructions: plausible trajectories of a rider drawn from the posterior.

The posterior is that of :mod:`vei.recon.smoother` (constant-velocity motion model, RTS
smoother over the rider's keyframes) with the scenario's own noise estimate
(``extra['reconstruction']['noise']`` when it was reconstructed with ``interp='kalman'``,
else estimated here the same way, by maximum likelihood over all the scenario's keyframes).
Samples are drawn jointly over the rider's whole time grid by forward filtering, backward
sampling, so each one is a continuous path with continuous velocity that passes as close
to the keyframes as the noise allows, and their spread is the 95 % band of the figure
(:mod:`vei.report.uncertainty`). Same scenario + seed -> the same samples (bit for bit).

:func:`scenario_with_sample` puts one sample in place of the rider's trajectory, which is
how a sweep varies over ``reconstruction: {samples: N}``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.errors import InputError
from vei.recon.smoother import NoiseEstimate, estimate_noise, sample_tracks
from vei.types import Scenario

FloatArray = npt.NDArray[np.float64]

#: Below this sampled speed [m/s] the sample keeps the reconstruction's yaw.
YAW_MIN_SPEED_MPS = 0.5


@dataclass(frozen=True)
class RiderSamples:
    """N posterior samples of one rider's trajectory on its scenario time grid.

    Attributes:
        agent_id: the rider. seed: the seed they were drawn with. noise: the noise model.
        t_s: [T] times [s] (the rider's rows of the scenario's trajectories).
        xy_m: [N, T, 2] positions [m]; vel_mps: [N, T, 2] velocities [m/s].
        yaw_rad: [N, T] yaw (direction of the sampled velocity; the reconstruction's yaw
            where the sample moves slower than YAW_MIN_SPEED_MPS).
    """

    agent_id: str
    seed: int
    noise: NoiseEstimate
    t_s: FloatArray
    xy_m: FloatArray
    vel_mps: FloatArray
    yaw_rad: FloatArray

    @property
    def n_samples(self) -> int:
        """N."""
        return int(self.xy_m.shape[0])


def scenario_noise(scenario: Scenario) -> NoiseEstimate:
    """The rider noise model of a scenario: its stored 'kalman' estimate, else ML over its
    keyframes (what the reconstruction would have estimated)."""
    stored = scenario.extra.get("reconstruction", {}).get("noise")
    if stored:
        return NoiseEstimate(
            noise_m=float(stored["noise_m"]),
            accel_psd_m2ps3=float(stored["accel_psd_m2ps3"]),
            method=str(stored.get("method", "ml")),
            loglik=float(stored["loglik"]) if stored.get("loglik") is not None else float("nan"),
            n_tracks=int(stored.get("n_tracks", 0)),
            n_keyframes=int(stored.get("n_keyframes", 0)),
            # Scenarios written before the calibration hold the pure model (factor 1).
            std_inflation=float(stored.get("std_inflation") or 1.0),
        )
    kf = scenario.keyframes
    if kf is None or kf.empty:
        raise InputError(
            "the scenario has no keyframes: sampled reconstructions need them",
            path=str(scenario.root or scenario.id),
            field="keyframes",
        )
    tracks = [
        (g["t_s"].to_numpy(np.float64), g[["x_m", "y_m"]].to_numpy(np.float64))
        for _, g in kf.groupby("agent_id", sort=True)
    ]
    return estimate_noise(tracks)


def sample_rider(
    scenario: Scenario, n_samples: int, seed: int, agent_id: str | None = None
) -> RiderSamples:
    """Draw posterior samples of a rider's trajectory.

    Args:
        scenario: a reconstructed scenario with keyframes.
        n_samples: N >= 1.
        seed: >= 0; the samples are a deterministic function of (scenario, N, seed).
        agent_id: the rider (default: the primary threat).
    Returns:
        RiderSamples on the rider's scenario time grid.
    Raises:
        InputError: no such rider, no keyframes, or fewer than 2 keyframes (nothing to
        sample between).
    """
    where = str(scenario.root or scenario.id)
    if isinstance(n_samples, bool) or not isinstance(n_samples, int) or n_samples < 1:
        raise InputError(f"n_samples must be an integer >= 1, got {n_samples!r}", path=where)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InputError(f"seed must be an integer >= 0, got {seed!r}", path=where)
    aid = agent_id or scenario.primary_threat
    if aid is None:
        raise InputError("the scenario has no primary threat to sample", path=where)
    kf = scenario.keyframes
    rows = kf[kf["agent_id"] == aid] if kf is not None else pd.DataFrame()
    if len(rows) < 2:
        raise InputError(
            f"rider {aid!r} has {len(rows)} keyframe(s); sampling needs >= 2",
            path=where,
            field="keyframes",
        )
    rows = rows.sort_values("t_s")
    track = scenario.track(aid)
    t = track["t_s"].to_numpy(np.float64)
    tk = rows["t_s"].to_numpy(np.float64)
    t_in = np.clip(t, tk[0], tk[-1])
    noise = scenario_noise(scenario)
    xy, vel = sample_tracks(
        tk,
        rows[["x_m", "y_m"]].to_numpy(np.float64),
        t_in,
        noise.noise_m,
        noise.accel_psd_m2ps3,
        n_samples,
        seed,
        noise.std_inflation,
    )
    speed = np.hypot(vel[..., 0], vel[..., 1])
    base_yaw = track["yaw_rad"].to_numpy(np.float64)
    yaw = np.where(
        speed >= YAW_MIN_SPEED_MPS, np.arctan2(vel[..., 1], vel[..., 0]), base_yaw[None, :]
    )
    return RiderSamples(aid, seed, noise, t, xy, vel, yaw)


def scenario_with_sample(scenario: Scenario, samples: RiderSamples, k: int) -> Scenario:
    """The scenario with sample ``k`` in place of the rider's trajectory (positions, yaw,
    speed); everything else (other agents, keyframes, map, metadata) unchanged, and
    ``extra['reconstruction_sample'] = {agent_id, index, seed, n_samples}``."""
    if not 0 <= k < samples.n_samples:
        raise IndexError(f"sample {k} of {samples.n_samples}")
    traj = scenario.trajectories
    sel = (traj["agent_id"] == samples.agent_id).to_numpy()
    rows = traj.loc[sel].sort_values("t_s")
    if not np.array_equal(rows["t_s"].to_numpy(np.float64), samples.t_s):
        raise ValueError("the samples were drawn for another time grid of this rider")
    new = traj.copy()
    idx = rows.index
    new.loc[idx, "x_m"] = samples.xy_m[k, :, 0]
    new.loc[idx, "y_m"] = samples.xy_m[k, :, 1]
    new.loc[idx, "yaw_rad"] = samples.yaw_rad[k]
    new.loc[idx, "speed_mps"] = np.hypot(samples.vel_mps[k, :, 0], samples.vel_mps[k, :, 1])
    extra = dict(scenario.extra)
    extra["reconstruction_sample"] = {
        "agent_id": samples.agent_id,
        "index": int(k),
        "seed": int(samples.seed),
        "n_samples": samples.n_samples,
    }
    return dataclasses.replace(scenario, trajectories=new, extra=extra)


@dataclass(frozen=True)
class RiderBand:
    """Posterior mean and spread of a rider's position on its scenario time grid.

    Attributes:
        agent_id: the rider. t_s: [T] times [s]. xy_m: [T, 2] posterior mean [m].
        std_m: [T] posterior standard deviation per axis [m] (isotropic).
        noise: the noise model used.
    """

    agent_id: str
    t_s: FloatArray
    xy_m: FloatArray
    std_m: FloatArray
    noise: NoiseEstimate


def rider_band(scenario: Scenario, agent_id: str | None = None) -> RiderBand:
    """The posterior (mean, std) of a rider at its scenario times, from its keyframes and
    the scenario's noise model (:func:`scenario_noise`).

    Raises:
        InputError: no such rider or fewer than 2 keyframes.
    """
    from vei.recon.smoother import posterior

    where = str(scenario.root or scenario.id)
    aid = agent_id or scenario.primary_threat
    kf = scenario.keyframes
    rows = kf[kf["agent_id"] == aid].sort_values("t_s") if kf is not None and aid else None
    if rows is None or len(rows) < 2:
        raise InputError(f"rider {aid!r} needs >= 2 keyframes for an uncertainty band", path=where)
    noise = scenario_noise(scenario)
    t = scenario.track(aid)["t_s"].to_numpy(np.float64)
    tk = rows["t_s"].to_numpy(np.float64)
    post = posterior(
        [(tk, rows[["x_m", "y_m"]].to_numpy(np.float64))],
        [np.clip(t, tk[0], tk[-1])],
        noise.noise_m,
        noise.accel_psd_m2ps3,
        noise.std_inflation,
    )[0]
    return RiderBand(aid, t, post.xy_m, post.std_m, noise)
