"""The radio channel between a rider's device and the car: path loss per link state, link
budget, delivery, latency (3GPP TR 37.885 V15.3.0, sidelink V2V at 5.9 GHz).

Each VAM's link is in one of three states, chosen per link from the geometry
(:mod:`.links`):

- **LOS**: the straight line between the two antennas is clear. Path loss (TR 37.885
  Table 6.2.1-1, V2V): urban ``38.77 + 16.7 log10 d + 18.2 log10 fc``, highway
  ``32.4 + 20 log10 d + 20 log10 fc`` (d the 3-D distance in m, fc in GHz); shadowing
  sigma 3 dB.
- **NLOSv** (blocked by a vehicle): the LOS path loss plus the vehicle blockage loss of TR
  37.885 clause 6.2.1 (Table 6.2.1-1, "NLOSv: PL = PL_LOS + additional vehicle blockage
  loss"): by the heights of the two antennas and of the blocker, case 1 (both antennas
  above the blocker) 0 dB; case 2 (both below) mean ``9 + max(0, 15 log10 d - 41)`` dB,
  std 4.5 dB; case 3 (otherwise) mean ``5 + max(0, 15 log10 d - 41)`` dB, std 4 dB; the
  loss is ``max(0, X)`` for a normal X in dB (a log-normal loss); shadowing sigma 3 dB.
- **NLOS** (blocked by a building, where the map has outlines): urban NLOS
  ``36.85 + 30 log10 d + 18.9 log10 fc``; shadowing sigma 4 dB.

A VAM is delivered with probability ``pdr_factor x Phi((SNR - SNR_10%) / sigma)``: SNR the
mean signal-to-noise ratio of the link (:data:`LINK_BUDGET`: transmit power and antenna
gains minus path loss and blockage, over the allocation's thermal noise and the receiver's
noise figure), SNR_10% the SNR of 10 % packet error, sigma the state's shadowing: the share
of log-normal shadowing draws that keep the SNR above the 10 %-error point (one link,
noise-limited, no interference: ``pdr_factor`` stands for the channel load). A user's own
delivery table (``pdr_distance_m`` / ``pdr``) replaces the link budget: it is the LOS
delivery against distance, and a blocked link is read at the distance where the LOS law
loses its extra loss: ``d 10^(L / slope)``.

**Latency**: fixed part + random part, the random part Exp(mean = jitter) truncated at 10
means, or U(0, jitter).

Every value and its source: docs/v2x.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

#: The exponential latency's draws are truncated at this many means.
EXP_TRUNCATION = 10.0
#: Carrier frequency of both technologies [GHz] (the 5.9 GHz ITS band).
FREQUENCY_GHZ = 5.9
#: Shortest 3-D distance the path-loss laws are evaluated at [m] (our choice: boxes may
#: touch; the laws diverge at 0).
MIN_DISTANCE_M = 3.0

#: Link states (``events['link']`` of :func:`vei.policy.v2x.model.step`).
LOS, NLOSV, NLOS = 0, 1, 2
LINK_STATES = ("LOS", "NLOSv", "NLOS")
#: Shadow-fading standard deviation per link state [dB] (TR 37.885 Table 6.2.1-1, V2V).
SHADOWING_STD_DB = (3.0, 3.0, 4.0)

#: Blocker heights [m] of TR 37.885 clause 6.1.2's vehicle types: type 1 / 2 passenger
#: vehicles 1.6 m, type 3 truck / bus 3 m.
PASSENGER_HEIGHT_M = 1.6
TRUCK_HEIGHT_M = 3.0

#: Transmitter (the rider's device, TR 37.885's UE maximum) [dBm] and antenna gains [dBi]
#: of :data:`LINK_BUDGET`; the receiver's noise figure [dB]; thermal noise [dBm/Hz].
TX_POWER_DBM = 23.0
TX_GAIN_DBI = 0.0
RX_GAIN_DBI = 3.0
NOISE_FIGURE_DB = 9.0
THERMAL_NOISE_DBM_HZ = -174.0

#: LTE-V2X PC5: one 350-byte VAM at MCS 4 (QPSK, TBS index 4) needs 40 physical resource
#: blocks (TS 36.213 Table 7.1.7.2.1-1: 2856 bits at 40 PRBs, 2792 at 39); its noise
#: bandwidth is that allocation, 40 x 180 kHz.
PC5_PRBS = 40
PC5_TBS_BITS = 2856
PRB_HZ = 180e3


def pc5_snr_threshold_db(
    n_prb: int = PC5_PRBS,
    tbs_bits: int = PC5_TBS_BITS,
    *,
    bits_per_symbol: int = 2,
    data_symbols: int = 9,
    alpha: float = 0.4,
) -> float:
    """SNR [dB] of 10 % block error of an LTE-V2X transport block (WiLabV2Xsim's
    ``findRBsBeaconSINRmin``: a Shannon bound scaled by ``alpha``).

    Code rate R = tbs / (n_prb x 12 subcarriers x data_symbols x bits_per_symbol),
    spectral efficiency eta = 12 x 14 x Q x R / (1 ms x 180 kHz) [b/s/Hz], SNR =
    2^(eta / alpha) - 1. 9 data symbols: 14 per subframe less 4 DMRS and the guard symbol
    (WiLabV2Xsim's current version counts 8, the AGC symbol as lost: 3.67 dB at 40 PRBs).
    """
    rate = tbs_bits / (n_prb * 12 * data_symbols * bits_per_symbol)
    eta = 12 * 14 * bits_per_symbol * rate / (1e-3 * PRB_HZ)
    return 10.0 * math.log10(2.0 ** (eta / alpha) - 1.0)


@dataclass(frozen=True)
class LinkBudget:
    """One technology's allocation: noise bandwidth [Hz] and SNR of 10 % packet error [dB].

    Attributes:
        bandwidth_hz: the transmission's (and the noise's) bandwidth [Hz].
        snr_10_db: SNR at which 10 % of the packets are lost [dB].
        what: the allocation in words (docs, reports).
    """

    bandwidth_hz: float
    snr_10_db: float
    what: str

    @property
    def noise_dbm(self) -> float:
        """Thermal noise over the bandwidth plus the noise figure [dBm]."""
        return THERMAL_NOISE_DBM_HZ + 10.0 * math.log10(self.bandwidth_hz) + NOISE_FIGURE_DB

    @property
    def max_path_loss_db(self) -> float:
        """The path loss (with blockage) at which the mean SNR is SNR_10% [dB]: delivery
        0.5 there."""
        return TX_POWER_DBM + TX_GAIN_DBI + RX_GAIN_DBI - self.noise_dbm - self.snr_10_db


#: The link budget of each technology (docs/v2x.md gives the sources): ITS-G5 802.11p MCS
#: 2 (QPSK 1/2) over its 10 MHz channel, 350-byte packets; LTE-V2X PC5 MCS 4 over the 40
#: PRBs (7.2 MHz) that carry 350 bytes (:data:`PC5_PRBS`).
LINK_BUDGET: dict[str, LinkBudget] = {
    "its-g5": LinkBudget(10e6, 5.92, "802.11p MCS 2 (QPSK 1/2), 350 bytes, 10 MHz"),
    "c-v2x-pc5": LinkBudget(
        PC5_PRBS * PRB_HZ,
        round(pc5_snr_threshold_db(), 2),
        f"LTE-V2X MCS 4 (QPSK), 350 bytes, {PC5_PRBS} PRBs ({PC5_PRBS * PRB_HZ / 1e6:.1f} MHz)",
    ),
}


def distance_3d_m(distance_m: npt.ArrayLike, height_diff_m: float) -> FloatArray:
    """The antennas' 3-D distance [m] from their horizontal distance [m] and height
    difference [m], at least :data:`MIN_DISTANCE_M`."""
    d = np.hypot(np.asarray(distance_m, dtype=np.float64), height_diff_m)
    return np.maximum(d, MIN_DISTANCE_M)


def pathloss_los_db(
    d3_m: npt.ArrayLike, environment: str = "urban", frequency_ghz: float = FREQUENCY_GHZ
) -> FloatArray:
    """LOS path loss [dB] at 3-D distances ``d3_m`` [m] (TR 37.885 Table 6.2.1-1, V2V):
    urban 38.77 + 16.7 log10 d + 18.2 log10 fc, highway 32.4 + 20 log10 d + 20 log10 fc."""
    d = np.asarray(d3_m, dtype=np.float64)
    if environment == "highway":
        return 32.4 + 20.0 * np.log10(d) + 20.0 * math.log10(frequency_ghz)
    if environment != "urban":
        raise ValueError(f"environment must be 'urban' or 'highway', got {environment!r}")
    return 38.77 + 16.7 * np.log10(d) + 18.2 * math.log10(frequency_ghz)


def pathloss_nlos_db(d3_m: npt.ArrayLike, frequency_ghz: float = FREQUENCY_GHZ) -> FloatArray:
    """NLOS (building) path loss [dB]: 36.85 + 30 log10 d + 18.9 log10 fc (TR 37.885
    Table 6.2.1-1, urban V2V NLOS; d the 3-D distance [m])."""
    d = np.asarray(d3_m, dtype=np.float64)
    return 36.85 + 30.0 * np.log10(d) + 18.9 * math.log10(frequency_ghz)


def los_slope_db_per_decade(environment: str = "urban") -> float:
    """The LOS law's slope [dB per decade of distance]: 16.7 urban, 20 highway."""
    return 20.0 if environment == "highway" else 16.7


