"""Frozen configuration of the models: the rider (social forces), the ego vehicle (path
following, PID, actuator, policy) and the paper's collision-avoidance planner (CAP), with
the shared validation helpers. Re-exported by :mod:`vei.config` (import from there).

Imports nothing of vei but errors (see DESIGN.md, dependency direction).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from typing import Any, Literal

from vei.config.settings import check_section
from vei.errors import ConfigError

DesiredVelocityForm = Literal["normalised", "paper"]
InfluentialPoint = Literal["closest_box_point", "front_bumper"]
BrakingLaw = Literal["gap", "paper_per_step"]
RiderModel = Literal["replay", "sfm"]
EgoMode = Literal["replay-speed", "pid", "cap", "policy"]

#: The paper's case-study cruise speed v_d [m/s] (Section IV-A/B).
PAPER_CRUISE_SPEED_MPS = 5.6
#: Sentinel of EgoConfig.cruise_speed_mps: use the recording's median moving speed.
MEDIAN_MOVING = "median-moving"
#: EgoConfig.run_up_m value: derive the run-up from the scenario (see EgoConfig).
AUTO = "auto"
#: Longest run-up [m] (the engine's path tables extend 300 m before the recorded start).
MAX_RUN_UP_M = 250.0


def _finite(name: str, value: Any, *, positive: bool = False, nonneg: bool = False) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ConfigError(f"{name} must be finite, got {value!r}")
    if positive and value <= 0:
        raise ConfigError(f"{name} must be > 0, got {value!r}")
    if nonneg and value < 0:
        raise ConfigError(f"{name} must be >= 0, got {value!r}")


def _choice(name: str, value: Any, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise ConfigError(f"{name} must be one of {', '.join(allowed)}; got {value!r}")


def _bool(name: str, value: Any) -> None:
    if not isinstance(value, bool):
        raise ConfigError(f"{name} must be true or false, got {value!r}")


# --------------------------------------------------------------------------------------
# E-scooter rider: social force model
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SFMConfig:
    """Social-force e-scooter rider (paper Section III-C, DESIGN.md "Models").

    ``m a = f_des + f_veh`` on a point mass, semi-implicit Euler at the engine step.

    Attributes:
        k_des_nspm: destination gain k_des [N s/m]; paper (Normal): 100.
        k_des_factor: multiplier on k_des [-]; 1 for Normal. The effective gain is
            ``k_des_nspm * k_des_factor``. The Aggressive preset uses 2.0: the paper says
            the aggressive rider's "force magnitudes [are] amplified" without a number;
            doubling the gain halves the rider's speed-relaxation time m/k_des (0.95 s ->
            0.475 s at 95 kg), i.e. it holds its course and speed twice as stubbornly.
        a_veh_n: vehicle repulsion amplitude A [N]; paper: 100.
        b_veh_per_m: repulsion decay rate b [1/m]; paper: 3.5.
        v0_mps: nominal desired speed v0 [m/s]; paper: 5.0.
        mass_kg: rider + e-scooter mass [kg]. The paper omits it; 95 kg = an adult rider
            (~80 kg) plus a typical shared e-scooter (~15 kg).
        sigma_m: regulariser sigma_des of the desired velocity [m]. The paper omits it;
            1.0 m makes the normalised form give ~v0 at the look-ahead distance (5 m:
            0.98 v0) and slow down only within about a metre of the final point.
        desired_velocity: 'normalised' (default): ``v0 (s_des - s) / sqrt(|.|^2 + sigma^2)``;
            'paper': the paper's literal ``v0 (s_des - s) / (|.|^2 + sigma^2)`` (wrong
            dimensions, speed depends on the distance to the goal; kept as an option).
        lookahead_m: the goal s_des is the point this far [m] ahead along the rider's own
            recorded path (arc length) from its current progress; the final point near the
            end. 5 m is about one second of riding at v0.
        arrive_radius_m: the SFM rider leaves the scene (inactive) once it is this close
            [m] to the final point of its recorded path, like the recording ends.
        influential_point: point of the ego that repels: 'closest_box_point' (default) of
            the ego's oriented box, or 'front_bumper' (centre of the front edge).
        use_vehicle_force: include f_veh (Normal: true; Aggressive: false, paper III-C).
        max_speed_mps: optional cap on the rider's speed [m/s]; None = no cap (paper).
        max_accel_mps2: optional cap on |f_total| / m [m/s^2]; None = no cap (paper).
        speed_from_recording: the speed parameters come from the simulated rider's own
            recording (the rule for applying a calibrated profile to one recorded rider,
            docs/riders.md): v0 such that the cruise speed of the normalised desired
            velocity, ``v0 L / sqrt(L^2 + sigma^2)``, equals the rider's recorded median
            speed while moving (> 0.5 m/s), and ``max_speed_mps`` = the 99th percentile of
            its recorded speed (at least that median). ``v0_mps`` / ``max_speed_mps`` are
            then the fallbacks for a rider that never moves. False = use them as given.
        a_rider_n, b_rider_per_m: rider-rider and rider-pedestrian repulsion
            ``A_r exp(-b_r d) n`` [N], d = centre distance minus the two agents' radii (half
            the footprint's longer side: 0.6 m for an e-scooter), n from the other agent to
            this rider; unclipped, so it grows where the discs overlap. Used only when
            several riders are social-force driven (``SimConfig.sfm_riders`` not
            'primary'). Not in the paper and not fitted (the shared recordings hold too few
            close rider-rider encounters): 1000 N = 10.5 m/s^2 at 95 kg at contact, decaying
            e-fold every 0.5 m (2.0 1/m; 18 N at a 2 m gap), so two paper riders meeting
            head-on stop 0.35 m apart (where it balances f_des = k_des v0 = 500 N).
        use_rider_force: include the rider-rider / rider-pedestrian repulsion.
        obstacle_braking: the rider brakes for a standing or slow car in its way (issue 32:
            the paper's forces alone let a rider ride into a car that stands in its path,
            its repulsion being ~3 N at 1 m against the ~400 N that keep it riding). Where
            the ray along its desired velocity meets the car's box, widened by the rider's
            half-diagonal, within braking reach, its desired speed is capped at
            ``sqrt(2 a (d - margin - v m / k_des))`` (the stop it needs, less what it rides
            in its relaxation time m / k_des). Off in the paper's riders (forces only) and
            the aggressive ones (non-cooperative by choice); on in the calibrated Normal
            rider. Only for a car slower than ``obstacle_speed_mps``.
        obstacle_decel_mps2: the deceleration a [m/s^2] of that stop: 2.0, the comfortable
            yielding deceleration of cyclists and e-scooter riders (docs/riders.md; an
            assumption below the 2.45 m/s^2 wet-pavement design value of AASHTO's 1999 Guide
            for the Development of Bicycle Facilities); the rider's force cap still bounds it.
        obstacle_margin_m: it stops this far [m] short of the car's widened box (0.5 m).
        obstacle_speed_mps: a car slower than this [m/s] is an obstacle (2.0: standing,
            creeping or stopping; a faster car is the repulsion's and the decision's matter).
    """

    k_des_nspm: float = 100.0
    k_des_factor: float = 1.0
    a_veh_n: float = 100.0
    b_veh_per_m: float = 3.5
    v0_mps: float = 5.0
    mass_kg: float = 95.0
    sigma_m: float = 1.0
    desired_velocity: DesiredVelocityForm = "normalised"
    lookahead_m: float = 5.0
    arrive_radius_m: float = 0.5
    influential_point: InfluentialPoint = "closest_box_point"
    use_vehicle_force: bool = True
    max_speed_mps: float | None = None
    max_accel_mps2: float | None = None
    speed_from_recording: bool = False
    a_rider_n: float = 1000.0
    b_rider_per_m: float = 2.0
    use_rider_force: bool = True
    obstacle_braking: bool = False
    obstacle_decel_mps2: float = 2.0
    obstacle_margin_m: float = 0.5
    obstacle_speed_mps: float = 2.0

    def __post_init__(self) -> None:
        check_section(self, "sfm")  # the declared settings (vei.config.settings)
        _finite("k_des_factor", self.k_des_factor, positive=True)
        _choice("desired_velocity", self.desired_velocity, ("normalised", "paper"))
        _choice("influential_point", self.influential_point, ("closest_box_point", "front_bumper"))

    @property
    def k_des_effective_nspm(self) -> float:
        """Effective destination gain k_des * k_des_factor [N s/m]."""
        return self.k_des_nspm * self.k_des_factor


#: Amplification of k_des of the Aggressive preset (see SFMConfig.k_des_factor).
AGGRESSIVE_K_DES_FACTOR = 2.0

#: The paper's Normal rider (Section III-C / IV): k_des 100 N s/m, A 100 N, b 3.5 1/m,
#: v0 5 m/s; look-ahead 5 m, no limits.
PAPER_SFM = SFMConfig()
#: The calibrated rider: medians of the 'all riders' population of the profile shipped with
#: vei (src/vei/riders_trafficmonitoring.json, `vei calibrate riders` on the nine shared
#: TrafficMonitoring scenarios: 15 rider tracks; docs/riders.md), rounded: relaxation time
#: tau = m / k_des = 0.53 s (k_des 180 N s/m at 95 kg), look-ahead 1.35 m, acceleration
#: limit 5.9 m/s^2; speeds from the simulated rider's own recording (fallbacks: the
#: population's v0 3.71 m/s and speed limit 4.72 m/s). A and b stay the paper's: the data
#: hold too few close encounters to identify them (25 windows, no error reduction). The
#: 'all riders' population is used because the e-scooter one has two tracks only.
CALIBRATED_SFM = SFMConfig(
    k_des_nspm=180.0,
    v0_mps=3.71,
    lookahead_m=1.35,
    max_speed_mps=4.72,
    max_accel_mps2=5.9,
    speed_from_recording=True,
    obstacle_braking=True,
)

#: Named riders. 'normal' / 'aggressive' are the riders of the case-study configurations
#: (CASE_PRESETS normal, aggressive, normal-cap, aggressive-cap): the calibrated rider and
#: its aggressive variant (f_veh off, k_des x 2), as issue 11 asks. The paper's riders stay
#: as 'paper' / 'paper-aggressive' (case presets paper-normal, ..., paper-aggressive-cap;
#: in a configuration file ``sfm: paper``). Note that SFMConfig() itself is the paper's rider.
SFM_PRESETS: dict[str, SFMConfig] = {
    "normal": CALIBRATED_SFM,
    "aggressive": replace(
        CALIBRATED_SFM,
        use_vehicle_force=False,
        k_des_factor=AGGRESSIVE_K_DES_FACTOR,
        obstacle_braking=False,
    ),
    "paper": PAPER_SFM,
    "paper-aggressive": replace(
        PAPER_SFM, use_vehicle_force=False, k_des_factor=AGGRESSIVE_K_DES_FACTOR
    ),
    "calibrated": CALIBRATED_SFM,
    "calibrated-aggressive": replace(
        CALIBRATED_SFM,
        use_vehicle_force=False,
        k_des_factor=AGGRESSIVE_K_DES_FACTOR,
        obstacle_braking=False,
    ),
}


# --------------------------------------------------------------------------------------
# Ego vehicle: path following, PID, actuator
# --------------------------------------------------------------------------------------
#: Built-in ego policies (vei.policy): name -> 'module:Class'. 'none' and 'paper-cap' run
#: the engine's own compiled ego modes in a run (KERNEL_POLICIES: name -> ego_mode).
BUILTIN_POLICIES: dict[str, str] = {
    "none": "vei.policy.builtin:PIDCruise",
    "paper-cap": "vei.policy.builtin:PaperCAP",
    "aeb": "vei.policy.aeb:AEB",
    "idm": "vei.policy.idm:IDM",
}
KERNEL_POLICIES: dict[str, str] = {"none": "pid", "paper-cap": "cap"}


#: Policies that take their parameters from the configuration's own fields (EgoConfig's
#: PID gains, CAPConfig), not from ``ego.policy_params``: at bind they take the run's
#: per-variant values, so policy_params given to them would be ignored.
CONFIG_FIELD_POLICIES: dict[str, str] = {
    "none": "none",
    "paper-cap": "paper-cap",
    BUILTIN_POLICIES["none"]: "none",
    BUILTIN_POLICIES["paper-cap"]: "paper-cap",
}


def _config_field_policy_message(policy: str, params: Mapping[str, Any]) -> str:
    """The error for policy_params given to 'none' / 'paper-cap': names, per key, the
    configuration field that sets it (``ego.kp``, ``cap.t_safe_s``, ...)."""
    ego_fields = {f.name for f in fields(EgoConfig)} - {"policy", "policy_params"}
    cap_fields = {f.name for f in fields(CAPConfig)}
    hints = []
    for key in params:
        if key in ego_fields:
            hints.append(f"{key!r}: set ego.{key}")
        elif key in cap_fields:
            hints.append(f"{key!r}: set cap.{key}")
        elif key == "paper_per_step":
            hints.append("'paper_per_step': set cap.braking_law: paper_per_step")
        else:
            hints.append(f"{key!r}: no parameter of {CONFIG_FIELD_POLICIES[policy]!r}")
    return (
        f"ego.policy_params given to policy {policy!r}, which takes its parameters from the "
        f"configuration's fields (ego.kp/ki/kd, cap.*), not from policy_params; " + "; ".join(hints)
    )


def validate_policy_spec(spec: Any) -> str:
    """``spec`` if it has the form of a policy spec (a ConfigError otherwise); loads nothing.

    A built-in name (BUILTIN_POLICIES), 'package.module:ClassName' or
    'path/to/file.py:ClassName'.
    """
    if not isinstance(spec, str) or not spec.strip():
        raise ConfigError(f"policy must be a non-empty string, got {spec!r}")
    if spec in BUILTIN_POLICIES:
        return spec
    target, sep, cls = spec.rpartition(":")
    if not sep or not target or not cls.isidentifier():
        raise ConfigError(
            f"policy {spec!r}: expected a built-in name ({', '.join(BUILTIN_POLICIES)}), "
            "'package.module:ClassName' or 'path/to/file.py:ClassName'"
        )
    return spec


@dataclass(frozen=True)
class EgoConfig:
    """Ego vehicle: follows its recorded path; PID speed control; actuator model.

    The PID produces a command u in [-1, 1] like CARLA's VehicleControl (u >= 0: throttle
    u; u < 0: brake -u). The engine maps it to a longitudinal acceleration
    ``u * max_accel_mps2`` (throttle) or ``u * max_decel_mps2`` (brake), passed through a
    first-order lag with time constant ``actuator_lag_s``.

    Attributes:
        cruise_speed_mps: v_d [m/s], or 'median-moving' (default): the recorded ego's
            median speed over the samples where it moves (> ``moving_threshold_mps``), see
            :func:`vei.models.ego.median_moving_speed_mps`. The paper's case uses 5.6.
        moving_threshold_mps: a recorded ego sample counts as moving above this [m/s].
        initial_speed: 'cruise' (default; the paper's ego drives at the constant desired
            velocity from the start) or 'recorded' (the recording's speed at t = 0).
        run_up_m: the PID/CAP ego starts this far [m] before the first point of its
            recorded path, on the path's straight backwards extension, driving at its
            initial speed (0 = the paper's start at the recorded start). A run-up matters
            when the rider's path meets the ego's near the recorded start (e.g. the
            recorded car waited at a red light while the rider crossed right in front of
            it): without one, a meeting comes within a second of the start and no planner
            has room to react. 'auto' (default): just long enough that the ego, at the
            cruise speed v_d, needs ``approach_time_s`` to reach the conflict point (the
            point of its recorded path nearest to the primary rider's recorded path):
            ``max(0, v_d * approach_time_s - s_conflict)``; 0 whenever the recording
            already has that much approach (as in the paper's case). At most 250 m. The
            replay-speed mode ignores it.
        approach_time_s: with run_up_m='auto', the time [s] the ego cruises before the
            conflict point. 6 s covers the CAP's reaction budget at the paper's settings:
            headway T_safe = 2 s, braking from 8.3 m/s at 6 m/s^2 (1.4 s), actuator lag,
            with margin; 0 = no run-up.
        kp, ki, kd: PID gains on the speed error [1/(m/s)], [1/m], [s/m]; paper: 0.05 each.
        integral_window_s: memory of the integral term [s]: the integral leaks with this
            time constant (``I <- I exp(-dt / window) + e dt``), i.e. it integrates over
            about the last ``window`` seconds, like CARLA's PIDLongitudinalController,
            whose integral is the sum over its last 10 errors (0.5 s at 20 Hz). None = a
            plain integral (clamped by ``integral_limit`` only). With the paper's gains a
            plain integral winds up while the car accelerates from a stop and overshoots
            the cruise speed by ~30 % (7.2 m/s for v_d = 5.6); the 0.5 s window gives a
            smooth return to v_d (time constant ~4.5 s with the default actuator).
        integral_limit: anti-windup: |ki * integral| is clamped to this [-] (the command
            share the integral may hold); 1.0 = the full command range.
        max_accel_mps2: acceleration at full throttle [m/s^2]. The paper omits it; 3.0 is
            a mid-size sedan's low-speed full-throttle acceleration (0-100 km/h in ~9 s).
        max_decel_mps2: deceleration at full brake [m/s^2] (positive number). 8.0 =
            ~0.8 g, full braking on dry asphalt. Must be >= |CAPConfig.a_min_mps2| so that
            the CAP's saturated demand is reachable.
        actuator_lag_s: time constant of the first-order lag between commanded and actual
            acceleration [s]; 0.2 s is a typical brake/powertrain response. 0 = no lag
            (explicit, allowed).
        policy: the ego's longitudinal controller (docs/policy.md): a built-in name
            ('none' = PID cruise, 'paper-cap' = the paper's CAP, 'aeb', 'idm'),
            'package.module:ClassName' or 'path/to/file.py:ClassName'. None (default) =
            the configuration's ego_mode decides ('pid' = 'none', 'cap' = 'paper-cap');
            set, it decides the ego_mode (CaseConfig).
        policy_params: parameters of the policy (a mapping of keyword arguments of its
            class, e.g. {ttc_full_s: 1.0} for 'aeb'); None = its defaults.
    """

    cruise_speed_mps: float | str = MEDIAN_MOVING
    moving_threshold_mps: float = 0.5
    initial_speed: Literal["cruise", "recorded"] = "cruise"
    run_up_m: float | str = AUTO
    approach_time_s: float = 6.0
    kp: float = 0.05
    ki: float = 0.05
    kd: float = 0.05
    integral_window_s: float | None = 0.5
    integral_limit: float = 1.0
    max_accel_mps2: float = 3.0
    max_decel_mps2: float = 8.0
    actuator_lag_s: float = 0.2
    policy: str | None = None
    policy_params: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        if self.policy is not None:
            validate_policy_spec(self.policy)
        if self.policy_params is not None:
            if not isinstance(self.policy_params, Mapping) or not all(
                isinstance(k, str) for k in self.policy_params
            ):
                raise ConfigError(
                    f"policy_params must be a mapping of parameter names, got {self.policy_params!r}"
                )
            if self.policy is None:
                raise ConfigError("policy_params given without a policy (ego.policy)")
            object.__setattr__(self, "policy_params", dict(self.policy_params))
            if self.policy_params and self.policy in CONFIG_FIELD_POLICIES:
                raise ConfigError(_config_field_policy_message(self.policy, self.policy_params))
        check_section(self, "ego")  # the declared settings (vei.config.settings)
        if isinstance(self.cruise_speed_mps, str):
            _choice("cruise_speed_mps", self.cruise_speed_mps, (MEDIAN_MOVING,))
        _finite("moving_threshold_mps", self.moving_threshold_mps, nonneg=True)
        _choice("initial_speed", self.initial_speed, ("cruise", "recorded"))
        if isinstance(self.run_up_m, str):
            _choice("run_up_m", self.run_up_m, (AUTO,))
        else:
            _finite("run_up_m", self.run_up_m, nonneg=True)
            if self.run_up_m > MAX_RUN_UP_M:
                raise ConfigError(f"run_up_m must be <= {MAX_RUN_UP_M:g} m, got {self.run_up_m}")
        _finite("approach_time_s", self.approach_time_s, nonneg=True)


# --------------------------------------------------------------------------------------
# Collision-avoidance planner
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CAPConfig:
    """Collision-avoidance planner: a CRUISE / BRAKE / RECOVER finite-state machine.

    ``d_safe = max(v^2 / (2 |a_min|), T_safe v) + d_buf``. CRUISE -> BRAKE when the rider
    is ahead in the ego's path corridor and the gap d < d_safe. In BRAKE the demanded
    acceleration follows ``braking_law``, saturated at a_min. BRAKE -> RECOVER when the
    rider is no longer ahead in the corridor (or inactive), or d > d_safe +
    ``release_margin_m``. RECOVER = PID back to the cruise speed (integral reset on entry),
    -> CRUISE once |v - v_d| <= ``recover_tolerance_mps``; RECOVER -> BRAKE as CRUISE.

    Attributes:
        t_safe_s: time headway T_safe [s]; the case study's value 2.0 (the text of III-D
            also says 5 s: configurable).
        d_buf_m: standstill buffer d_buf [m]; paper 3.0.
        a_min_mps2: maximum braking deceleration a_min [m/s^2] (< 0). The paper omits it;
            -6.0 is an emergency-braking level a passenger car reaches on dry asphalt with
            margin (full ABS braking ~ -8 to -9), the order of Euro NCAP AEB peak
            decelerations.
        corridor_half_width_m: the rider counts as "in front of the vehicle" when some
            part of its box (its along-path extent) lies ahead of the ego's front bumper
            and its centre lies within this lateral distance [m] of the ego's path
            (measured across the path at the rider's along-path position). 3.5 m = one lane width each side of the ego's centre line: the ego's
            lane and half of each neighbouring lane, so a crossing rider is seen when it
            enters the carriageway ahead, not only once it is already in the car's swept
            width (1.2 m), where no brake can help at urban speed.
        detection_range_m: the rider is only considered within this along-path distance
            ahead [m] (sensor range).
        braking_law: 'gap' (default): a = -v^2 / (2 (d - d_buf)) recomputed each step in
            BRAKE with the current gap d, which equals the paper's command at the trigger
            instant (d = d_safe) and stops the car d_buf short of a standing obstacle;
            'paper_per_step': the paper's a = -v^2 / (2 (d_safe(v) - d_buf)) recomputed
            every step (at urban speeds -v / (2 T_safe): it hits a standing obstacle).
        release_margin_m: BRAKE is released when d > d_safe + this [m] (hysteresis).
        recover_tolerance_mps: RECOVER -> CRUISE when |v - v_d| <= this [m/s].
        perception_delay_s: the CAP sees the rider's state this much late [s] (rounded to
            whole engine steps); 0 = no delay.
    """

    t_safe_s: float = 2.0
    d_buf_m: float = 3.0
    a_min_mps2: float = -6.0
    corridor_half_width_m: float = 3.5
    detection_range_m: float = 60.0
    braking_law: BrakingLaw = "gap"
    release_margin_m: float = 2.0
    recover_tolerance_mps: float = 0.2
    perception_delay_s: float = 0.0

    def __post_init__(self) -> None:
        check_section(self, "cap")  # the declared settings (vei.config.settings)
        _choice("braking_law", self.braking_law, ("gap", "paper_per_step"))
