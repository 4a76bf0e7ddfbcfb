"""The output folder of ``vei risk`` (every file written atomically).

============================  ==========================================================
``risk.json``                 format ``vei.risk/1``: scenario and rider, the variation
                              (as given and as resolved for this scenario), the automatic
                              time shift, per planner the figures with their 95 % CIs,
                              method, simulations and diagnostics, the failure modes,
                              importance factors, the pairwise comparisons, the Sobol
                              indices, timings
``summary.csv``               one row per planner: the figures and their intervals
``samples.parquet``           every simulated sample: variant_id, the parameters, ``u.*``
                              (standard-space coordinates), the metrics, the outcomes,
                              ``stage`` (mc, ce-k, ce-final-k, ss-k, pair, sobol),
                              ``policy``, ``weight`` (the importance weight of samples in
                              a planner's final estimate, 1 for Monte Carlo), ``in_estimate``
``probability_map.png``       the first planner's P(collision | cell) over time shift x
                              cruise speed (or the first two varied quantities), shown
                              where its 95 % CI is within +-0.1, the rest hatched
``configs/<variant_id>.yaml`` run configurations (``vei run SCENARIO --config FILE``
                              re-runs the sample alone and gives its row): up to
                              200 collisions, those the final estimates rest on first,
                              and the first 20 other samples
                              (``--configs failures``, default), every sample
                              (``all``, ~3 ms each), none
============================  ==========================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

RISK_FORMAT = "vei.risk/1"
#: With ``--configs failures``: at most this many collisions (in sample order) and this
#: many other samples get a run configuration (writing one takes ~3 ms).
MAX_FAILURE_CONFIGS = 200
OTHER_CONFIGS = 20


@dataclass(frozen=True)
class _SpecView:
    """What :func:`vei.sweep.io.write_variant_configs` reads of a spec."""

    base: str
    time_shift_reference: str
    perception: Any
    names: tuple[str, ...]
    v2x: Any = None


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def samples_table(result: Any) -> pd.DataFrame:
    """Every simulated sample, with ``weight`` and ``in_estimate`` of the final estimates."""
    samples = result.problem.samples()
    if samples.empty:
        return samples
    samples = samples.copy()
    samples["in_estimate"] = False
    samples["weight"] = np.nan
    key = samples["variant_id"].astype(str) + "|" + samples["stage"].astype(str)
    for p in result.planners:
        if p.rows is None or p.rows.empty or "variant_id" not in p.rows:
            continue
        k = p.rows["variant_id"].astype(str) + "|" + p.rows["stage"].astype(str)
        w = pd.Series(p.rows["weight"].to_numpy(np.float64), index=k.to_numpy())
        w = w[~w.index.duplicated()]
        hit = key.isin(w.index).to_numpy()
        samples.loc[hit, "in_estimate"] = True
        samples.loc[hit, "weight"] = w.loc[key[hit].to_numpy()].to_numpy()
    return samples


def summary_rows(result: Any) -> pd.DataFrame:
    """One row per planner: figures, intervals, method, simulations."""
    recs = []
    for p in result.planners:
        rec: dict[str, Any] = {"policy": p.policy, "method": p.method,
                               "n_simulations": p.n_simulations}  # fmt: skip
        for name, e in (
            ("p_collision", p.p_collision),
            ("p_collision_recorded", p.p_collision_recorded),
            ("share_synthetic", p.share_synthetic),
            ("p_injury_relevant", p.p_injury_relevant),
            ("expected_injury_risk", p.expected_injury),
            ("p_seen_too_late", p.p_seen_too_late),
        ):
            if e is None:
                continue
            rec[name] = e.value
            rec[f"{name}_lo"] = e.lo
            rec[f"{name}_hi"] = e.hi
        rec["p_collision_rel_ci"] = p.p_collision.rel_ci
        rec["upper_bound_only"] = p.p_collision.bound
        rec["reliable"] = p.p_collision.reliable
        rec["target_reached"] = p.target_reached
        recs.append(rec)
    return pd.DataFrame(recs)


def encounter_columns(result: Any) -> dict[str, Any]:
    """The first planner's figures as flat columns (``risk_*``) for the catalogue:
    P(collision), P(injury-relevant collision), the expected harm (= the expected injury
    risk: probability x injury risk), P(seen too late), each with its interval; the
    method, simulations, reliability, whether only a bound is known."""
    p = result.planners[0]
    out: dict[str, Any] = {
        "risk_policy": p.policy,
        "risk_method": p.method,
        "risk_n_simulations": int(p.n_simulations),
    }
    for name, e in (
        ("p_collision", p.p_collision),
        ("p_collision_recorded", p.p_collision_recorded),
        ("share_synthetic", p.share_synthetic),
        ("p_injury_relevant", p.p_injury_relevant),
        ("expected_harm", p.expected_injury),
        ("p_seen_too_late", p.p_seen_too_late),
    ):
        if e is None:
            continue
        out[f"risk_{name}"] = float(e.value)
        out[f"risk_{name}_lo"] = float(e.lo)
        out[f"risk_{name}_hi"] = float(e.hi)
    out["risk_upper_bound_only"] = bool(p.p_collision.bound)
    out["risk_reliable"] = bool(p.p_collision.reliable)
    return out


def risk_document(result: Any) -> dict[str, Any]:
    """The content of risk.json."""
    prob = result.problem
    space = prob.space
    planners = []
    for p in result.planners:
        d = p.as_dict()
        d["failure_modes"] = result.modes.get(p.policy, {})
        if p.policy in result.importance:
            d["importance_factors"] = result.importance[p.policy]
        planners.append(d)
    resolved = [{"name": n, "distribution": dist.summary()} for n, dist in space.distributions]
    if space.rider_profile is not None:
        resolved.append({
            "name": "rider",
            "distribution": f"rider population '{space.category}' of profile "
            f"{prob.model.rider.profile if prob.model.rider else ''} (5 log-normal dimensions)",
        })  # fmt: skip
    return _jsonable({
        "format": RISK_FORMAT,
        "scenario": {"id": prob.scenario_id, "path": str(prob.scenario_dir),
                     "rider_id": prob.rider_id, "rider_category": prob.rider_category},
        "variation": prob.model.to_dict(),
        "variation_digest": prob.model.digest(),
        "variation_resolved": resolved,
        "dimensions": list(space.names),
        "fixed": {k: v for k, v in space.fixed.items()},
        "time_shift": None if prob.auto_shift is None else prob.auto_shift.as_dict(),
        "planners": planners,
        "comparisons": [c.as_dict() for c in result.comparisons],
        "sobol": result.sobol,
        "n_simulations": result.n_simulations,
        "timings_s": result.timings,
    })  # fmt: skip


def config_rows(samples: pd.DataFrame, which: str) -> pd.DataFrame:
    """The samples that get a run configuration (module docstring), unique by id.

    ``failures``: the collisions the final estimates rest on (``in_estimate``) first, the
    other collisions after them, at most MAX_FAILURE_CONFIGS, and OTHER_CONFIGS samples
    without collision."""
    if which == "none" or samples.empty:
        return samples.iloc[:0]
    if which == "all":
        return samples.drop_duplicates("variant_id")
    if "in_estimate" in samples:  # a sample simulated twice counts where it is used
        samples = samples.sort_values("in_estimate", ascending=False, kind="stable")
    uniq = samples.drop_duplicates("variant_id")
    coll = uniq["collision"].to_numpy(bool)
    used = (
        uniq["in_estimate"].fillna(False).to_numpy(bool)
        if "in_estimate" in uniq
        else np.zeros(len(uniq), bool)
    )
    fail = pd.concat([uniq[coll & used], uniq[coll & ~used]]).head(MAX_FAILURE_CONFIGS)
    other = uniq[~coll].head(OTHER_CONFIGS)
    return pd.concat([fail, other])


def write_configs(result: Any, folder: Path, rows: pd.DataFrame) -> list[Path]:
    """Run configurations of ``rows`` (``vei run --config``), as sweeps write theirs."""
    from vei.sweep.io import write_variant_configs
    from vei.sweep.params import PARAMETERS

    prob = result.problem
    names = tuple(n for n in PARAMETERS if n in rows.columns)
    spec = _SpecView(prob.model.base, prob.model.time_shift_reference, prob.model.perception,
                     names, prob.model.v2x)  # fmt: skip
    reach = prob.evaluator.sim.continuation.ego_speed_mps  # what the samples ran with
    return write_variant_configs(
        folder, rows, spec, prob.prepared.auto_shift_s, reach_speed_mps=reach
    )


def write_risk(result: Any, out: Path, *, configs: str = "failures") -> None:
    """Write the output folder (module docstring)."""
    from vei.io.atomic import write_json, write_parquet, write_text

    out.mkdir(parents=True, exist_ok=True)
    samples = samples_table(result)
    write_parquet(out / "samples.parquet", samples)
    write_text(out / "summary.csv", summary_rows(result).to_csv(index=False))
    if hasattr(result.problem, "prepared"):
        write_configs(result, out / "configs", config_rows(samples, configs))
    write_map(result, out / "probability_map.png")
    write_json(out / "risk.json", risk_document(result))


def write_map(result: Any, path: Path) -> bool:
    """probability_map.png: the first planner's P(collision | cell) over the first two
    varied quantities (time shift x cruise speed when both vary), from its final sample
    (weighted where importance sampling drew it), cells not known hatched. False when
    fewer than two quantities vary or the sample is too small."""
    from vei.sweep.riskmap import write_sample_probability_map

    p = result.planners[0]
    dims = [n for n, _ in result.problem.space.distributions]
    if len(dims) < 2 or p.rows is None or p.rows.empty:
        return False
    x, y = (
        ("time_shift_s", "ego.cruise_speed_mps")
        if {"time_shift_s", "ego.cruise_speed_mps"} <= set(dims)
        else dims[:2]
    )
    if not {x, y} <= set(p.rows.columns):
        return False
    grid = write_sample_probability_map(
        path, p.rows[x], p.rows[y], p.rows["failure"].to_numpy(bool),
        weights=p.rows["weight"].to_numpy(float) if p.proposal is not None else None,
        x_label=x, y_label=y,
        title=f"{p.policy}: P(collision | cell) from {len(p.rows):,} samples ({p.method})",
    )  # fmt: skip
    return grid is not None