def blockage_stats_db(
    d3_m: npt.ArrayLike, tx_height_m: float, rx_height_m: float, blocker_height_m: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Mean and standard deviation [dB] of the vehicle blockage loss (TR 37.885 clause
    6.2.1): case 1, min(h_tx, h_rx) > h_blocker: 0 / 0; case 2, max(h_tx, h_rx) <
    h_blocker: 9 + max(0, 15 log10 d - 41) / 4.5; case 3, otherwise: 5 + max(0, 15 log10 d
    - 41) / 4.

    Args:
        d3_m: [...] 3-D distances [m]. tx_height_m, rx_height_m: antenna heights [m].
        blocker_height_m: [...] the (tallest) blocker's height [m].
    Returns:
        (mean [...], std [...]) [dB].
    """
    d = np.asarray(d3_m, dtype=np.float64)
    h = np.broadcast_to(np.asarray(blocker_height_m, dtype=np.float64), d.shape)
    far = np.maximum(0.0, 15.0 * np.log10(d) - 41.0)
    lo, hi = min(tx_height_m, rx_height_m), max(tx_height_m, rx_height_m)
    case1 = lo > h
    case2 = ~case1 & (hi < h)
    mean = np.where(case1, 0.0, np.where(case2, 9.0, 5.0) + far)
    std = np.where(case1, 0.0, np.where(case2, 4.5, 4.0))
    return mean, std


def blockage_loss(mean_db: npt.ArrayLike, std_db: npt.ArrayLike, z: npt.ArrayLike) -> FloatArray:
    """max(0, mean + std z) [dB] for standard normals z (TR 37.885's "max{0 dB, a
    log-normal random variable}": normal in dB)."""
    return np.maximum(
        0.0,
        np.asarray(mean_db, dtype=np.float64)
        + np.asarray(std_db, dtype=np.float64) * np.asarray(z, dtype=np.float64),
    )


def mean_snr_db(path_loss_db: npt.ArrayLike, technology: str) -> FloatArray:
    """Mean SNR [dB] of a link with this path loss (blockage included) [dB]."""
    budget = LINK_BUDGET[technology]
    return (
        TX_POWER_DBM + TX_GAIN_DBI + RX_GAIN_DBI
        - np.asarray(path_loss_db, dtype=np.float64) - budget.noise_dbm
    )  # fmt: skip


def delivery_ratio(
    snr_db: npt.ArrayLike, technology: str, shadowing_db: npt.ArrayLike
) -> FloatArray:
    """Phi((SNR - SNR_10%) / sigma): the share of shadowing draws (normal in dB, std
    ``shadowing_db``) that keep the SNR above the technology's 10 %-error point."""
    from scipy.special import ndtr

    budget = LINK_BUDGET[technology]
    z = (np.asarray(snr_db, dtype=np.float64) - budget.snr_10_db) / np.asarray(
        shadowing_db, dtype=np.float64
    )
    return np.asarray(ndtr(z), dtype=np.float64)


def path_loss_db(
    d3_m: npt.ArrayLike,
    state: npt.ArrayLike,
    environment: str = "urban",
    blockage_db: npt.ArrayLike = 0.0,
) -> FloatArray:
    """Path loss [dB] of links in ``state`` (:data:`LOS`, :data:`NLOSV`, :data:`NLOS`):
    LOS law, LOS law + ``blockage_db``, or the NLOS law."""
    st = np.asarray(state)
    los = pathloss_los_db(d3_m, environment)
    return np.where(
        st == NLOS,
        pathloss_nlos_db(d3_m),
        los + np.where(st == NLOSV, np.asarray(blockage_db, dtype=np.float64), 0.0),
    )


def link_pdr(
    distance_m: npt.ArrayLike,
    state: npt.ArrayLike,
    technology: str,
    *,
    environment: str = "urban",
    blockage_db: npt.ArrayLike = 0.0,
    height_diff_m: float = 0.1,
) -> FloatArray:
    """Delivery ratio of single links (the link budget; no ``pdr_factor``).

    Args:
        distance_m: [...] horizontal distances [m]. state: [...] link states.
        technology: 'its-g5' or 'c-v2x-pc5'. environment: 'urban' or 'highway'.
        blockage_db: [...] the vehicle blockage loss of NLOSv links [dB].
        height_diff_m: the antennas' height difference [m].
    Returns:
        [...] delivery ratios in [0, 1].
    """
    st = np.asarray(state)
    d3 = distance_3d_m(distance_m, height_diff_m)
    snr = mean_snr_db(path_loss_db(d3, st, environment, blockage_db), technology)
    sigma = np.asarray(SHADOWING_STD_DB)[st]
    return delivery_ratio(snr, technology, sigma)


def pdr_at(
    distance_m: npt.ArrayLike, table_distance_m: npt.ArrayLike, table_pdr: npt.ArrayLike
) -> FloatArray:
    """A delivery table's ratio at ``distance_m`` [...] (linear, held beyond the ends)."""
    return np.interp(np.asarray(distance_m, dtype=np.float64), table_distance_m, table_pdr)


def effective_distance(
    distance_m: npt.ArrayLike, loss_db: npt.ArrayLike, slope_db_per_decade: float
) -> FloatArray:
    """d * 10^(L / slope): the distance at which the path loss is L dB more [m]."""
    return np.asarray(distance_m, dtype=np.float64) * np.power(
        10.0, np.asarray(loss_db, dtype=np.float64) / slope_db_per_decade
    )


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


__all__ = [
    "EXP_TRUNCATION",
    "LINK_BUDGET",
    "LINK_STATES",
    "LOS",
    "NLOS",
    "NLOSV",
    "SHADOWING_STD_DB",
    "LinkBudget",
    "blockage_loss",
    "blockage_stats_db",
    "delivery_ratio",
    "distance_3d_m",
    "effective_distance",
    "latency",
    "latency_bound",
    "link_pdr",
    "los_slope_db_per_decade",
    "mean_snr_db",
    "path_loss_db",
    "pathloss_los_db",
    "pathloss_nlos_db",
    "pc5_snr_threshold_db",
    "pdr_at",
]
