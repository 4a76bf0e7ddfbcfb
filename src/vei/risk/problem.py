"""One encounter as a risk problem: samples in standard space -> simulated outcomes.

:class:`RiskProblem` prepares a scenario once (the sweep's evaluator,
:class:`vei.sweep.evaluator.EngineEvaluator`: the compiled scenario and its automatic
time shift), resolves the variation model for it (:func:`vei.risk.variation.
resolve_space`) and evaluates samples ``u [N, d]`` for a planner in engine batches: every
sample is a sweep variant (its ``variant_id`` from its parameters, so ``vei run --config
configs/<variant_id>.yaml`` re-runs it alone and gives the same row). Every evaluated
sample is kept (:attr:`RiskProblem.log`) for the output's ``samples.parquet``.

Outcomes of a sample (columns added to the engine's metrics):

- ``collision``: the boxes touched (vei.metrics); ``failure``: a collision that was not
  seen too late (what every probability counts);
- ``injury_relevant``: a collision with a measured approach and an impact speed of at
  least ``injury_relevant_speed_mps`` (a collision without approach, the rider appearing
  in contact, has no impact speed: not counted, reported as ``no_approach``);
- ``injury``: the rider's injury risk (vei.metrics.severity; 0 without a collision and,
  for a collision without approach, 0 and counted in ``no_approach``);
- ``seen_too_late``: no planner could have reacted (issue 22's metric; all False while
  the engine does not report it): excluded from the probabilities, reported beside them;
- ``margin``: the limit-state function of the rare-event estimators: -1 for a failure,
  else the minimum gap [m] (>= 0), so that ``margin < 0`` is the failure event.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.errors import ConfigError
from vei.risk.variation import ScenarioSpace, VariationModel, reach_speed_mps, resolve_space

FloatArray = npt.NDArray[np.float64]

#: Outcome columns added to the metrics of every sample.
OUTCOMES: tuple[str, ...] = (
    "failure",
    "injury_relevant",
    "injury",
    "no_approach",
    "seen_too_late",
    "margin",
)
#: What every answer with reconstruction samples says about its run configurations.
RECON_NOTE = (
    "reconstruction.sample varies the rider's posterior reconstruction (kalman samples); a "
    "run configuration cannot name a posterior sample, so vei run re-runs such a sample on "
    "the mean reconstruction"
)
#: Most samples simulated in one engine call (memory: the compiled kernel keeps no series).
BATCH = 8192
#: Seconds between progress lines during long simulation.
PROGRESS_S = 10.0


@dataclass
class RiskProblem:
    """A scenario, a variation model and the planners to assess, ready to simulate.

    Build with :meth:`prepare`. Attributes: scenario_dir, model, policies (names: built-in
    policies or 'path/file.py:Class'; () = the base configuration's controller), the
    evaluator and its prepared scenario, the resolved space, scenario_id, rider_id,
    rider_category, auto_shift (the TimeShiftResult of reference 'auto', else None),
    ``log``: every evaluated batch (DataFrames), and ``progress``: a callback that gets a
    line at most every PROGRESS_S seconds of simulation.
    """

    scenario_dir: Path
    model: VariationModel
    policies: tuple[str, ...]
    evaluator: Any
    prepared: Any
    space: ScenarioSpace
    scenario_id: str
    rider_id: str
    rider_category: str
    auto_shift: Any = None
    log: list[pd.DataFrame] = field(default_factory=list)
    progress: Callable[[str], None] | None = None
    _next_index: int = 0
    _last_report: float = 0.0

    @classmethod
    def prepare(
        cls, scenario_dir: str | Path, model: VariationModel, policies: Sequence[str] = ()
    ) -> RiskProblem:
        """Read and compile the scenario, find its automatic shift, resolve the space.

        Raises:
            InputError: the scenario cannot be read. ConfigError: a policy is unknown, a
                distribution is impossible for this scenario.
        """
        from vei.config import ContinuationConfig
        from vei.continuation.scenario import recorded_ego_speed_mps
        from vei.io.scenario import read_scenario
        from vei.sim.timeshift import find_time_shift
        from vei.sweep.evaluator import EngineEvaluator
        from vei.sweep.params import PARAMETERS, POLICY_PARAM, reach_sim, resolve_policy

        checked = []
        for pol in policies:
            value = resolve_policy(pol, "--policy", None)
            checked.append(PARAMETERS[POLICY_PARAM].check(value, "--policy"))
        if len(set(checked)) != len(checked):
            raise ConfigError(f"--policy: a policy is given twice: {', '.join(checked)}")
        if checked and POLICY_PARAM in dict(model.fixed):
            raise ConfigError("the risk spec fixes ego.policy: give --policy or 'fixed', not both")
        path = Path(scenario_dir)
        scenario = read_scenario(path)
        # Every sample's riders enter from beyond the car's reach at the fast end of the
        # sampled cruise speeds (issue 22), and the run configurations say the same.
        recorded = recorded_ego_speed_mps(scenario)
        if not math.isfinite(recorded):  # a car that never moves: the continuations' floor
            recorded = ContinuationConfig().min_ego_speed_mps
        reach = reach_speed_mps(model, recorded)
        evaluator = EngineEvaluator(
            time_shift_reference=model.time_shift_reference,
            base=model.base,
            perception=model.perception,
            v2x=model.v2x,
            sim=reach_sim(reach),
            reconstruction_samples=model.reconstruction_samples,
            sample_seed=model.seed,
        )
        prepared = evaluator.prepare(path)
        rider = scenario.agent(scenario.primary_threat)
        shift = None
        if model.time_shift_reference == "auto":
            shift = find_time_shift(scenario, sim=evaluator.sim)
        from vei.risk.rider_space import recorded_rider_speeds

        space = resolve_space(
            model,
            float(prepared.arrays.ego_median_moving_speed_mps),
            str(rider.category),
            recorded_rider_speeds(scenario, str(rider.agent_id)),
            shift,
        )
        if model.reconstruction_samples:
            import dataclasses

            space = dataclasses.replace(space, notes=(*space.notes, RECON_NOTE))
        return cls(
            path, model, tuple(checked), evaluator, prepared, space, prepared.scenario_id,
            str(rider.agent_id), str(rider.category), shift,
        )  # fmt: skip

    @property
    def policy_names(self) -> tuple[str, ...]:
        """The planners assessed: the --policy values, or the base configuration's."""
        if self.policies:
            return self.policies
        fixed = dict(self.model.fixed)
        if "ego.policy" in fixed:
            return (str(fixed["ego.policy"]),)
        from vei.config import CASE_PRESETS

        return (CASE_PRESETS[self.model.base].policy_name,)

    def variants(self, u: npt.ArrayLike, policy: str | None) -> pd.DataFrame:
        """The variants table of samples u [N, d] for one planner: variant_id, scenario_id,
        variant_index, seed, then the sweep parameters (ego.policy when ``policy``)."""
        from vei.sweep.ids import name_variants
        from vei.sweep.params import PARAMETERS

        params = self.space.to_params(u)
        if policy is not None and self.policies:
            params["ego.policy"] = policy
        order = [c for c in PARAMETERS if c in params.columns]
        order += [c for c in params.columns if c not in order]
        n = len(params)
        head = pd.DataFrame(
            {
                "scenario_id": self.scenario_id,
                "variant_index": np.arange(self._next_index, self._next_index + n, dtype=np.int64),
            }
        )
        self._next_index += n
        rows = pd.concat([head, params[order].reset_index(drop=True)], axis=1)
        return name_variants(rows, self.model.seed)

    def evaluate(
        self, u: npt.ArrayLike, policy: str | None = None, *, stage: str = "mc",
        weights: npt.ArrayLike | None = None,
    ) -> pd.DataFrame:  # fmt: skip
        """Simulate samples u [N, d] under one planner, in engine batches of <= BATCH.

        Args:
            u: standard-normal samples [N, d]. policy: a name of :attr:`policy_names`
                (None: the first). stage: a label stored with the rows (e.g. 'mc',
                'ce-2'). weights: importance weights [N] stored with the rows (1 if None).
        Returns:
            [N rows]: the variants table columns, ``u.<dimension>`` [N], the metrics
            (vei.sweep.evaluator.DEFAULT_METRICS), :data:`OUTCOMES`, stage, policy,
            weight. The rows are also appended to :attr:`log`.
        """
        u = np.atleast_2d(np.asarray(u, dtype=np.float64))
        pol = self.policy_names[0] if policy is None else policy
        parts = []
        for start in range(0, len(u), BATCH):
            chunk = u[start : start + BATCH]
            table = self.variants(chunk, pol)
            metrics = self._metrics(table)
            # the evaluator keeps the row order (equal samples, e.g. in a Sobol design,
            # are equal variants with one id: aligned by position, not by id)
            if not np.array_equal(metrics["variant_id"].to_numpy(), table["variant_id"].to_numpy()):
                raise RuntimeError("the evaluator returned its rows out of order")
            frame = pd.concat(
                [table.reset_index(drop=True), metrics.drop(columns="variant_id")], axis=1
            )
            self._report()
            for j, name in enumerate(self.space.names):
                frame[f"u.{name}"] = chunk[:, j]
            parts.append(frame)
        out = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()
        out = add_outcomes(out, self.model.injury_relevant_speed_mps,
                           only_recorded=self.model.failure_count == "recorded")  # fmt: skip
        out["stage"] = stage
        out["policy"] = pol
        out["weight"] = 1.0 if weights is None else np.asarray(weights, dtype=np.float64)
        self.log.append(out)
        return out

    def _metrics(self, table: pd.DataFrame) -> pd.DataFrame:
        """The evaluator's metrics of a variants table, row for row; variants on a
        reconstruction sample run on that sample's arrays (one batch per sample, put back
        in the table's order: equal variants of a Sobol design keep their positions)."""
        from vei.sweep.evaluator import PreparedScenario
        from vei.sweep.spec import SAMPLE_COLUMN

        if SAMPLE_COLUMN not in table.columns:
            return self.evaluator.evaluate(self.prepared, table)
        pr, parts = self.prepared, []
        ks = table[SAMPLE_COLUMN].to_numpy()
        for k in np.unique(ks):
            at = np.flatnonzero(ks == k)
            one = PreparedScenario(
                pr.scenario_id, pr.path, pr.sample_arrays[int(k)], pr.auto_shift_s
            )
            rows = table.iloc[at].drop(columns=SAMPLE_COLUMN)
            parts.append(self.evaluator.evaluate(one, rows).set_axis(at))
        return pd.concat(parts).sort_index().reset_index(drop=True)

    def _report(self) -> None:
        import time

        now = time.monotonic()
        if self.progress is not None and now - self._last_report >= PROGRESS_S:
            if self._last_report:
                self.progress(f"{self._next_index:,} simulations so far")
            self._last_report = now

    def margin(self, u: npt.ArrayLike, policy: str | None = None, stage: str = "") -> FloatArray:
        """The limit-state values [N] of samples u [N, d] (failure: < 0)."""
        return self.evaluate(u, policy, stage=stage)["margin"].to_numpy(np.float64)

    def samples(self) -> pd.DataFrame:
        """Every evaluated sample so far (one table)."""
        return pd.concat(self.log, ignore_index=True) if self.log else pd.DataFrame()


def add_outcomes(
    frame: pd.DataFrame, injury_relevant_speed_mps: float, *, only_recorded: bool = False
) -> pd.DataFrame:
    """The :data:`OUTCOMES` columns of a metrics table [N rows] (a copy).

    ``seen_too_late`` is read where the table has it (issue 22) and False otherwise.
    ``only_recorded`` (risk spec ``failure: {count: recorded}``): only a collision on the
    primary rider's recorded behaviour (``collision_recorded``) is a failure; the others
    count as misses with margin 0.
    """
    out = frame.copy()
    n = len(out)
    coll = out["collision"].to_numpy(bool) if "collision" in out else np.zeros(n, bool)
    speed = (
        out["impact_speed_mps"].to_numpy(np.float64)
        if "impact_speed_mps" in out
        else np.full(n, np.nan)
    )
    risk = out["injury_risk"].to_numpy(np.float64) if "injury_risk" in out else np.zeros(n)
    gap = out["min_gap_m"].to_numpy(np.float64) if "min_gap_m" in out else np.full(n, np.inf)
    late = (
        out["seen_too_late"].fillna(False).to_numpy(bool)
        if "seen_too_late" in out
        else np.zeros(n, bool)
    )
    fail = coll & ~late
    if only_recorded:
        rec = (
            out["collision_recorded"].fillna(False).to_numpy(bool)
            if "collision_recorded" in out
            else np.zeros(n, bool)
        )
        fail = fail & rec
    out["collision"] = coll
    out["failure"] = fail
    out["no_approach"] = fail & ~np.isfinite(speed)
    out["injury_relevant"] = fail & np.isfinite(speed) & (speed >= injury_relevant_speed_mps)
    out["injury"] = np.where(fail & np.isfinite(risk), risk, 0.0)
    out["seen_too_late"] = late
    out["margin"] = np.where(fail, -1.0, np.maximum(np.nan_to_num(gap, nan=np.inf), 0.0))
    return out
