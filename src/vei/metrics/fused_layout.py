"""Layout of the fused per-run metrics (:mod:`vei.metrics.fused`), without numba.

The names and order of a fused output row, the rows of the channel matrix and of the
config vector that the compiled code reads, and the conversions on both sides: a
MetricsConfig to that vector (:func:`config_vector`), rows to the DataFrame
:func:`vei.metrics.summarize` returns (:func:`metrics_frame`). Importing this module
never imports numba, so callers can ask which metrics have a fused implementation
(:data:`FUSED_METRICS`) on any install.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.errors import ConfigError
from vei.metrics.config import MetricsConfig
from vei.metrics.severity import SIDES, STRIKING, injury_risk_at_impact

#: The scalar metrics computed here, in the order of a fused output row.
FUSED_METRICS: tuple[str, ...] = (
    "collision", "collision_time_s", "safety_index", "t_safe_s", "t_attention_s",
    "t_alert_s", "t_collision_s", "t_interaction_s", "min_gap_m", "min_ttc_s",
    "max_drac_mps2", "drac_unavoidable", "impact_speed_mps", "delta_v_rider_mps",
    "delta_v_car_mps", "impact_side", "striking", "injury_risk", "peak_decel_mps2",
    "ego_speed_std_mps", "ego_speed_mean_mps", "ego_speed_min_mps",
    # issue 22 / 28.7 (vei.metrics.seen)
    "first_seen_gap_m", "first_seen_ttc_s", "seen_too_late", "safety_index_rel",
)  # fmt: skip
N_FUSED = len(FUSED_METRICS)
(
    M_COLL, M_COLL_T, M_SI, M_SAFE, M_ATT, M_ALERT, M_TCOLL, M_ALL, M_GAP, M_TTC, M_DRAC,
    M_UNAV, M_IMPACT, M_DVR, M_DVC, M_SIDE, M_STRIKE, M_INJ, M_PEAK, M_STD, M_MEAN, M_MIN,
    M_FSG, M_FST, M_STL, M_SIR,
) = range(N_FUSED)  # fmt: skip
#: Columns holding a bool (0/1) and a label (index of SIDES / STRIKING, -1 = '').
_BOOL_COLUMNS = ("collision", "drac_unavoidable", "seen_too_late")
_LABEL_COLUMNS = {"impact_side": SIDES, "striking": STRIKING}

#: Rows of the channel matrix ch [N_CH, T].
CH_EX, CH_EY, CH_EYAW, CH_EV, CH_EA, CH_RX, CH_RY, CH_RYAW, CH_RSP, CH_RACT, CH_RCOL = range(11)
N_CH = 11
#: Rows of the config vector (NaN ceiling / rider mass = each run's own).
C_SAFE, C_ALERT, C_AHEAD, C_MINV, C_CEIL, C_REACT, C_CAR, C_RIDER = range(8)
N_CFG = 8


def config_vector(cfg: MetricsConfig | None = None) -> npt.NDArray[np.float64]:
    """[N_CFG] the MetricsConfig values the compiled metrics read (NaN = per-run value)."""
    cfg = MetricsConfig() if cfg is None else cfg
    nan = float("nan")
    return np.array(
        [
            cfg.safe_ttc_s,
            cfg.alert_ttc_s,
            1.0 if cfg.ttc_scope == "ahead" else 0.0,
            cfg.min_speed_mps,
            nan if cfg.drac_ceiling_mps2 is None else cfg.drac_ceiling_mps2,
            cfg.reaction_time_s,
            cfg.car_mass_kg,
            nan if cfg.rider_mass_kg is None else cfg.rider_mass_kg,
        ],
        dtype=np.float64,
    )


def metrics_frame(
    rows: npt.NDArray[np.float64], names: Sequence[str], cfg: MetricsConfig | None = None
) -> pd.DataFrame:
    """The fused rows [B, N_FUSED] as :func:`vei.metrics.summarize` returns them: one
    column per name (bool for collision / drac_unavoidable, the labels as strings with ''
    for none, float otherwise).

    The injury risk is taken here from the rows' impact speed [m/s] and collision with
    :func:`vei.metrics.severity.injury_risk_at_impact` (``cfg``'s coefficients; paper
    defaults when None): the compiled pass leaves it out because NumPy's SIMD exp, which
    summarize uses, and the C library's exp, which compiled code calls, differ in the last
    bit on some CPUs (AVX-512).
    """
    check_names(names)
    cols: dict[str, np.ndarray] = {}
    for name in names:
        if name == "injury_risk":
            hit = rows[:, FUSED_METRICS.index("collision")] != 0.0
            speed = rows[:, FUSED_METRICS.index("impact_speed_mps")]
            cols[name] = injury_risk_at_impact(hit, speed, cfg)
            continue
        v = rows[:, FUSED_METRICS.index(name)]
        if name in _BOOL_COLUMNS:
            cols[name] = v != 0.0
        elif name in _LABEL_COLUMNS:
            labels = np.asarray(("", *_LABEL_COLUMNS[name]), dtype=object)
            cols[name] = labels[v.astype(np.intp) + 1]
        else:
            cols[name] = v.copy()
    return pd.DataFrame(cols)


def check_names(names: Sequence[str]) -> None:
    """ConfigError unless every name is one of :data:`FUSED_METRICS`."""
    bad = [n for n in names if n not in FUSED_METRICS]
    if bad:
        raise ConfigError(
            f"metric(s) {', '.join(bad)} have no fused implementation; fused: "
            f"{', '.join(FUSED_METRICS)}"
        )
