"""The engine's settings, each declared once (:data:`SETTINGS`).

One :class:`Setting` per field of the engine's per-variant parameters
(:class:`vei.sim.params.VariantParams`, same names, same order) says its unit, its bounds,
where it lives in the run configuration (``cap.t_safe_s``: the field ``t_safe_s`` of the
case's ``cap`` section), how the configuration's value becomes the engine's (identity, or
a named conversion), a one-line description, whether a sweep may vary it and whether it is
a row of the compiled kernel's parameter matrix. Derived from it:

- the run configuration's checks of those fields (:func:`check_section`, called by the
  dataclasses of :mod:`vei.config.models`);
- ``VariantParams``' validation (bounds, messages naming the run-config path), its dtypes
  and :meth:`~vei.sim.params.VariantParams.from_case`'s mapping (:func:`config_value`);
- the kernel's parameter rows (:data:`vei.sim.kernel.layout.PARAM_FIELDS`, ``P_*``);
- the sweep parameters (:data:`vei.sweep.params.PARAMETERS`: the name is the
  run-config path; unit, bounds, description; the renamed spellings) and the parameter
  table of docs/sweeps.md.

Adding a setting: its model, one :class:`Setting` here, the field of that name in
``VariantParams`` and in its configuration section (tests/config/test_settings.py checks that the
three agree), and the kernel where the model is compiled.

Imports nothing of vei but errors (a configuration module: see DESIGN.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

from vei.errors import ConfigError

Kind = Literal["float", "bool", "int", "object"]
#: How the run configuration's value becomes the engine's:
#: identity: the value itself; times_k_des_factor: value x ``sfm.k_des_factor``;
#: none_is_inf: None -> +inf (no limit); equals: ``value == Setting.equals`` (a bool);
#: median_moving: the value, or the recorded ego's median moving speed for
#: 'median-moving'; policy_param: the built-in policy's parameter (``Setting.policy``'s
#: config, its default for any other policy); derived: computed by
#: ``VariantParams.from_case`` from several fields, the scenario or the run (see doc);
#: none_is_default: the value, or for None the section's ``default_for(field)`` (e.g. a
#: V2X technology's latency).
Convert = Literal[
    "identity", "times_k_des_factor", "none_is_inf", "equals", "median_moving",
    "policy_param", "derived", "none_is_default",
]  # fmt: skip
#: Conversions whose engine value is the configuration's number in the same unit (or +inf
#: for None): the declared bounds are the configuration field's bounds too.
NUMERIC_CONVERTS = (
    "identity", "times_k_des_factor", "none_is_inf", "median_moving", "none_is_default",
)  # fmt: skip
#: The run configuration's sections that hold settings (fields of CaseConfig).
SECTIONS = ("sfm", "ego", "cap", "decision", "traffic", "v2x")


@dataclass(frozen=True)
class Setting:
    """One engine setting.

    Attributes:
        field: its VariantParams field ([B] array).
        path: the run configuration's field it comes from, relative to the case
            (``section.field`` or a CaseConfig field, e.g. ``rider``); for a built-in
            policy's parameter ``ego.policy_params.<field>``; None = not from the case.
        unit: physical unit ('s', 'm/s', 'N s/m', ...; '-' = dimensionless; 'bool',
            'code' (int8) and 'object' for the non-numbers).
        doc: one line on what it is (the sweep's and the docs' description).
        kind: numpy kind of the [B] array: float64, bool, int8 or object.
        lower, upper: bounds (None = none); ``lower_open`` / ``upper_open``: the bound itself
            is excluded.
        convert: how the run configuration's value becomes the engine's (:data:`Convert`).
        equals: the configuration value that makes an 'equals' setting True.
        policy: the built-in policy owning a 'policy_param' setting ('aeb', 'idm').
        sweep: a sweep may vary it under the name ``path``.
        kernel: a row of the compiled kernel's parameter matrix P.
        former: earlier spellings of its sweep name (refused naming ``path``).
    """

    field: str
    path: str | None
    unit: str
    doc: str
    kind: Kind = "float"
    lower: float | None = None
    upper: float | None = None
    lower_open: bool = False
    upper_open: bool = False
    convert: Convert = "identity"
    equals: str | None = None
    policy: str | None = None
    sweep: bool = False
    kernel: bool = True
    former: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.field.isidentifier():
            raise ConfigError(f"setting {self.field!r}: not an identifier")
        if (self.convert == "equals") != (self.equals is not None):
            raise ConfigError(f"setting {self.field}: 'equals' goes with convert 'equals'")
        if (self.convert == "policy_param") != (self.policy is not None):
            raise ConfigError(f"setting {self.field}: 'policy' goes with convert 'policy_param'")
        if self.path is None and self.convert != "derived":
            raise ConfigError(f"setting {self.field}: only a derived setting has no path")
        if self.kind in ("bool", "object") and (self.lower, self.upper) != (None, None):
            raise ConfigError(f"setting {self.field}: bounds need a number")
        if self.kind == "object" and self.kernel:
            raise ConfigError(f"setting {self.field}: an object is no kernel row")
        if self.sweep and (self.path is None or self.kind == "int"):
            raise ConfigError(f"setting {self.field}: a sweep parameter needs a path")
        if self.lower is not None and self.upper is not None and self.lower > self.upper:
            raise ConfigError(f"setting {self.field}: lower > upper")

    @property
    def section(self) -> str | None:
        """The configuration section of ``path`` ('sfm', 'ego', 'cap'), None for a CaseConfig
        field or no path."""
        if self.path is None or "." not in self.path:
            return None
        return self.path.split(".", 1)[0]

    @property
    def config_field(self) -> str | None:
        """The last part of ``path``: the field's name in its configuration class."""
        return None if self.path is None else self.path.rsplit(".", 1)[-1]

    @property
    def allows_inf(self) -> bool:
        """+inf is a value of the engine's array (None = no limit)."""
        return self.convert == "none_is_inf"

    def bounds_text(self) -> str:
        """The bounds as text: '> 0', '>= 0', '< 0', 'in [-250, 0]', '' (none)."""
        lo, hi = self.lower, self.upper
        if lo is not None and hi is not None:
            left, right = "(" if self.lower_open else "[", ")" if self.upper_open else "]"
            return f"in {left}{lo:g}, {hi:g}{right}"
        if lo is not None:
            return f"{'>' if self.lower_open else '>='} {lo:g}"
        if hi is not None:
            return f"{'<' if self.upper_open else '<='} {hi:g}"
        return ""

    def outside(self, value: Any) -> Any:
        """True where ``value`` (a number or a numpy array) breaks the bounds (NaN too)."""
        bad = value != value  # NaN
        if self.lower is not None:
            bad = bad | (value < self.lower) | ((value == self.lower) & self.lower_open)
        if self.upper is not None:
            bad = bad | (value > self.upper) | ((value == self.upper) & self.upper_open)
        return bad


