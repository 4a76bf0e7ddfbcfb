"""The built-in engine as a sweep's evaluator: a variants table -> engine parameters ->
one batch -> one metrics row per variant."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pandas as pd

from vei.calibrate.columns import RIDER_PARAM_COLUMNS
from vei.errors import ConfigError
from vei.sweep.params import POLICY_PARAM, SWEEP_FIELDS, check_aeb_rows
from vei.sweep.spec import SAMPLE_COLUMN


class Evaluator(Protocol):
    """Turns a scenario and a chunk of variants into one metrics row per variant.

    ``prepare(scenario_dir)`` runs once per scenario and worker and returns a picklable
    object (the scenario read and compiled); ``evaluate(prepared, variants)`` takes a
    variants-table slice [B rows] and returns a DataFrame of B rows in the same order with
    a ``variant_id`` column and one column per metric (it must not depend on which other
    variants share the chunk).
    """

    def prepare(self, scenario_dir: Path) -> Any: ...

    def scenario_id(self, prepared: Any) -> str: ...

    def evaluate(self, prepared: Any, variants: pd.DataFrame) -> pd.DataFrame: ...

    def auto_shift_s(self, prepared: Any) -> float | None: ...


#: Metrics a sweep records by default (scalar metrics of vei.metrics, one column each).
DEFAULT_METRICS: tuple[str, ...] = (
    "collision",
    "collision_time_s",
    "safety_index",
    "t_safe_s",
    "t_attention_s",
    "t_alert_s",
    "t_interaction_s",
    "min_gap_m",
    "min_ttc_s",
    "max_drac_mps2",
    "drac_unavoidable",
    "peak_decel_mps2",
    "ego_speed_std_mps",
    "ego_speed_min_mps",
    "impact_speed_mps",
    "delta_v_rider_mps",
    "delta_v_car_mps",
    "impact_side",
    "striking",
    "injury_risk",
    # issue 24: secondary collisions (vei.metrics.secondary)
    "secondary_collision",
    "secondary_collisions",
    "secondary_first",
    "secondary_impact_speed_mps",
    "rear_end_collision",
    # issue 22 / 28.7: could the car have known (flagged runs count apart), and the safety
    # index on the relative-velocity TTC
    "first_seen_gap_m",
    "first_seen_ttc_s",
    "seen_too_late",
    "safety_index_rel",
    # issue 31: where the contacts happened (the rider's recorded behaviour or vei's run-in
    # / run-out of it: vei.metrics.where)
    "contact_where",
    "secondary_where",
    "collision_recorded",
)


#: Categorical sweep parameters: variants sharing them share one base configuration.
_CATEGORICAL = (
    "rider_model",
    "sfm.use_vehicle_force",
    POLICY_PARAM,
    # issue 24: the rider's decisions and the reacting road users switch model branches
    "decision.enabled",
    "traffic.cars_react",
    "traffic.pedestrians",
)


#: Float sweep parameter (results column) -> VariantParams field: the sweepable settings
#: (vei.config.settings, via sweep_params.SWEEP_FIELDS; sfm.k_des_nspm is scaled by
#: k_des_factor) and a population rider's (RIDER_PARAM_COLUMNS). [H4: derived from the
#: settings' declarations, was spelled out from CONFIG_FIELDS / POLICY_PARAMS here]
_PARAM_FIELDS: dict[str, str] = {**SWEEP_FIELDS, **RIDER_PARAM_COLUMNS}


#: Columns of a destination gain (scaled by the configuration's k_des_factor).
_K_DES_COLUMNS = ("sfm.k_des_nspm", "rider.k_des_nspm")


@dataclass(frozen=True)
class PreparedScenario:
    """A scenario compiled for the engine (picklable; shared by every chunk).

    Attributes:
        scenario_id: its id. path: its folder. arrays: vei.sim.state.ScenarioArrays.
        auto_shift_s: the automatic time shift [s] (None unless the reference is 'auto').
        sample_arrays: one ScenarioArrays per posterior sample of the primary rider's
            trajectory (``reconstruction: {samples: N}``; empty otherwise).
    """

    scenario_id: str
    path: str
    arrays: Any
    auto_shift_s: float | None
    sample_arrays: tuple = ()


def variant_params(
    variants: pd.DataFrame,
    arrays: Any,
    *,
    base: str = "normal-cap",
    time_shift_reference: str = "auto",
    auto_shift_s: float | None = None,
    perception: Any = None,
    v2x: Any = None,
) -> Any:
    """The engine's per-variant parameters ([B] arrays) of a variants table, vectorised.

    Rows are grouped by their categorical parameters (rider model, vehicle force, policy:
    at most 24 groups); each group starts from the run configuration that
    :func:`vei.sweep.spec.variant_config` gives it and takes the float
    parameters as [B_g] overrides. The result equals, row by row, the parameters of the
    row's own run configuration (what ``vei run --config`` runs; a test checks this).

    Args:
        variants: [B] rows of a variants table (parameter columns by dotted name).
        arrays: the scenario's ``vei.sim.state.ScenarioArrays``.
        base, time_shift_reference: of the sweep spec.
        auto_shift_s: the scenario's automatic shift [s] (reference 'auto').
        perception: the spec's sensor model (PerceptionConfig) for every variant; None:
            the base configuration's.
        v2x: the spec's V2X (V2XConfig) for every variant; None: the base's (off).

    Returns:
        ``vei.sim.state.VariantParams`` with B variants in row order (labels = variant ids).

    Raises:
        ConfigError: a variant's configuration is invalid (e.g. a_min beyond the brake,
            AEB thresholds out of order).
    """
    from vei.sim.state import VariantParams
    from vei.sweep.spec import SweepSpec, variant_config

    check_aeb_rows(variants, base)

    probe = SweepSpec(
        design="grid",
        parameters=(),
        time_shift_reference=time_shift_reference,
        base=base,
        perception=perception,
        v2x=v2x,
    )
    b = len(variants)
    cats = [c for c in _CATEGORICAL if c in variants.columns]
    keys = (
        variants[cats].astype(str).agg("|".join, axis=1).to_numpy()
        if cats
        else np.zeros(b, dtype=object)
    )
    pieces, order = [], []
    for key in dict.fromkeys(keys):
        idx = np.flatnonzero(keys == key)
        first = variants.iloc[idx[0]]
        cat_params = {c: first[c] for c in cats}
        case = variant_config(cat_params, probe, auto_shift_s=auto_shift_s or 0.0).case
        grp = variants.iloc[idx]
        overrides: dict[str, np.ndarray] = {}
        for col, fname in _PARAM_FIELDS.items():
            if col in grp.columns:
                v = grp[col].to_numpy(np.float64)
                if col in _K_DES_COLUMNS:
                    v = v * case.sfm.k_des_factor
                overrides[fname] = v
        if "v0_mps" in overrides and case.sfm.speed_from_recording:
            # A swept or sampled v0 is the rider's own (as in variant_config).
            case = replace(case, sfm=replace(case.sfm, speed_from_recording=False))
        if case.ego_mode == "cap":
            a_min = overrides.get("a_min_mps2", np.array([case.cap.a_min_mps2]))
            if np.any(-a_min > case.ego.max_decel_mps2):
                raise ConfigError(
                    f"cap.a_min_mps2 below -ego.max_decel_mps2 ({-case.ego.max_decel_mps2}): "
                    "the CAP would demand more than the car's full brake"
                )
        offset = (
            grp["time_shift_s"].to_numpy(np.float64)
            if "time_shift_s" in grp
            else np.zeros(len(idx))
        )
        shift = offset + (float(auto_shift_s or 0.0) if time_shift_reference == "auto" else 0.0)
        if time_shift_reference == "auto" and auto_shift_s is None:
            raise ConfigError("time_shift_reference 'auto' needs the scenario's automatic shift")
        p = VariantParams.from_case(case, arrays, len(idx), time_shift_s=shift, **overrides)
        pieces.append(p.with_values(labels=grp["variant_id"].to_numpy(object)))
        order.append(idx)
    params = VariantParams.concat(pieces)
    perm = np.concatenate(order)
    inverse = np.empty(b, dtype=np.intp)
    inverse[perm] = np.arange(b)
    return params if np.array_equal(perm, np.arange(b)) else params.take(inverse)


class EngineEvaluator:
    """Evaluates sweep chunks with the built-in batched engine and the metrics registry.

    Args:
        time_shift_reference: 'auto' or 'zero' (of the sweep spec).
        base: the spec's base configuration name.
        sim: engine settings (default: SimConfig(), 20 Hz over the scenario's span).
        metrics: scalar metric names (vei.metrics) to record per variant.
        reconstruction_samples: N posterior samples of the primary rider's trajectory
            (:func:`vei.recon.samples.sample_rider`, drawn with ``sample_seed``); variants
            carry the sample they run on in column SAMPLE_COLUMN. None: mean trajectory.
        perception: the spec's sensor model (PerceptionConfig) for every variant; None:
            the base configuration's.
        v2x: the spec's V2X (V2XConfig) for every variant; None: the base's (off).
    """

    def __init__(
        self,
        time_shift_reference: str = "auto",
        base: str = "normal-cap",
        sim: Any = None,
        metrics: Sequence[str] = DEFAULT_METRICS,
        reconstruction_samples: int | None = None,
        sample_seed: int = 0,
        perception: Any = None,
        v2x: Any = None,
    ) -> None:
        from vei.config import SimConfig

        self.reconstruction_samples = reconstruction_samples
        self.perception = perception
        self.v2x = v2x
        self.sample_seed = sample_seed
        self.time_shift_reference = time_shift_reference
        self.base = base
        self.sim = sim if sim is not None else SimConfig()
        self.metrics = tuple(metrics)

    def prepare(self, scenario_dir: Path) -> PreparedScenario:
        """Read the scenario, compile its arrays, and find its automatic time shift."""
        from vei.io.scenario import read_scenario
        from vei.sim.state import prepare_scenario

        scenario = read_scenario(scenario_dir)
        arrays = prepare_scenario(scenario, self.sim)
        auto = None
        if self.time_shift_reference == "auto":
            from vei.sim.timeshift import find_time_shift

            auto = float(find_time_shift(scenario, sim=self.sim).time_shift_s)
        sample_arrays: tuple = ()
        if self.reconstruction_samples:
            from vei.recon.samples import sample_rider, scenario_with_sample

            draws = sample_rider(scenario, self.reconstruction_samples, self.sample_seed)
            sample_arrays = tuple(
                prepare_scenario(scenario_with_sample(scenario, draws, k), self.sim)
                for k in range(draws.n_samples)
            )
        return PreparedScenario(scenario.id, str(scenario_dir), arrays, auto, sample_arrays)

    def params(self, prepared: PreparedScenario, arrays: Any, variants: pd.DataFrame) -> Any:
        """The engine parameters (VariantParams [B]) of ``variants`` [B rows] on ``arrays``
        (``prepared.arrays`` or one of its reconstruction samples' arrays), with this
        evaluator's base configuration, time-shift reference and perception."""
        return variant_params(
            variants,
            arrays,
            base=self.base,
            time_shift_reference=self.time_shift_reference,
            auto_shift_s=prepared.auto_shift_s,
            perception=self.perception,
            v2x=self.v2x,
        )

    def score(self, result: Any, params: Any) -> pd.DataFrame:
        """This evaluator's metrics [B rows] of a full recording ``result`` (SimResult),
        scored as a run's time series is (vei run, vei casestudy) with each variant's rider
        mass [kg] and full brake [m/s^2] from ``params``."""
        from vei.metrics import sensor_params, summarize
        from vei.metrics.timeseries import as_timeseries_trace

        trace = as_timeseries_trace(result.to_trace())
        run_params = {
            "rider_mass_kg": params.mass_kg,
            "ego_max_decel_mps2": params.max_decel_mps2_ego,
            **sensor_params(list(params.perception)),
        }
        return summarize(trace, names=self.metrics, params=run_params)

    def warm_up(self, load_kernel: bool = False) -> None:
        """Import the modules :meth:`evaluate` and a part file's writer need (a sweep's
        pool workers call it while their parent prepares the scenario).

        Args:
            load_kernel: also load the compiled kernel's machine code (~0.3 s, paid by the
                first chunk otherwise) by scoring one variant of a small synthetic scene
                (:func:`vei.sim.testing.crossing_scenario`): for a forked worker, which
                has nothing else to do meanwhile.
        """
        import pyarrow.parquet  # noqa: F401

        import vei.metrics.timeseries  # noqa: F401
        import vei.sim.engine  # noqa: F401
        from vei.sim import kernel

        if not kernel.available():
            return
        import vei.metrics.fused  # noqa: F401
        from vei.sim.engine import kernel_metrics

        kernel._build()
        if load_kernel and all(n in kernel_metrics() for n in self.metrics):
            from vei.config import case_preset
            from vei.sim.engine import simulate_metrics
            from vei.sim.state import VariantParams, prepare_scenario
            from vei.sim.testing import crossing_scenario

            arrays = prepare_scenario(crossing_scenario(), self.sim)
            one = VariantParams.from_case(case_preset("normal-cap"), arrays, 1)
            if kernel.is_cold(kernel.features_of(arrays, one, True)):
                return  # never compile here: a run compiles what it uses, once
            simulate_metrics(arrays, one, names=self.metrics, kernel=self.sim.kernel)

    def scenario_id(self, prepared: PreparedScenario) -> str:
        """The scenario's id."""
        return prepared.scenario_id

    def auto_shift_s(self, prepared: PreparedScenario) -> float | None:
        """The scenario's automatic time shift [s] (None for reference 'zero')."""
        return prepared.auto_shift_s

    def evaluate(self, prepared: PreparedScenario, variants: pd.DataFrame) -> pd.DataFrame:
        """Simulate ``variants`` [B rows] as one batch; one metrics row per variant.

        Returns a DataFrame: variant_id, time_shift_applied_s (the absolute shift [s]),
        then ``self.metrics`` columns (collision bool, the others float). Variants with a
        SAMPLE_COLUMN run on that sample's arrays (one batch per sample).
        """
        from vei.sim.engine import kernel_metrics, simulate, simulate_metrics

        if SAMPLE_COLUMN in variants.columns and prepared.sample_arrays:
            parts = []
            for k, grp in variants.groupby(SAMPLE_COLUMN, sort=False):
                one = PreparedScenario(
                    prepared.scenario_id,
                    prepared.path,
                    prepared.sample_arrays[int(k)],
                    prepared.auto_shift_s,
                )
                parts.append(self.evaluate(one, grp.drop(columns=SAMPLE_COLUMN)))
            out = pd.concat(parts, ignore_index=True).set_index("variant_id")
            return out.loc[variants["variant_id"].to_numpy()].reset_index()

        params = self.params(prepared, prepared.arrays, variants)
        # Scored as a run's time series is (vei run, vei casestudy): bit-identical metrics,
        # with the variant's rider mass and full brake (delta-v, DRAC ceiling) as in vei run.
        if all(name in kernel_metrics() for name in self.metrics):
            # in the compiled kernel's pass, no [B, T] series (policy variants and the
            # NumPy kernel: recorded in sub-batches and summarized; same rows)
            summary = simulate_metrics(
                prepared.arrays, params, names=self.metrics, kernel=self.sim.kernel
            )
        else:
            result = simulate(prepared.arrays, params, record="full", kernel=self.sim.kernel)
            summary = self.score(result, params)
        summary.insert(0, "time_shift_applied_s", params.time_shift_s)
        summary.insert(0, "variant_id", variants["variant_id"].to_numpy())
        return summary.reset_index(drop=True)
