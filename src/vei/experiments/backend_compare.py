"""Two backends side by side on one scenario: does the closed loop play the same?

:func:`compare_backends` runs the case study's configurations on a reference backend
(default: the built-in engine) and on another one (default: esmini) with the same time
shift, and tabulates per configuration: the collision outcome and time, the safety
index, the minimum gap, the RMS difference of the ego's speed over the run, and the RMS
distance between the two rider paths (over the steps where the rider is in the scene in
both runs), and the largest distance between the two backends' replayed road users (how
exactly the other backend plays them). :func:`format_comparison` renders the table.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from vei.config import CaseConfig, SimConfig
from vei.errors import BackendError
from vei.experiments.casestudy import CaseStudyResult, Runner, run_casestudy
from vei.types import EGO_ID, Scenario

#: The must-show tolerances (issue 10): same collision outcome, ego speed within
#: 0.1 m/s RMS, rider path within 0.1 m RMS.
SPEED_RMS_TOL_MPS = 0.1
PATH_RMS_TOL_M = 0.1


@dataclass(frozen=True)
class BackendComparison:
    """Outcome of :func:`compare_backends`.

    Attributes:
        table: one row per configuration (see :data:`COLUMNS`).
        reference, other: the two case-study results.
        reference_s, other_s: wall time of each case study [s].
    """

    table: pd.DataFrame
    reference: CaseStudyResult
    other: CaseStudyResult
    reference_s: float
    other_s: float

    @property
    def agree(self) -> bool:
        """Same collision outcome and both RMS differences within the tolerances everywhere."""
        t = self.table
        return bool(
            t["same_collision"].all()
            and (t["ego_speed_rms_diff_mps"] <= SPEED_RMS_TOL_MPS).all()
            and (t["rider_path_rms_m"].fillna(0.0) <= PATH_RMS_TOL_M).all()
        )


#: Columns of BackendComparison.table ('_ref' = the reference backend).
COLUMNS: tuple[str, ...] = (
    "config",
    "collision_ref",
    "collision",
    "same_collision",
    "collision_time_ref_s",
    "collision_time_s",
    "safety_index_ref",
    "safety_index",
    "min_gap_ref_m",
    "min_gap_m",
    "ego_speed_rms_diff_mps",
    "rider_path_rms_m",
    "others_max_dev_m",
)


def _series(frame: pd.DataFrame, config: str, agent: str) -> pd.DataFrame:
    part = frame[(frame["config"] == config) & (frame["agent_id"] == agent)]
    return part.sort_values("t_s").reset_index(drop=True)


def run_differences(
    ref: pd.DataFrame, other: pd.DataFrame, config: str, rider_id: str
) -> tuple[float, float]:
    """(ego speed RMS difference [m/s], rider path RMS distance [m]) of one configuration.

    Args:
        ref, other: long time series (TIMESERIES_COLUMNS) of the two backends.
        config: the configuration's name. rider_id: the rider's agent_id.
    Returns:
        The RMS over the common steps; the rider's over the steps where it is active in
        both (NaN if there is none).
    Raises:
        BackendError: the two runs have different step times.
    """
    e1, e2 = _series(ref, config, EGO_ID), _series(other, config, EGO_ID)
    if len(e1) != len(e2) or not np.allclose(e1["t_s"], e2["t_s"], atol=1e-9):
        raise BackendError(f"{config}: the two backends' runs have different step times")
    dv = e1["speed_mps"].to_numpy() - e2["speed_mps"].to_numpy()
    r1, r2 = _series(ref, config, rider_id), _series(other, config, rider_id)
    both = r1["active"].to_numpy(bool) & r2["active"].to_numpy(bool)
    if both.any():
        dx = r1["x_m"].to_numpy()[both] - r2["x_m"].to_numpy()[both]
        dy = r1["y_m"].to_numpy()[both] - r2["y_m"].to_numpy()[both]
        path = float(np.sqrt(np.mean(dx * dx + dy * dy)))
    else:
        path = float("nan")
    return float(np.sqrt(np.mean(dv * dv))), path


def others_max_deviation(
    ref: pd.DataFrame, other: pd.DataFrame, config: str, ids: Sequence[str]
) -> float:
    """Largest distance [m] between the two backends' replayed road users ``ids`` over the
    steps where both have them active (0 if none; NaN if their step counts differ)."""
    worst = 0.0
    for aid in ids:
        a, b = _series(ref, config, aid), _series(other, config, aid)
        if len(a) != len(b):
            return float("nan")
        both = a["active"].to_numpy(bool) & b["active"].to_numpy(bool)
        if both.any():
            d = np.hypot(
                a["x_m"].to_numpy()[both] - b["x_m"].to_numpy()[both],
                a["y_m"].to_numpy()[both] - b["y_m"].to_numpy()[both],
            )
            worst = max(worst, float(d.max()))
    return worst


def compare_backends(
    scenario: Scenario,
    *,
    backend: str | Runner = "esmini",
    reference: str | Runner = "builtin",
    cases: Sequence[str | CaseConfig] | None = None,
    time_shift: str | float = "auto",
    sim: SimConfig | None = None,
    **casestudy: Any,
) -> BackendComparison:
    """Run the configurations on ``reference`` and on ``backend`` (same shift); compare.

    Args:
        scenario: reconstructed scenario with a primary threat.
        backend, reference: backend names or case-study Runners.
        cases: configurations (default: the paper's five).
        time_shift: 'auto' (resolved once, on the reference) or seconds.
        sim: engine settings.
        casestudy: further run_casestudy arguments for the reference run (threat,
            make_critical, metrics_config); the other backend runs the scenario, rider
            and shift that the reference run used.
    Returns:
        BackendComparison (table, both results, wall times).
    """
    t0 = time.perf_counter()
    ref = run_casestudy(
        scenario, cases=cases, time_shift=time_shift, backend=reference, sim=sim, **casestudy
    )
    t1 = time.perf_counter()
    got = run_casestudy(
        ref.scenario,
        cases=ref.cases,
        time_shift=ref.time_shift_s,
        backend=backend,
        sim=sim,
        metrics_config=ref.metrics_config,
    )
    t2 = time.perf_counter()
    rows: list[dict[str, Any]] = []
    s_ref = ref.summary.set_index("name")
    s_got = got.summary.set_index("name")
    others = sorted(set(ref.frame["agent_id"]) - {EGO_ID, ref.other_id})  # replayed users
    for case in ref.cases:
        a, b = s_ref.loc[case.name], s_got.loc[case.name]
        dv, dp = run_differences(ref.frame, got.frame, case.name, ref.other_id)
        do = others_max_deviation(ref.frame, got.frame, case.name, others)
        rows.append(
            {
                "config": case.name,
                "collision_ref": bool(a["collision"]),
                "collision": bool(b["collision"]),
                "same_collision": bool(a["collision"]) == bool(b["collision"]),
                "collision_time_ref_s": float(a["collision_time_s"]),
                "collision_time_s": float(b["collision_time_s"]),
                "safety_index_ref": float(a["safety_index"]),
                "safety_index": float(b["safety_index"]),
                "min_gap_ref_m": float(a["min_gap_m"]),
                "min_gap_m": float(b["min_gap_m"]),
                "ego_speed_rms_diff_mps": dv,
                "rider_path_rms_m": dp,
                "others_max_dev_m": do,
            }
        )
    table = pd.DataFrame(rows, columns=list(COLUMNS))
    return BackendComparison(table, ref, got, t1 - t0, t2 - t1)


def format_comparison(cmp: BackendComparison) -> str:
    """The comparison as a Markdown table (plus a header line naming both backends)."""
    ref, got = cmp.reference.backend, cmp.other.backend
    head = (
        f"{cmp.reference.scenario.id}: {got} vs {ref}, time shift {cmp.reference.time_shift_s:+.3f} s "
        f"({ref} {cmp.reference_s:.2f} s, {got} {cmp.other_s:.2f} s wall)"
    )

    def f(v: Any, fmt: str) -> str:
        if isinstance(v, bool | np.bool_):
            return "yes" if v else "no"
        if v is None or (isinstance(v, float) and np.isnan(v)):
            return "-"
        return format(v, fmt)

    cols = [
        ("config", "config", "s"),
        (f"collision {ref}/{got}", ("collision_ref", "collision"), ""),
        (f"t coll. [s] {ref}/{got}", ("collision_time_ref_s", "collision_time_s"), ".2f"),
        (f"safety index {ref}/{got}", ("safety_index_ref", "safety_index"), ".3f"),
        (f"min gap [m] {ref}/{got}", ("min_gap_ref_m", "min_gap_m"), ".3f"),
        ("ego speed RMS diff [m/s]", "ego_speed_rms_diff_mps", ".2e"),
        ("rider path RMS [m]", "rider_path_rms_m", ".2e"),
        ("others max dev. [m]", "others_max_dev_m", ".2e"),
    ]
    lines = [head, "", "| " + " | ".join(c[0] for c in cols) + " |"]
    lines.append("|" + "|".join("---" for _ in cols) + "|")
    for rec in cmp.table.to_dict(orient="records"):
        cells = []
        for _, key, fmt in cols:
            if isinstance(key, tuple):
                cells.append(" / ".join(f(rec[k], fmt) for k in key))
            else:
                cells.append(f(rec[key], fmt))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
