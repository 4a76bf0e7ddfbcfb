"""Per-variant parameters of the built-in engine: every field an array ``[B]``."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from vei.config import AUTO, MAX_RUN_UP_M, MEDIAN_MOVING, CaseConfig
from vei.config.settings import BY_FIELD, SETTINGS, config_value
from vei.errors import ConfigError, InputError
from vei.sim.tables import TimeTable, recorded_column


class SceneDefaults(Protocol):
    """What :meth:`VariantParams.from_case` reads of a scenario to resolve its defaults.

    :class:`vei.sim.state.ScenarioArrays` has these attributes (a protocol, so that this
    module does not import the one that imports it).
    """

    @property
    def scenario_id(self) -> str:
        """The scenario's id (for messages)."""

    @property
    def ego_speed0_mps(self) -> float:
        """Recorded ego speed at t = 0 [m/s]."""

    @property
    def ego_median_moving_speed_mps(self) -> float:
        """Median recorded ego speed while moving [m/s] (NaN when it never moves)."""

    @property
    def conflict_s_m(self) -> float:
        """Arc length [m] along the ego's path of its point nearest to the rider's path."""

    @property
    def rider_track(self) -> TimeTable:
        """The rider's recording on a uniform time grid (column speed_mps used)."""


FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Ego modes (int8 codes of VariantParams.ego_mode); 3 = a policy on the API (vei.policy).
EGO_REPLAY_SPEED, EGO_PID, EGO_CAP, EGO_POLICY = 0, 1, 2, 3
EGO_MODE_CODES: dict[str, int] = {
    "replay-speed": EGO_REPLAY_SPEED,
    "pid": EGO_PID,
    "cap": EGO_CAP,
    "policy": EGO_POLICY,
}

# --------------------------------------------------------------------------------------
# Per-variant parameters
# --------------------------------------------------------------------------------------
_BOOL_FIELDS = tuple(s.field for s in SETTINGS if s.kind == "bool")
_INT_FIELDS = tuple(s.field for s in SETTINGS if s.kind == "int")
_OBJECT_FIELDS = tuple(s.field for s in SETTINGS if s.kind == "object")