def _f(field: str, path: str | None, unit: str, doc: str, **kw: Any) -> Setting:
    return Setting(field, path, unit, doc, **kw)


def _b(field: str, path: str, doc: str, **kw: Any) -> Setting:
    return Setting(field, path, "bool", doc, kind="bool", **kw)


_POS = {"lower": 0.0, "lower_open": True}  # > 0
_NONNEG = {"lower": 0.0}  # >= 0
_DERIVED = {"convert": "derived"}

#: Every engine setting, in the field order of VariantParams.
SETTINGS: tuple[Setting, ...] = (
    _f("time_shift_s", None, "s", "time shift of the primary rider (the run's time_shift; "
       "positive = the rider comes later)", **_DERIVED),
    _b("rider_sfm", "rider", "social-force rider (rider: sfm), else kinematic replay",
       convert="equals", equals="sfm"),
    _f("k_des_nspm", "sfm.k_des_nspm", "N s/m", "desired-velocity gain k_des before the "
       "configuration's k_des_factor: the engine's gain is this x 1 (normal) or x 2 "
       "(aggressive presets)", convert="times_k_des_factor", sweep=True,
       former=("sfm.k_des",), **_POS),
    _f("a_veh_n", "sfm.a_veh_n", "N", "vehicle repulsion amplitude A", sweep=True,
       former=("sfm.A",), **_NONNEG),
    _f("b_veh_per_m", "sfm.b_veh_per_m", "1/m", "vehicle repulsion decay rate b",
       sweep=True, former=("sfm.b",), **_NONNEG),
    _f("v0_mps", "sfm.v0_mps", "m/s", "rider's nominal desired speed v0 (the rider's own "
       "recorded speed when sfm.speed_from_recording; a swept v0 turns that off)",
       sweep=True, former=("sfm.v0",), **_NONNEG),
    _f("mass_kg", "sfm.mass_kg", "kg", "rider + e-scooter mass", sweep=True,
       former=("sfm.mass",), **_POS),
    _f("sigma_m", "sfm.sigma_m", "m", "regulariser sigma of the desired velocity", **_POS),
    _f("lookahead_m", "sfm.lookahead_m", "m", "look-ahead of the goal on the rider's path",
       **_POS),
    _f("arrive_radius_m", "sfm.arrive_radius_m", "m", "the rider leaves this close to its "
       "final point", **_POS),
    _b("use_vehicle_force", "sfm.use_vehicle_force", "apply the vehicle repulsion force "
       "f_veh", sweep=True, former=("sfm.vehicle_force",)),
    _b("paper_vdes", "sfm.desired_velocity", "the paper's literal desired velocity",
       convert="equals", equals="paper"),
    _b("front_bumper", "sfm.influential_point", "the vehicle repels from its front bumper",
       convert="equals", equals="front_bumper"),
    _f("max_speed_mps", "sfm.max_speed_mps", "m/s", "rider speed limit (None = +inf; the "
       "rider's recorded 99th percentile when sfm.speed_from_recording)",
       convert="none_is_inf", **_POS),
    _f("max_accel_mps2", "sfm.max_accel_mps2", "m/s^2", "rider acceleration limit "
       "(None = +inf)", convert="none_is_inf", **_POS),
    Setting("ego_mode", "ego_mode", "code", "ego controller: 0 replay-speed, 1 pid, 2 cap, "
            "3 policy (ego.policy, or any closed loop with perception enabled)", kind="int",
            lower=0.0, upper=3.0, convert="derived"),
    _f("cruise_speed_mps", "ego.cruise_speed_mps", "m/s", "ego PID cruise speed v_d "
       "('median-moving' = the recorded ego's median moving speed)",
       convert="median_moving", sweep=True, **_POS),
    _f("initial_speed_mps", "ego.initial_speed", "m/s", "ego speed at t = 0 (v_d, or the "
       "recorded speed for 'recorded' and replay-speed)", kernel=False, **_DERIVED,
       **_NONNEG),
    _f("ego_start_s_m", "ego.run_up_m", "m", "ego arc length at t = 0: -run-up ('auto' "
       "from the scenario; 0 for replay-speed)", lower=-250.0, upper=0.0, kernel=False,
       **_DERIVED),
    _f("kp", "ego.kp", "1/(m/s)", "PID proportional gain", **_NONNEG),
    _f("ki", "ego.ki", "1/m", "PID integral gain", **_NONNEG),
    _f("kd", "ego.kd", "s/m", "PID derivative gain", **_NONNEG),
    _f("integral_limit", "ego.integral_limit", "-", "anti-windup: |ki * integral| <= this",
       **_POS),
    _f("integral_window_s", "ego.integral_window_s", "s", "memory of the PID integral "
       "(None = +inf, a plain integral)", convert="none_is_inf", **_POS),
    _f("max_accel_mps2_ego", "ego.max_accel_mps2", "m/s^2", "ego acceleration at full "
       "throttle", **_POS),
    _f("max_decel_mps2_ego", "ego.max_decel_mps2", "m/s^2", "ego deceleration at full "
       "brake", **_POS),
    _f("actuator_lag_s", "ego.actuator_lag_s", "s", "actuator lag time constant", **_NONNEG),
    _f("t_safe_s", "cap.t_safe_s", "s", "CAP time headway T_safe", sweep=True,
       former=("cap.T_safe_s",), **_NONNEG),
    _f("d_buf_m", "cap.d_buf_m", "m", "CAP standstill buffer d_buf", sweep=True, **_NONNEG),
    _f("a_min_mps2", "cap.a_min_mps2", "m/s^2", "CAP maximum braking a_min (negative)",
       sweep=True, upper=0.0, upper_open=True),
    _f("corridor_half_width_m", "cap.corridor_half_width_m", "m", "CAP path corridor half "
       "width", **_POS),
    _f("detection_range_m", "cap.detection_range_m", "m", "CAP detection range", **_POS),
    _f("release_margin_m", "cap.release_margin_m", "m", "CAP brake release hysteresis",
       **_NONNEG),
    _f("recover_tolerance_mps", "cap.recover_tolerance_mps", "m/s", "CAP RECOVER -> CRUISE "
       "speed tolerance", **_POS),
    _b("paper_per_step", "cap.braking_law", "the paper's per-step braking law",
       convert="equals", equals="paper_per_step"),
    _f("perception_delay_s", "cap.perception_delay_s", "s", "perception latency of every "
       "policy (it sees late; rounded to whole engine steps)", sweep=True, former=("perception_delay_s",),
       **_NONNEG),
    _b("speed_from_recording", "sfm.speed_from_recording", "extra SFM riders take their "
       "speeds from their own recordings"),
    _f("a_rider_n", "sfm.a_rider_n", "N", "rider-rider repulsion amplitude", **_NONNEG),
    _f("b_rider_per_m", "sfm.b_rider_per_m", "1/m", "rider-rider repulsion decay rate",
       **_NONNEG),
    _b("use_rider_force", "sfm.use_rider_force", "apply the rider-rider repulsion"),
    # issue 32: riders brake for a standing or slow car in their way
    _b("obstacle_braking", "sfm.obstacle_braking", "the rider brakes for a standing or "
       "slow car in its way", sweep=True),
    _f("obstacle_decel_mps2", "sfm.obstacle_decel_mps2", "m/s^2", "deceleration of the "
       "rider's stop for a car in its way", sweep=True, **_POS),
    _f("obstacle_margin_m", "sfm.obstacle_margin_m", "m", "the rider stops this far short "
       "of a car in its way", **_NONNEG),
    _f("obstacle_speed_mps", "sfm.obstacle_speed_mps", "m/s", "a car slower than this is "
       "an obstacle the rider brakes for", **_NONNEG),
    Setting("policy", "ego.policy", "object", "ego policy (vei.policy): none = PID cruise, "
            "paper-cap = PID + CAP, aeb, idm, or a user policy 'package.module:Class' / "
            "'path/file.py:Class' (docs/policy.md)", kind="object", kernel=False, sweep=True,
            former=("policy",), **_DERIVED),
    Setting("perception", "perception", "object", "the policy's sensor model (None = "
            "ideal)", kind="object", kernel=False, **_DERIVED),
    # V2X (vei.config.v2x, docs/v2x.md): the riders' messages and the channel, per variant.
    Setting("v2x", "v2x", "object", "V2X (None = off): riders' VAMs, channel and the car's "
            "tracks", kind="object", kernel=False, **_DERIVED),
    _f("v2x_penetration_rate", "v2x.penetration_rate", "-", "V2X: share of riders equipped "
       "(drawn per rider with the V2X seed)", lower=0.0, upper=1.0, sweep=True, kernel=False),
    _f("v2x_latency_s", "v2x.latency_s", "s", "V2X: fixed part of the latency (None = the "
       "technology's)", sweep=True, kernel=False, convert="none_is_default", **_NONNEG),
    _f("v2x_latency_jitter_s", "v2x.latency_jitter_s", "s", "V2X: scale of the latency's "
       "random part (None = the technology's)", sweep=True, kernel=False,
       convert="none_is_default", **_NONNEG),
    _f("v2x_pdr_factor", "v2x.pdr_factor", "-", "V2X: factor on every packet delivery "
       "ratio (channel load)", lower=0.0, upper=1.0, sweep=True, kernel=False),
    _f("v2x_position_error_std_m", "v2x.position_error_std_m", "m", "V2X: the riders' "
       "GNSS error per axis (1 sigma)", sweep=True, kernel=False, **_NONNEG),
    _f("v2x_clock_offset_s", "v2x.clock_offset_s", "s", "V2X: the riders' clock minus true "
       "time", sweep=True, kernel=False),
    *(
        _f(f"{pol}_{name}", f"ego.policy_params.{name}", unit, doc, convert="policy_param",
           policy=pol, sweep=sweep, kernel=False, former=(f"{pol}.{name}",) if sweep else (),
           **bounds)
        for pol, name, unit, doc, bounds, sweep in (
            ("aeb", "ttc_warning_s", "s", "AEB forward collision warning TTC", _POS, True),
            ("aeb", "ttc_partial_s", "s", "AEB partial braking TTC", _POS, True),
            ("aeb", "ttc_full_s", "s", "AEB full braking TTC", _POS, True),
            ("aeb", "partial_decel_mps2", "m/s^2", "AEB partial braking deceleration", _POS,
             True),
            ("aeb", "full_decel_mps2", "m/s^2", "AEB full braking deceleration", _POS, True),
            ("idm", "max_accel_mps2", "m/s^2", "IDM maximum acceleration a", _POS, True),
            ("idm", "comfort_decel_mps2", "m/s^2", "IDM comfortable deceleration b", _POS,
             True),
            ("idm", "time_headway_s", "s", "IDM desired time headway T", _NONNEG, True),
            ("idm", "min_gap_m", "m", "IDM jam distance s0", _NONNEG, True),
            ("idm", "delta", "-", "IDM acceleration exponent", _POS, False),
        )
    ),
    # ---- issue 24: the rider's yield / go decision (vei.models.decision_core)
    _b("decide", "decision.enabled", "the social-force rider decides yield / go at a "
       "conflict with the car (gap acceptance)", sweep=True),
    _f("critical_gap_s", "decision.critical_gap_s", "s", "the rider's critical gap t_c on "
       "the difference in time-to-arrival (the car's minus the rider's): it goes when the "
       "offered gap is at least this", sweep=True, lower=-30.0, upper=30.0),
    _f("decision_horizon_s", "decision.horizon_s", "s", "the rider decides when it is "
       "this far (time to arrive) from the conflict zone", **_POS),
    _f("yield_decel_mps2", "decision.yield_decel_mps2", "m/s^2", "deceleration of a "
       "yielding rider's stop", sweep=True, **_POS),
    _f("stop_margin_m", "decision.stop_margin_m", "m", "a yielding rider stops this far "
       "short of the conflict zone", **_NONNEG),
    _f("clear_margin_m", "decision.clear_margin_m", "m", "the car has left the conflict "
       "zone once its rear is this far beyond it", **_NONNEG),
    # ---- issue 24: recorded cars that react (IDM), pedestrians (social force)
    _b("cars_react", "traffic.cars_react", "recorded cars on or across the ego's path "
       "react (IDM along their recorded paths) when the ego deviates", sweep=True),
    _f("car_v0_mps", "traffic.idm_desired_speed_mps", "m/s", "reacting cars' IDM desired "
       "speed v0", sweep=True, **_POS),
    _f("car_headway_s", "traffic.idm_time_headway_s", "s", "reacting cars' IDM time "
       "headway T", sweep=True, **_NONNEG),
    _f("car_min_gap_m", "traffic.idm_min_gap_m", "m", "reacting cars' IDM jam distance "
       "s0", sweep=True, **_NONNEG),
    _f("car_accel_mps2", "traffic.idm_max_accel_mps2", "m/s^2", "reacting cars' IDM "
       "maximum acceleration a", sweep=True, **_POS),
    _f("car_decel_mps2", "traffic.idm_comfort_decel_mps2", "m/s^2", "reacting cars' IDM "
       "comfortable deceleration b", sweep=True, **_POS),
    _f("car_delta", "traffic.idm_delta", "-", "reacting cars' IDM acceleration exponent",
       **_POS),
    _f("car_max_decel_mps2", "traffic.max_decel_mps2", "m/s^2", "reacting cars' hardest "
       "braking", sweep=True, **_POS),
    _f("car_reaction_s", "traffic.reaction_time_s", "s", "reacting drivers' reaction "
       "time", sweep=True, **_NONNEG),
    _f("car_trigger_mps2", "traffic.trigger_mps2", "m/s^2", "a car reacts once the IDM "
       "asks this much more braking of it than its recording", **_NONNEG),
    _b("peds_sfm", "traffic.pedestrians", "recorded pedestrians walk by the social force "
       "(Helbing-Molnar), reacting to the car, the riders and each other (the NumPy step)",
       sweep=True, kernel=False),
    _f("ped_tau_s", "traffic.ped_tau_s", "s", "pedestrians' relaxation time tau", **_POS, kernel=False),
    _f("ped_a_n", "traffic.ped_a_n", "N", "pedestrians' repulsion strength A", **_NONNEG, kernel=False),
    _f("ped_b_m", "traffic.ped_b_m", "m", "pedestrians' repulsion range B among "
       "pedestrians", **_POS, kernel=False),
    _f("ped_mass_kg", "traffic.ped_mass_kg", "kg", "pedestrian mass", **_POS, kernel=False),
    _f("ped_lambda", "traffic.ped_lambda", "-", "pedestrians' anisotropy lambda (1 = "
       "isotropic)", lower=0.0, upper=1.0, kernel=False),
    _f("ped_radius_m", "traffic.ped_radius_m", "m", "pedestrian body radius", **_POS, kernel=False),
    _f("ped_vehicle_range_m", "traffic.ped_vehicle_range_m", "m", "range B of a "
       "pedestrian's repulsion from vehicles and riders", **_POS, kernel=False),
    Setting("labels", "name", "object", "the configuration's name (outputs)", kind="object",
            kernel=False),
)  # fmt: skip

