"""The radio channel between a rider's device and the car: delivery, blockage, latency.

- **Delivery**: a VAM reaches the car with probability ``pdr_factor * PDR(d_eff)``: PDR the
  configured table (delivery ratio against the rider-car distance, linear in between,
  held beyond its ends), d the distance between the rider's and the car's box centres when
  the VAM is sent, and d_eff = d when the direct line is clear.
- **Blockage** (non-line-of-sight, NLOSv): when the straight segment between the two
  centres crosses the box of a vehicle (not the car itself; a box holding either end is
  ignored), the link takes an extra loss L ~ max(0, N(nlos_loss_db, nlos_loss_std_db))
  [dB] (3GPP TR 37.885 clause 6.2.1) and is read from the table farther away:
  d_eff = d * 10^(L / pdr_slope_db_per_decade) (the distance at which the table's own
  path-loss law loses L more). The line test is vei's occlusion test
  (:func:`vei.policy.perception_geometry.segments_blocked`).
- **Latency**: fixed part + random part, the random part Exp(mean = jitter) truncated at
  10 means, or U(0, jitter).

:func:`link_budget_pdr` recomputes the default tables (vei.config.v2x.DEFAULT_PDR) from
TR 37.885's urban NLOS path loss and a link budget (the calculation is this project's:
docs/v2x.md).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from vei.policy import perception_geometry as geom

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: The exponential latency's draws are truncated at this many means.
EXP_TRUNCATION = 10.0

#: Link budget of :func:`link_budget_pdr` per technology: noise bandwidth [Hz] and the SNR
#: [dB] of 10 % packet error (350-byte packets, crossing NLOS channel): 802.11p MCS 2 (QPSK
#: 1/2) over 10 MHz; LTE-V2X MCS 4 over 20 resource blocks (3.6 MHz).
LINK_BUDGET: dict[str, tuple[float, float]] = {
    "its-g5": (10e6, 5.92),
    "c-v2x-pc5": (20 * 180e3, 2.85),
}


def link_budget_pdr(
    distance_m: npt.ArrayLike,
    technology: str,
    *,
    tx_power_dbm: float = 23.0,
    tx_gain_dbi: float = 0.0,
    rx_gain_dbi: float = 3.0,
    noise_figure_db: float = 9.0,
    frequency_ghz: float = 5.9,
    shadowing_db: float = 4.0,
    antenna_height_diff_m: float = 0.4,
    min_distance_m: float = 3.0,
) -> FloatArray:
    """Delivery ratio of a single rider -> car link around a built-up corner.

    ``PL = 36.85 + 30 log10(d3D) + 18.9 log10(fc)`` (3GPP TR 37.885 Table 6.2.1-1, urban
    V2V NLOS), SNR = P_tx + G_tx + G_rx - PL - (-174 dBm/Hz + 10 log10(B) + NF), PDR =
    Phi((SNR - SNR_10%) / sigma_shadowing): the share of log-normal shadowing draws that
    keep the SNR above the 10 %-error point (noise-limited, one link, no interference).

    Args:
        distance_m: [...] horizontal distances [m] (clamped to ``min_distance_m``).
        technology: 'its-g5' or 'c-v2x-pc5' (:data:`LINK_BUDGET`).
    Returns:
        [...] delivery ratios in [0, 1].
    """
    from scipy.stats import norm

    bandwidth_hz, snr_10_db = LINK_BUDGET[technology]
    d = np.maximum(np.asarray(distance_m, dtype=np.float64), min_distance_m)
    d3 = np.hypot(d, antenna_height_diff_m)
    pl = 36.85 + 30.0 * np.log10(d3) + 18.9 * math.log10(frequency_ghz)
    noise_dbm = -174.0 + 10.0 * math.log10(bandwidth_hz) + noise_figure_db
    snr = tx_power_dbm + tx_gain_dbi + rx_gain_dbi - pl - noise_dbm
    return np.asarray(norm.cdf((snr - snr_10_db) / shadowing_db), dtype=np.float64)


def pdr_at(
    distance_m: npt.ArrayLike, table_distance_m: npt.ArrayLike, table_pdr: npt.ArrayLike
) -> FloatArray:
    """The table's delivery ratio at ``distance_m`` [...] (linear, held beyond the ends)."""
    return np.interp(np.asarray(distance_m, dtype=np.float64), table_distance_m, table_pdr)