@dataclass(frozen=True)
class VariantParams:
    """Per-variant parameters, every field an array ``[B]`` (float64 unless noted).

    Build with :meth:`from_case` (a configuration broadcast to B variants, with optional
    per-variant overrides), :meth:`concat` (stack several) or directly.

    Attributes:
        One per engine setting, declared in :data:`vei.config.settings.SETTINGS` (same
        names, same order): its unit, bounds (checked here, messages naming the run-config
        path), the run-config field it comes from and how (:meth:`from_case`), and what it
        is. Bools are bool arrays, ``ego_mode`` int8 (:data:`EGO_MODE_CODES`), ``policy``
        (the vei.policy instance of each variant where ego_mode == 3, else None; variants
        sharing one instance share one block, the engine calls its ``bind`` with the
        block's parameters), ``perception`` (the enabled PerceptionConfig of each policy
        variant, else None) and ``labels`` (configuration names) object arrays.
    """

    time_shift_s: FloatArray
    rider_sfm: BoolArray
    k_des_nspm: FloatArray
    a_veh_n: FloatArray
    b_veh_per_m: FloatArray
    v0_mps: FloatArray
    mass_kg: FloatArray
    sigma_m: FloatArray
    lookahead_m: FloatArray
    arrive_radius_m: FloatArray
    use_vehicle_force: BoolArray
    paper_vdes: BoolArray
    front_bumper: BoolArray
    max_speed_mps: FloatArray
    max_accel_mps2: FloatArray
    ego_mode: npt.NDArray[np.int8]
    cruise_speed_mps: FloatArray
    initial_speed_mps: FloatArray
    ego_start_s_m: FloatArray
    kp: FloatArray
    ki: FloatArray
    kd: FloatArray
    integral_limit: FloatArray
    integral_window_s: FloatArray
    max_accel_mps2_ego: FloatArray
    max_decel_mps2_ego: FloatArray
    actuator_lag_s: FloatArray
    t_safe_s: FloatArray
    d_buf_m: FloatArray
    a_min_mps2: FloatArray
    corridor_half_width_m: FloatArray
    detection_range_m: FloatArray
    release_margin_m: FloatArray
    recover_tolerance_mps: FloatArray
    paper_per_step: BoolArray
    perception_delay_s: FloatArray
    speed_from_recording: BoolArray
    a_rider_n: FloatArray
    b_rider_per_m: FloatArray
    use_rider_force: BoolArray
    obstacle_braking: BoolArray
    obstacle_decel_mps2: FloatArray
    obstacle_margin_m: FloatArray
    obstacle_speed_mps: FloatArray
    policy: npt.NDArray[np.object_]
    perception: npt.NDArray[np.object_]
    v2x: npt.NDArray[np.object_]
    v2x_penetration_rate: FloatArray
    v2x_latency_s: FloatArray
    v2x_latency_jitter_s: FloatArray
    v2x_pdr_factor: FloatArray
    v2x_position_error_std_m: FloatArray
    v2x_clock_offset_s: FloatArray
    aeb_ttc_warning_s: FloatArray
    aeb_ttc_partial_s: FloatArray
    aeb_ttc_full_s: FloatArray
    aeb_partial_decel_mps2: FloatArray
    aeb_full_decel_mps2: FloatArray
    idm_max_accel_mps2: FloatArray
    idm_comfort_decel_mps2: FloatArray
    idm_time_headway_s: FloatArray
    idm_min_gap_m: FloatArray
    idm_delta: FloatArray
    decide: BoolArray
    critical_gap_s: FloatArray
    decision_horizon_s: FloatArray
    yield_decel_mps2: FloatArray
    stop_margin_m: FloatArray
    clear_margin_m: FloatArray
    cars_react: BoolArray
    car_v0_mps: FloatArray
    car_headway_s: FloatArray
    car_min_gap_m: FloatArray
    car_accel_mps2: FloatArray
    car_decel_mps2: FloatArray
    car_delta: FloatArray
    car_max_decel_mps2: FloatArray
    car_reaction_s: FloatArray
    car_trigger_mps2: FloatArray
    peds_sfm: BoolArray
    ped_tau_s: FloatArray
    ped_a_n: FloatArray
    ped_b_m: FloatArray
    ped_mass_kg: FloatArray
    ped_lambda: FloatArray
    ped_radius_m: FloatArray
    ped_vehicle_range_m: FloatArray
    labels: npt.NDArray[np.object_]

    def __post_init__(self) -> None:
        b = None
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not isinstance(v, np.ndarray) or v.ndim != 1:
                raise ConfigError(f"VariantParams.{f.name} must be a 1-D array [B]")
            if b is None:
                b = v.shape[0]
            elif v.shape[0] != b:
                raise ConfigError(f"VariantParams.{f.name} has {v.shape[0]} entries, expected {b}")
            if v.dtype.kind == "f" and not np.all(np.isfinite(v) | np.isposinf(v)):
                raise ConfigError(f"VariantParams.{f.name} has NaN or -inf values")
        if b == 0:
            raise ConfigError("VariantParams needs at least one variant")
        for s in SETTINGS:  # the declared bounds (vei.config.settings)
            v = getattr(self, s.field)
            where = f"VariantParams.{s.field}" + (f" ({s.path})" if s.path else "")
            if s.kind == "float" and not s.allows_inf and np.any(np.isposinf(v)):
                raise ConfigError(f"{where} must be finite")
            if s.bounds_text() and np.any(s.outside(v)):
                raise ConfigError(f"{where} must be {s.bounds_text()}")
        has_policy = np.array([p is not None for p in self.policy], dtype=bool)
        if np.any(has_policy != (self.ego_mode == EGO_POLICY)):
            raise ConfigError(
                "VariantParams.policy must be set exactly where ego_mode == 3 (policy)"
            )
        if any(
            q is not None and m != EGO_POLICY
            for q, m in zip(self.perception, self.ego_mode, strict=True)
        ):
            raise ConfigError(
                "VariantParams.perception applies to policy variants (ego_mode 3) only"
            )
        if any(
            q is not None and m != EGO_POLICY for q, m in zip(self.v2x, self.ego_mode, strict=True)
        ):
            raise ConfigError("VariantParams.v2x applies to policy variants (ego_mode 3) only")

    @property
    def batch_size(self) -> int:
        """B, the number of variants."""
        return int(self.time_shift_s.shape[0])

    @classmethod
    def from_case(
        cls,
        case: CaseConfig,
        arrays: SceneDefaults,
        batch_size: int = 1,
        *,
        time_shift_s: npt.ArrayLike = 0.0,
        **overrides: npt.ArrayLike,
    ) -> VariantParams:
        """B copies of one configuration, with optional per-variant overrides.

        The cruise speed 'median-moving' resolves to the scenario's median moving speed;
        initial_speed 'cruise' to v_d, 'recorded' to the recorded speed at t = 0 (the
        replay-speed mode always starts from the recorded speed).

        Args:
            case: the configuration. arrays: the scenario's arrays (a ScenarioArrays; for
                resolved defaults).
            batch_size: B. time_shift_s: scalar or [B] [s].
            overrides: any field of VariantParams, scalar or [B] (e.g. cruise_speed_mps=
                np.linspace(4, 8, B)). An overridden cruise_speed_mps also sets
                initial_speed_mps when the case starts at cruise and it is not overridden.
        Returns:
            VariantParams with B variants.
        """
        sfm, ego = case.sfm, case.ego
        # An enabled sensor model (or V2X) runs every closed-loop controller on the policy API.
        with_v2x = bool(case.v2x.enabled) and case.ego_mode != "replay-speed"
        perceived = (
            case.perception is not None
            and bool(case.perception.enabled)
            and case.ego_mode != "replay-speed"
        ) or with_v2x
        if ego.cruise_speed_mps == MEDIAN_MOVING:
            vd = arrays.ego_median_moving_speed_mps
            if not math.isfinite(vd):
                raise InputError(
                    "cannot derive the cruise speed: the recorded ego never moves; set ego.cruise_speed_mps",
                    path=f"scenario {arrays.scenario_id}",
                    field="cruise_speed_mps",
                )
        else:
            vd = float(ego.cruise_speed_mps)
        v_init: Any
        if case.ego_mode == "replay-speed" or ego.initial_speed == "recorded":
            v_init = arrays.ego_speed0_mps
        else:
            v_init = overrides.get("cruise_speed_mps", vd)
        if ego.run_up_m == AUTO:
            # Per variant: the cruise speed may be overridden per variant (sweeps).
            v_cruise = np.asarray(overrides.get("cruise_speed_mps", vd), dtype=np.float64)
            run_up_m: Any = np.clip(
                v_cruise * ego.approach_time_s - arrays.conflict_s_m, 0.0, MAX_RUN_UP_M
            )
        else:
            run_up_m = float(ego.run_up_m)
        inf = math.inf
        v0, vmax = sfm.v0_mps, sfm.max_speed_mps
        if sfm.speed_from_recording:  # calibrated rider: speeds from its own recording
            from vei.models.sfm import speed_from_recording

            tr = arrays.rider_track
            moving = getattr(arrays, "rider_moving_speeds_mps", None)  # outside its waits
            v0, vmax = speed_from_recording(
                moving
                if moving is not None
                else recorded_column(
                    tr, "speed_mps", getattr(arrays, "rider_recorded_span_s", (-math.inf, math.inf))
                ),
                sfm.lookahead_m,
                sfm.sigma_m,
                v0,
                vmax,
            )
        # Every declared setting read from the configuration (vei.config.settings), then
        # those derived from the scenario, the run or the policy.
        base: dict[str, Any] = {
            s.field: config_value(s, case)
            for s in SETTINGS
            if s.convert not in ("derived", "policy_param")
        }
        base.update(
            {
                "time_shift_s": time_shift_s,
                "v0_mps": v0,
                "max_speed_mps": inf if vmax is None else vmax,
                "ego_mode": EGO_MODE_CODES["policy" if perceived else case.ego_mode],
                "cruise_speed_mps": vd,
                "initial_speed_mps": v_init,
                "ego_start_s_m": 0.0 if case.ego_mode == "replay-speed" else -run_up_m,
                "policy": _case_policy(case, perceived),
                "perception": case.perception
                if perceived and case.perception is not None and case.perception.enabled
                else None,
                "v2x": case.v2x if with_v2x else None,
                **_policy_param_values(case),
            }
        )
        missing = set(BY_FIELD) - set(base)
        if missing:  # pragma: no cover - a setting declared without its conversion here
            raise ConfigError(f"from_case sets no value for {', '.join(sorted(missing))}")
        unknown = set(overrides) - set(base)
        if unknown:
            raise ConfigError(f"unknown VariantParams field(s): {', '.join(sorted(unknown))}")
        base.update(overrides)
        return cls._broadcast(base, batch_size)

    @classmethod
    def _broadcast(cls, values: dict[str, Any], batch_size: int) -> VariantParams:
        out: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            v = values[f.name]
            if f.name in _OBJECT_FIELDS:
                arr = np.empty(batch_size, dtype=object)
                if isinstance(v, np.ndarray) and v.ndim == 1:
                    arr[:] = list(v)
                elif isinstance(v, list | tuple):
                    arr[:] = list(v)
                else:
                    arr.fill(v)
            elif f.name in _BOOL_FIELDS:
                arr = np.broadcast_to(np.asarray(v, dtype=bool), (batch_size,)).copy()
            elif f.name in _INT_FIELDS:
                arr = np.broadcast_to(np.asarray(v, dtype=np.int8), (batch_size,)).copy()
            else:
                arr = np.broadcast_to(np.asarray(v, dtype=np.float64), (batch_size,)).copy()
            out[f.name] = arr
        return cls(**out)

    @classmethod
    def _of_checked(cls, values: dict[str, Any]) -> VariantParams:
        """A VariantParams of rows of checked ones (take / concat): every field a 1-D
        array of the same B >= 1, every value from a checked VariantParams, so not checked
        again (the checks cost ~1 ms per call, several calls per sweep chunk)."""
        sizes = {v.shape[0] if v.ndim == 1 else -1 for v in values.values()}
        if len(sizes) != 1 or sizes & {0, -1}:
            return cls(**values)  # the checks say what is wrong (B = 0, an index of ndim 2)
        out = object.__new__(cls)
        for name, v in values.items():
            object.__setattr__(out, name, v)
        return out

    @classmethod
    def concat(cls, parts: Sequence[VariantParams]) -> VariantParams:
        """Stack several VariantParams along the batch axis (in order)."""
        if not parts:
            raise ConfigError("concat needs at least one VariantParams")
        return cls._of_checked(
            {
                f.name: np.concatenate([getattr(p, f.name) for p in parts])
                for f in dataclasses.fields(cls)
            }
        )

    def take(self, index: npt.ArrayLike) -> VariantParams:
        """The variants at ``index`` (int array, slice or bool mask) as a new VariantParams."""
        if isinstance(index, slice):
            return self._of_checked(
                {f.name: getattr(self, f.name)[index].copy() for f in dataclasses.fields(self)}
            )
        idx = np.atleast_1d(np.asarray(index))
        return self._of_checked(
            {f.name: getattr(self, f.name)[idx] for f in dataclasses.fields(self)}
        )

    def with_values(self, **values: npt.ArrayLike) -> VariantParams:
        """A copy with some fields replaced (scalars or [B] arrays, broadcast)."""
        current = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        unknown = set(values) - set(current)
        if unknown:
            raise ConfigError(f"unknown VariantParams field(s): {', '.join(sorted(unknown))}")
        current.update(values)
        return VariantParams._broadcast(current, self.batch_size)

    def delay_steps(self, dt_s: float) -> npt.NDArray[np.intp]:
        """Perception delay in whole engine steps [B] (rounded to nearest)."""
        return np.rint(self.perception_delay_s / dt_s).astype(np.intp)