#: VariantParams field -> its Setting.
BY_FIELD: dict[str, Setting] = {s.field: s for s in SETTINGS}
if len(BY_FIELD) != len(SETTINGS):  # pragma: no cover - a declaration error
    raise ConfigError("two settings declare the same field")


def config_value(setting: Setting, case: Any) -> Any:
    """The engine's value of ``setting`` in a configuration (a scalar, before broadcast).

    Args:
        setting: a setting whose ``convert`` is not 'derived' or 'policy_param' (those
            need the scenario, the run or the policy: VariantParams.from_case).
        case: the run configuration's case (a vei.config.CaseConfig).
    Returns:
        The value (float / bool / str); for 'median_moving' the sentinel 'median-moving'
        unchanged (from_case resolves it).
    """
    if setting.path is None or setting.convert in ("derived", "policy_param"):
        raise ConfigError(f"setting {setting.field}: {setting.convert} is not read directly")
    node = case
    parent = case
    for part in setting.path.split("."):
        parent, node = node, getattr(node, part)
    if setting.convert == "none_is_default":
        return parent.default_for(setting.config_field) if node is None else node
    if setting.convert == "times_k_des_factor":
        return node * case.sfm.k_des_factor
    if setting.convert == "none_is_inf":
        return math.inf if node is None else node
    if setting.convert == "equals":
        return node == setting.equals
    return node