def effective_distance(
    distance_m: npt.ArrayLike, loss_db: npt.ArrayLike, slope_db_per_decade: float
) -> FloatArray:
    """d * 10^(L / slope): the distance at which the path loss is L dB more [m]."""
    return np.asarray(distance_m, dtype=np.float64) * np.power(
        10.0, np.asarray(loss_db, dtype=np.float64) / slope_db_per_decade
    )


def blockage_loss(mean_db: float, std_db: float, z: npt.ArrayLike) -> FloatArray:
    """max(0, mean + std z) [dB] for standard normals z."""
    return np.maximum(0.0, mean_db + std_db * np.asarray(z, dtype=np.float64))


def latency(u: npt.ArrayLike, fixed_s: FloatArray, jitter_s: FloatArray, dist: str) -> FloatArray:
    """Latency [s] from uniforms u in [0, 1): fixed + Exp(mean jitter) (inverse CDF,
    truncated at :data:`EXP_TRUNCATION` means) or fixed + U(0, jitter)."""
    u = np.asarray(u, dtype=np.float64)
    if dist == "uniform":
        return fixed_s + jitter_s * u
    cut = 1.0 - math.exp(-EXP_TRUNCATION)
    return fixed_s - jitter_s * np.log1p(-u * cut)


def latency_bound(fixed_s: float, jitter_s: float, dist: str) -> float:
    """The largest latency :func:`latency` can return [s]."""
    return fixed_s + (jitter_s if dist == "uniform" else EXP_TRUNCATION * jitter_s)


def _contains(px: FloatArray, py: FloatArray, x: FloatArray, y: FloatArray, yaw: FloatArray,
              length: FloatArray, width: FloatArray) -> BoolArray:  # fmt: skip
    c, s = np.cos(yaw), np.sin(yaw)
    dx, dy = px - x, py - y
    return (np.abs(dx * c + dy * s) < 0.5 * length) & (np.abs(-dx * s + dy * c) < 0.5 * width)


def links_blocked(
    sx_m: FloatArray,
    sy_m: FloatArray,
    rx_m: FloatArray,
    ry_m: FloatArray,
    box_x_m: FloatArray,
    box_y_m: FloatArray,
    box_yaw_rad: FloatArray,
    box_length_m: FloatArray,
    box_width_m: FloatArray,
    blockers: BoolArray,
) -> BoolArray:
    """Whether each link's straight segment crosses a blocker's box.

    Args:
        sx_m, sy_m: [Q] sender (rider) positions [m]. rx_m, ry_m: [Q] receiver (car)
            positions [m].
        box_*: [Q, M] the candidate blockers' boxes [m, rad]. blockers: [Q, M] which of
            them block this link (present vehicles other than the sender).
    Returns:
        [Q] bool. A box holding either end is ignored; grazing an edge does not block
        (:data:`vei.policy.perception_geometry.BLOCK_TOL_M`).
    """
    q, m = box_x_m.shape
    if q == 0 or m == 0:
        return np.zeros(q, dtype=bool)
    ends_inside = _contains(sx_m[:, None], sy_m[:, None], box_x_m, box_y_m, box_yaw_rad,
                            box_length_m, box_width_m) | _contains(
        rx_m[:, None], ry_m[:, None], box_x_m, box_y_m, box_yaw_rad, box_length_m, box_width_m
    )  # fmt: skip
    use = blockers & ~ends_inside
    qi, mi = np.nonzero(use)
    if qi.size == 0:
        return np.zeros(q, dtype=bool)
    hit = geom.segments_blocked(
        sx_m[qi], sy_m[qi], rx_m[qi][:, None], ry_m[qi][:, None], box_x_m[qi, mi],
        box_y_m[qi, mi], box_yaw_rad[qi, mi], box_length_m[qi, mi], box_width_m[qi, mi],
    )[:, 0]  # fmt: skip
    out = np.zeros(q, dtype=bool)
    np.logical_or.at(out, qi, hit)
    return out


__all__ = [
    "EXP_TRUNCATION",
    "LINK_BUDGET",
    "blockage_loss",
    "effective_distance",
    "latency",
    "latency_bound",
    "link_budget_pdr",
    "links_blocked",
    "pdr_at",
]