def _case_policy(case: CaseConfig, perceived: bool = False) -> Any:
    """The policy instance of a configuration with ego_mode 'policy' (or any closed-loop
    one with perception enabled), else None."""
    if case.ego_mode != "policy" and not perceived:
        return None
    from vei.policy.load import load_policy

    return load_policy(case.policy_name, case.ego.policy_params)


def _policy_configs() -> dict[str, type]:
    """The built-in policies' parameter classes: name -> AEBConfig / IDMConfig."""
    from vei.policy.aeb import AEBConfig
    from vei.policy.idm import IDMConfig

    return {"aeb": AEBConfig, "idm": IDMConfig}


def _policy_param_values(case: CaseConfig) -> dict[str, float]:
    """The aeb_* / idm_* VariantParams values of a configuration (the declared
    'policy_param' settings): its ego.policy_params for the built-in 'aeb' / 'idm' it runs,
    the policy configuration's defaults for the others."""
    name = case.policy_name
    cfgs: dict[str, Any] = {}
    for pol, cls in _policy_configs().items():
        try:
            cfgs[pol] = cls(**(case.ego.policy_params or {})) if pol == name else cls()
        except TypeError as exc:
            raise ConfigError(f"ego.policy_params of {name!r}: {exc}") from None
    return {
        s.field: float(getattr(cfgs[str(s.policy)], str(s.config_field)))
        for s in SETTINGS
        if s.convert == "policy_param"
    }


def __getattr__(name: str) -> Any:
    """``POLICY_PARAM_DEFAULTS``: VariantParams field -> default of every built-in
    policy's parameter (from AEBConfig / IDMConfig, read when asked)."""
    if name == "POLICY_PARAM_DEFAULTS":
        return _policy_param_values(CaseConfig(name="defaults"))
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