def check_section(obj: Any, section: str) -> None:
    """Check the declared settings' fields of one configuration section (its
    ``__post_init__`` calls this): a number within the declared bounds (None where None
    means +inf, the sentinel 'median-moving' where that is the conversion), true/false for
    a bool.

    Args:
        obj: an SFMConfig / EgoConfig / CAPConfig. section: 'sfm', 'ego' or 'cap'.
    Raises:
        ConfigError: '<field> must be a number / finite / > 0 ..., got <value>'.
    """
    for s in SETTINGS:
        if s.section != section or s.path is None or s.path.count(".") != 1:
            continue
        name = str(s.config_field)
        value = getattr(obj, name)
        if s.kind == "bool" and s.convert == "identity":
            if not isinstance(value, bool):
                raise ConfigError(f"{name} must be true or false, got {value!r}")
            continue
        if s.kind != "float" or s.convert not in NUMERIC_CONVERTS:
            continue
        if (value is None and s.convert in ("none_is_inf", "none_is_default")) or (
            isinstance(value, str) and s.convert == "median_moving"
        ):
            continue  # None / the sentinel: checked by the class
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{name} must be a number, got {value!r}")
        if not math.isfinite(value):
            raise ConfigError(f"{name} must be finite, got {value!r}")
        if s.outside(value):
            raise ConfigError(f"{name} must be {s.bounds_text()}, got {value!r}")
