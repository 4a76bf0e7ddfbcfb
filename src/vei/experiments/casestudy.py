"""The paper's case study (Section IV): five configurations of one scenario, scored.

``run_casestudy`` takes a reconstructed scenario, fixes the primary rider's time shift
(``'auto'``: :func:`vei.sim.timeshift.find_time_shift`, computed under ``replay``'s
ego motion; or a number of seconds), runs the configurations through a *backend* and
scores the runs with :mod:`vei.metrics`. Backends only have to return the long time
series (:data:`vei.types.TIMESERIES_COLUMNS`), so the built-in engine and CARLA give the
same outputs. ``write_casestudy`` writes::

    summary.json        {"scenario_id", "primary_threat", "time_shift_s", "time_shift",
                         "backend", "metrics_config", "paper_outcome", "configs": [...]}
    summary.csv         one row per configuration (the scalar metrics, severity included,
                        then 'reference' and 'verdict': see :func:`add_verdicts`)
    timeseries.parquet  the runs' long time series
    fig4_birdseye.png, fig5_speed_profiles.png, fig6_speed_std.png,
    fig8_safety_index.png, ttc_zones.png
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.config import PAPER_CASES, CaseConfig, SimConfig, case_preset, config_to_dict
from vei.errors import BackendError, ConfigError, InputError
from vei.experiments.run_labels import add_run_labels
from vei.metrics import (
    MetricsConfig,
    paper_ttc,
    run_params,
    summarize,
    summary_records,
    trace_from_timeseries,
)
from vei.metrics.secondary import secondary_from_timeseries
from vei.types import CONTINUATION_COLUMN, EGO_ID, TIMESERIES_COLUMNS, Scenario

#: Signature of a backend: (scenario, cases, time_shift_s, sim) -> long time series with
#: TIMESERIES_COLUMNS, column 'config' = the case's name.
Runner = Callable[[Scenario, Sequence[CaseConfig], float, SimConfig], pd.DataFrame]

#: The configurations that the paper reports colliding / not colliding (Section IV-C).
PAPER_COLLIDING: tuple[str, ...] = ("replay", "normal", "aggressive")
PAPER_SAFE: tuple[str, ...] = ("normal-cap", "aggressive-cap")
#: The verdict of a case whose no-avoidance reference did not collide either.
NOTHING_TO_AVOID = "nothing-to-avoid"
#: The key of a backend's time series attrs that carries what V2X did (SimResult.v2x).
V2X_ATTR = "v2x"
#: Backends that vei knows by name.
BACKENDS: tuple[str, ...] = ("builtin", "esmini", "carla")


@dataclass(frozen=True)
class CaseStudyResult:
    """Outcome of :func:`run_casestudy`.

    Attributes:
        scenario: the scenario that was run.
        backend: backend name.
        time_shift_s: the rider's time shift used by every configuration [s].
        time_shift: how it was chosen ({'mode': 'auto'|'given', ...details}).
        cases: the configurations, in run order.
        frame: long time series of every run (TIMESERIES_COLUMNS).
        summary: one row per configuration: 'name' + every scalar metric.
        t_s: [T] step times [s]; ttc_s: [B, T] the paper's TTC per configuration.
        metrics_config: thresholds used.
        sfm_riders: the riders the SFM configurations drive when ``sim.sfm_riders``
            selects several (primary first; empty for the one-rider case study);
            riders: then one row per configuration and rider
            (vei.experiments.multi_rider.rider_table), written to riders.csv.
    """

    scenario: Scenario
    backend: str
    time_shift_s: float
    time_shift: dict[str, Any]
    cases: tuple[CaseConfig, ...]
    frame: pd.DataFrame
    summary: pd.DataFrame
    t_s: np.ndarray
    ttc_s: np.ndarray
    metrics_config: MetricsConfig = field(default_factory=MetricsConfig)
    criticality: dict[str, Any] = field(default_factory=dict)
    sfm_riders: tuple[str, ...] = ()
    riders: pd.DataFrame | None = None

    @property
    def other_id(self) -> str:
        """agent_id of the scored road user (the scenario's primary threat)."""
        assert self.scenario.primary_threat is not None
        return self.scenario.primary_threat

    def paper_outcome(self) -> dict[str, Any]:
        """Whether the paper's Section IV-C outcome holds: replay/normal/aggressive collide
        (safety index 0), normal-cap/aggressive-cap do not and keep safety index 1.

        Returns {'reproduced': bool | None (None if a paper configuration was not run),
        'per_config': {name: {'expected_collision', 'collision', 'safety_index', 'ok'}}}.
        """
        rows = {r["name"]: r for r in summary_records(self.summary)}
        per: dict[str, Any] = {}
        for name in PAPER_CASES:
            if name not in rows:
                continue
            r = rows[name]
            expect = name in PAPER_COLLIDING
            si = r["safety_index"]
            ok = r["collision"] == expect and (si == 0.0 if expect else si == 1.0)
            per[name] = {
                "expected_collision": expect,
                "collision": r["collision"],
                "safety_index": si,
                "ok": bool(ok),
            }
        reproduced = all(v["ok"] for v in per.values()) if len(per) == len(PAPER_CASES) else None
        return {"reproduced": reproduced, "per_config": per}


def resolve_cases(names: Sequence[str | CaseConfig] | None) -> tuple[CaseConfig, ...]:
    """Configurations from names (presets) or CaseConfig objects; default: the paper's five."""
    items = PAPER_CASES if names is None else names
    out = tuple(case_preset(n) if isinstance(n, str) else n for n in items)
    if not out:
        raise ConfigError("no configuration to run")
    seen = [c.name for c in out]
    if len(set(seen)) != len(seen):
        raise ConfigError(f"configuration names must be unique, got {seen}")
    return out


def is_no_avoidance(case: CaseConfig) -> bool:
    """The case drives without collision avoidance: policy 'none', or no policy and ego
    mode 'pid' (the paper's replay / normal / aggressive)."""
    policy = getattr(case.ego, "policy", None)
    return policy == "none" or (policy is None and case.ego_mode == "pid")


def _scenario_fields(case: CaseConfig) -> dict[str, Any]:
    """Everything of a case except its name and its controller (ego_mode, ego.policy,
    ego.policy_params, the CAP's parameters): what a policy run and its no-avoidance
    reference must share (rider, SFM, the ego's cruise speed / PID / actuator, perception)."""
    ego = {
        f.name: getattr(case.ego, f.name)
        for f in fields(case.ego)
        if f.name not in ("policy", "policy_params")
    }
    return {"rider": case.rider, "sfm": case.sfm, "ego": ego, "perception": case.perception}


def add_verdicts(
    summary: pd.DataFrame, cases: Sequence[CaseConfig], cfg: MetricsConfig | None = None
) -> pd.DataFrame:
    """``summary`` (one row per case, same order) with columns 'reference' and 'verdict'.

    Each case is compared (:func:`vei.metrics.severity.verdict`) with the no-avoidance
    case (:func:`is_no_avoidance`) of the same scenario in the same case study: equal in
    everything but the name and the controller (:func:`_scenario_fields`: rider, SFM,
    ego cruise speed / PID / actuator settings, perception). Verdicts: 'avoided' (the
    reference collided, this case did not), 'mitigated' (impact speed at least
    ``cfg.mitigation_share`` lower), 'not-mitigated' (also a collision the reference did
    not have), :data:`NOTHING_TO_AVOID` (neither collided: no credit for avoiding);
    the no-avoidance case itself gets 'reference' (its own name as reference). A case
    without a matching no-avoidance case (e.g. the recorded-speed replay, a study without a
    'none' run, or ``--configs normal,aggressive-cap`` whose only no-avoidance case has
    another rider) gets '' in both columns: no verdict rather than a misleading one.

    Raises:
        ConfigError: two no-avoidance cases match.
        InputError: the reference's row is not in ``summary`` (names and cases differ).
    """
    from vei.metrics.severity import verdict

    cfg = MetricsConfig() if cfg is None else cfg
    out = summary.copy()
    names = out["name"].astype(str).tolist() if "name" in out else [c.name for c in cases]
    if len(names) != len(cases):
        raise InputError(f"summary has {len(names)} rows for {len(cases)} cases")
    row_of = {n: i for i, n in enumerate(names)}
    keys = [_scenario_fields(c) for c in cases]
    refs: list[str] = []
    for case, key in zip(cases, keys, strict=True):
        if is_no_avoidance(case):
            refs.append(case.name)
            continue
        pool = [(c, k) for c, k in zip(cases, keys, strict=True) if is_no_avoidance(c)]
        match = [c.name for c, k in pool if k == key]
        if len(match) > 1:
            raise ConfigError(
                f"case {case.name!r}: several no-avoidance cases match ({', '.join(match)})"
            )
        if not match:  # no verdict: comparing with another rider or cruise speed would mislead
            refs.append("")
            continue
        refs.append(match[0])
    for r in refs:
        if r and r not in row_of:
            raise InputError(f"reference case {r!r} has no row in the summary", field="name")
    out["reference"] = np.asarray(refs, dtype=object)
    has = np.array([r != "" for r in refs], dtype=bool)
    ri = np.array([row_of[r] if r else i for i, r in enumerate(refs)], dtype=np.int64)
    hit = out["collision"].to_numpy(bool)
    speed = out["impact_speed_mps"].to_numpy(float)
    v = verdict(hit, speed, hit[ri], speed[ri], cfg.mitigation_share)
    # 'avoided' only where the reference collided: with nothing to avoid, no credit
    v = np.where(~hit & ~hit[ri], NOTHING_TO_AVOID, v)
    is_ref = np.array([is_no_avoidance(c) for c in cases], dtype=bool)
    v = np.where(is_ref, "reference", v)
    out["verdict"] = np.where(has, v, "").astype(object)
    return out


def timeseries_table(frame: pd.DataFrame) -> pd.DataFrame:
    """The columns of a run's time series as written to timeseries.parquet:
    TIMESERIES_COLUMNS, then ``continuation`` (vei.continuation.flags) where present."""
    cols = list(TIMESERIES_COLUMNS)
    if CONTINUATION_COLUMN in frame.columns:
        cols.append(CONTINUATION_COLUMN)
    return frame[cols]


def continuation_sim(sim: SimConfig, cases: Sequence[CaseConfig], scenario: Scenario) -> SimConfig:
    """``sim`` whose continuations reach far enough for the fastest of ``cases``: the
    reach distance's speed (vei.config.ContinuationConfig.ego_speed_mps) is the largest
    cruise speed of the cases ('median-moving' = the recorded ego's median moving speed),
    unless ``sim.continuation.ego_speed_mps`` is set. Unchanged when every case cruises
    at the median moving speed (the continuation's own default)."""
    from dataclasses import replace

    from vei.continuation import reach_speed_mps

    given = [c.ego.cruise_speed_mps for c in cases if not isinstance(c.ego.cruise_speed_mps, str)]
    if sim.continuation.ego_speed_mps is not None or not given:
        return sim
    speeds = [float(v) for v in given]
    if len(given) < len(cases):  # some cruise at the median moving speed
        speeds.append(reach_speed_mps(scenario, sim.continuation))
    return replace(sim, continuation=replace(sim.continuation, ego_speed_mps=max(speeds)))


def parse_time_shift(value: str | float | None) -> float | str:
    """'auto' (or None) -> 'auto'; a number or numeric text -> float seconds
    (:func:`vei.sim.timeshift.parse_time_shift`; InputError otherwise)."""
    from vei.sim.timeshift import parse_time_shift as parse

    return "auto" if value is None else parse(value)


# ------------------------------------------------------------------------------ backends
def _run_builtin(
    scenario: Scenario, cases: Sequence[CaseConfig], time_shift_s: float, sim: SimConfig
) -> pd.DataFrame:
    """Built-in engine: all configurations in one batch. What V2X did in each run
    (SimResult.v2x) rides along in ``frame.attrs['v2x']`` ({field: [B] list})."""
    from vei.sim.engine import run_cases

    result = run_cases(scenario, list(cases), time_shift_s=time_shift_s, sim=sim, kernel=sim.kernel)
    frame = result.to_frame()
    if result.v2x is not None:
        frame.attrs[V2X_ATTR] = {k: np.asarray(v).tolist() for k, v in result.v2x.items()}
    return frame


def get_backend(name: str) -> Runner:
    """The runner of a backend by name: 'builtin', 'esmini' (esmini found by $VEI_ESMINI,
    else ../shared/tools/esmini; see vei.sim.backends.esmini.esmini_runner for a folder),
    'carla' (host/port from $VEI_CARLA_HOST / $VEI_CARLA_PORT)."""
    if name == "builtin":
        return _run_builtin
    if name == "esmini":
        from vei.sim.backends.esmini import run_cases_frame as run_esmini

        return run_esmini
    if name == "carla":
        if importlib.util.find_spec("vei.sim.backends.carla") is None:
            raise BackendError(
                "backend 'carla' is not available in this installation (vei.sim.backends.carla missing)"
            )
        mod = importlib.import_module("vei.sim.backends.carla")
        runner = getattr(mod, "run_cases_frame", None)
        if runner is None:
            raise BackendError(
                "vei.sim.backends.carla has no run_cases_frame(scenario, cases, time_shift_s, sim)"
            )
        return runner
    raise ConfigError(f"unknown backend {name!r}; expected one of {', '.join(BACKENDS)}")


# ------------------------------------------------------------------------------ case study
def run_casestudy(
    scenario: Scenario,
    *,
    cases: Sequence[str | CaseConfig] | None = None,
    time_shift: str | float = "auto",
    backend: str | Runner = "builtin",
    sim: SimConfig | None = None,
    metrics_config: MetricsConfig | None = None,
    threat: str | None = None,
    make_critical: str = "timing",
) -> CaseStudyResult:
    """Run the configurations on one scenario with one time shift and score them.

    Args:
        scenario: reconstructed scenario with a primary threat (a rider).
        threat: the rider to simulate instead of the primary threat (agent or track id).
        make_critical: 'timing' (the paper's time shift) or 'timing+path' (the smallest
            change of the rider's path that lets a shift make the paths meet;
            vei.experiments.critical_path). Whether the paths meet, the miss distance and
            the change are in ``result.criticality``.
        cases: configuration names / CaseConfigs (default: the paper's five, in order).
        time_shift: 'auto' or seconds (positive: the rider comes later).
        backend: 'builtin', 'carla', or a Runner callable.
        sim: engine settings (default SimConfig(): 0.05 s step, the scenario's span).
        metrics_config: TTC zone thresholds (paper defaults).
    Returns:
        CaseStudyResult (time series, summary table, TTC series).
    """
    if scenario.primary_threat is None:
        raise InputError(
            f"scenario {scenario.id!r} has no primary threat (no e-scooter or cyclist): nothing to simulate",
            path=scenario.root,
        )
    case_objs = resolve_cases(cases)
    sim = SimConfig() if sim is None else sim
    mcfg = MetricsConfig() if metrics_config is None else metrics_config
    from vei.continuation import strip_continuations, with_continuations
    from vei.continuation.flags import mark_frame
    from vei.continuation.where import where_from_timeseries
    from vei.experiments.critical_path import make_critical as _make_critical
    from vei.recon.threat import with_threat

    scenario = with_threat(strip_continuations(scenario), threat)
    sim = continuation_sim(sim, case_objs, scenario)
    scenario, shift_s, shift_info, criticality = _make_critical(
        scenario, time_shift=parse_time_shift(time_shift), mode=make_critical, sim=sim
    )
    # every road user arrives and leaves (issue 22): the same continuations as the engine's
    scenario = with_continuations(scenario, sim.continuation)
    runner = get_backend(backend) if isinstance(backend, str) else backend
    backend_name = backend if isinstance(backend, str) else getattr(backend, "__name__", "custom")
    frame = runner(scenario, case_objs, shift_s, sim)
    v2x_report = frame.attrs.get(V2X_ATTR)
    missing = [c for c in TIMESERIES_COLUMNS if c not in frame.columns]
    if missing:
        raise BackendError(
            f"backend {backend_name!r} returned a time series without column(s) {', '.join(missing)}"
        )
    sfm_ids: tuple[str, ...] = ()
    if sim.sfm_riders != "primary":
        from vei.experiments.multi_rider import sfm_rider_ids

        sfm_ids = sfm_rider_ids(scenario, sim)
    frame = mark_frame(
        frame,
        scenario,
        rider_id=scenario.primary_threat,
        time_shift_s=shift_s,
        sfm_configs={c.name for c in case_objs if c.rider == "sfm"},
        sfm_agents=sfm_ids,
    )
    ego = scenario.agent(EGO_ID)
    other = scenario.agent(scenario.primary_threat)
    ego_dims = (sim.ego_length_m or ego.length_m, sim.ego_width_m or ego.width_m)
    other_dims = (sim.rider_length_m or other.length_m, sim.rider_width_m or other.width_m)
    trace, runs = trace_from_timeseries(
        frame, other_id=other.agent_id, ego_dims_m=ego_dims, other_dims_m=other_dims
    )
    # secondary collisions (issue 24): every contact but the ego's with the rider
    dims = {a.agent_id: (a.length_m, a.width_m) for a in scenario.agents}
    dims.update({EGO_ID: ego_dims, other.agent_id: other_dims})
    sec = secondary_from_timeseries(frame, runs, dims, other.agent_id)
    # where the contacts happened (issue 31): recorded behaviour, run-in or run-out
    where = where_from_timeseries(
        frame, runs, scenario, rider_id=other.agent_id, time_shift_s=shift_s,
        sfm_configs={c.name for c in case_objs if c.rider == "sfm"}, secondary=sec,
    )  # fmt: skip
    trace = dataclasses.replace(trace, secondary=sec, where=where)
    names = [c for c, _ in runs]
    order = [c.name for c in case_objs]
    if names != order:
        raise BackendError(f"backend {backend_name!r} returned runs {names}, expected {order}")
    summary = add_verdicts(
        summarize(trace, mcfg, labels=names, params=run_params(case_objs)), case_objs, mcfg
    )
    # what ran: the behaviour switches of each configuration, what V2X did (issue 32.4)
    summary = add_run_labels(summary, case_objs, v2x_report, backend=str(backend_name))
    rider_rows = None
    if sim.sfm_riders != "primary":
        from vei.experiments.multi_rider import rider_table

        rider_rows = rider_table(frame, scenario, sfm_ids, shift_s)
    return CaseStudyResult(
        scenario=scenario,
        backend=str(backend_name),
        time_shift_s=shift_s,
        time_shift=shift_info,
        cases=case_objs,
        frame=frame,
        summary=summary,
        t_s=np.asarray(trace.t_s),
        ttc_s=paper_ttc(trace, mcfg),
        metrics_config=mcfg,
        criticality=criticality,
        sfm_riders=sfm_ids,
        riders=rider_rows,
    )


def summary_document(result: CaseStudyResult) -> dict[str, Any]:
    """The summary.json document of a case study (JSON-safe: NaN/inf -> null)."""
    from dataclasses import asdict

    configs = summary_records(result.summary)
    case_by_name = {c.name: c for c in result.cases}
    for rec in configs:
        case = case_by_name[rec["name"]]
        rec["rider"] = case.rider
        rec["ego_mode"] = case.ego_mode
    return {
        "scenario_id": result.scenario.id,
        "primary_threat": result.other_id,
        "time_shift_s": result.time_shift_s,
        "time_shift": _json_safe(result.time_shift),
        "backend": result.backend,
        "metrics_config": asdict(result.metrics_config),
        "paper_outcome": result.paper_outcome(),
        "criticality": _json_safe(result.criticality),
        "configs": configs,
        "case_configs": {c.name: config_to_dict(c) for c in result.cases},
        **(
            {
                "sfm_riders": list(result.sfm_riders),
                "riders": _json_safe(result.riders.to_dict(orient="records")),
            }
            if result.riders is not None
            else {}
        ),
    }


def _json_safe(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def write_casestudy(
    result: CaseStudyResult,
    out_dir: str | Path,
    *,
    roads: Callable | None = None,
    figures: bool = True,
) -> dict[str, Path]:
    """Write summary.json, summary.csv, timeseries.parquet and the figures into ``out_dir``.

    Each file is written atomically; the bird's-eye figure draws the scenario's OpenDRIVE
    roads when it has a map (or ``roads(ax)`` when given). Returns {name: path} ('summary_json', 'summary_csv',
    'timeseries', and the figure keys of vei.report.casestudy_figures.FIGURE_FILES).
    """
    from vei.io.atomic import write_json, write_parquet, write_text

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {
        "timeseries": write_parquet(out / "timeseries.parquet", timeseries_table(result.frame)),
        "summary_csv": write_text(out / "summary.csv", result.summary.to_csv(index=False)),
        "summary_json": write_json(out / "summary.json", summary_document(result)),
    }
    if result.riders is not None:
        paths["riders_csv"] = write_text(out / "riders.csv", result.riders.to_csv(index=False))
    if figures:
        from vei.report.casestudy_figures import write_casestudy_figures

        if roads is None:  # draw the scenario's own map (vei reconstruct --map) when it has one
            from vei.report.birdseye import scenario_roads

            roads = scenario_roads(result.scenario)

        paths.update(
            write_casestudy_figures(
                out,
                frame=result.frame,
                summary=result.summary,
                other_id=result.other_id,
                ttc_t_s=result.t_s,
                ttc_s=result.ttc_s,
                keyframes=result.scenario.keyframes,
                roads=roads,
                dims={a.agent_id: (a.length_m, a.width_m) for a in result.scenario.agents},
                safe_ttc_s=result.metrics_config.safe_ttc_s,
                alert_ttc_s=result.metrics_config.alert_ttc_s,
            )
        )
    return paths
