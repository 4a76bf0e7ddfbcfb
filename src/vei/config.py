"""Frozen configuration dataclasses for the models and the simulation, with named presets.

Every tunable of the rider model (social forces), the ego vehicle (path following, PID,
actuator), the collision-avoidance planner (CAP) and the engine lives here, with units in
the field names and the paper's values as defaults. Values the paper does not give are
chosen here and justified in the field documentation. Every class validates itself on
construction and raises :class:`vei.errors.ConfigError`.

Files (YAML or JSON) are loaded with :func:`load_config`; unknown keys are an error, and a
key ``preset`` selects a named preset as the base that the other keys override.

Imports nothing of vei but errors (see DESIGN.md, dependency direction).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Literal, TypeVar

from vei.errors import ConfigError

T = TypeVar("T")

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

    def __post_init__(self) -> None:
        _finite("a_rider_n", self.a_rider_n, nonneg=True)
        _finite("b_rider_per_m", self.b_rider_per_m, nonneg=True)
        _bool("use_rider_force", self.use_rider_force)
        _finite("k_des_nspm", self.k_des_nspm, positive=True)
        _finite("k_des_factor", self.k_des_factor, positive=True)
        _finite("a_veh_n", self.a_veh_n, nonneg=True)
        _finite("b_veh_per_m", self.b_veh_per_m, nonneg=True)
        _finite("v0_mps", self.v0_mps, nonneg=True)
        _finite("mass_kg", self.mass_kg, positive=True)
        _finite("sigma_m", self.sigma_m, positive=True)
        _choice("desired_velocity", self.desired_velocity, ("normalised", "paper"))
        _finite("lookahead_m", self.lookahead_m, positive=True)
        _finite("arrive_radius_m", self.arrive_radius_m, positive=True)
        _choice("influential_point", self.influential_point, ("closest_box_point", "front_bumper"))
        _bool("use_vehicle_force", self.use_vehicle_force)
        if self.max_speed_mps is not None:
            _finite("max_speed_mps", self.max_speed_mps, positive=True)
        if self.max_accel_mps2 is not None:
            _finite("max_accel_mps2", self.max_accel_mps2, positive=True)
        _bool("speed_from_recording", self.speed_from_recording)

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
)

#: Named riders. 'normal' / 'aggressive' are the riders of the case-study configurations
#: (CASE_PRESETS normal, aggressive, normal-cap, aggressive-cap): the calibrated rider and
#: its aggressive variant (f_veh off, k_des x 2), as issue 11 asks. The paper's riders stay
#: as 'paper' / 'paper-aggressive' (case presets paper-normal, ..., paper-aggressive-cap;
#: in a configuration file ``sfm: paper``). Note that SFMConfig() itself is the paper's rider.
SFM_PRESETS: dict[str, SFMConfig] = {
    "normal": CALIBRATED_SFM,
    "aggressive": replace(
        CALIBRATED_SFM, use_vehicle_force=False, k_des_factor=AGGRESSIVE_K_DES_FACTOR
    ),
    "paper": PAPER_SFM,
    "paper-aggressive": replace(
        PAPER_SFM, use_vehicle_force=False, k_des_factor=AGGRESSIVE_K_DES_FACTOR
    ),
    "calibrated": CALIBRATED_SFM,
    "calibrated-aggressive": replace(
        CALIBRATED_SFM, use_vehicle_force=False, k_des_factor=AGGRESSIVE_K_DES_FACTOR
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
        if isinstance(self.cruise_speed_mps, str):
            _choice("cruise_speed_mps", self.cruise_speed_mps, (MEDIAN_MOVING,))
        else:
            _finite("cruise_speed_mps", self.cruise_speed_mps, positive=True)
        _finite("moving_threshold_mps", self.moving_threshold_mps, nonneg=True)
        _choice("initial_speed", self.initial_speed, ("cruise", "recorded"))
        if isinstance(self.run_up_m, str):
            _choice("run_up_m", self.run_up_m, (AUTO,))
        else:
            _finite("run_up_m", self.run_up_m, nonneg=True)
            if self.run_up_m > MAX_RUN_UP_M:
                raise ConfigError(f"run_up_m must be <= {MAX_RUN_UP_M:g} m, got {self.run_up_m}")
        _finite("approach_time_s", self.approach_time_s, nonneg=True)
        for name in ("kp", "ki", "kd"):
            _finite(name, getattr(self, name), nonneg=True)
        if self.integral_window_s is not None:
            _finite("integral_window_s", self.integral_window_s, positive=True)
        _finite("integral_limit", self.integral_limit, positive=True)
        _finite("max_accel_mps2", self.max_accel_mps2, positive=True)
        _finite("max_decel_mps2", self.max_decel_mps2, positive=True)
        _finite("actuator_lag_s", self.actuator_lag_s, nonneg=True)


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
        _finite("t_safe_s", self.t_safe_s, nonneg=True)
        _finite("d_buf_m", self.d_buf_m, nonneg=True)
        _finite("a_min_mps2", self.a_min_mps2)
        if self.a_min_mps2 >= 0:
            raise ConfigError(f"a_min_mps2 must be < 0 (a deceleration), got {self.a_min_mps2}")
        _finite("corridor_half_width_m", self.corridor_half_width_m, positive=True)
        _finite("detection_range_m", self.detection_range_m, positive=True)
        _choice("braking_law", self.braking_law, ("gap", "paper_per_step"))
        _finite("release_margin_m", self.release_margin_m, nonneg=True)
        _finite("recover_tolerance_mps", self.recover_tolerance_mps, positive=True)
        _finite("perception_delay_s", self.perception_delay_s, nonneg=True)


# --------------------------------------------------------------------------------------
# Engine
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SimConfig:
    """Built-in engine settings.

    Attributes:
        dt_s: fixed step [s]; 0.05 (20 Hz, CARLA's usual synchronous step).
        duration_s: simulated span [s] from t = 0; None = the scenario's span (last
            trajectory time). Explicit, never 0.
        ego_length_m, ego_width_m, rider_length_m, rider_width_m: collision footprints
            [m]; None = the scenario's agent dimensions.
        stop_on_collision: after an ego / primary-rider collision both stop and the run
            keeps recording (paper Fig. 5); false = record the contact only.
        kernel: how the built-in engine steps: 'numpy' (the reference: the pure step
            function in a loop), 'numba' (the same model compiled; extra ``vei[fast]``;
            ~40x faster on small batches, compiled once per machine and cached on disk) or
            'auto' (default: numba when installed, else numpy).
        ego_max_lat_accel_mps2: the ego path is smoothed until its curvature keeps the
            lateral acceleration at ``ego_path_speed_mps`` within this [m/s^2]
            (vei.models.drivable_path; default 4).
        ego_path_speed_mps: speed of that bound [m/s]; None = 1.05 x the recorded ego's
            median moving speed (the default cruise speed v_d, with room for the speed
            controller's overshoot).
        sfm_riders: which riders are social-force driven in the SFM configurations:
            'primary' (default: the primary threat only; every other road user replayed,
            the engine as before), 'all' (every other e-scooter and cyclist too) or a list
            of agent ids (besides the primary). Each extra rider follows its own recorded
            route, enters at its first recorded sample (recording time, no shift) and
            leaves at its final point after its last; all SFM riders repel each other and
            the recorded pedestrians (SFMConfig.a_rider_n / b_rider_per_m). In 'replay'
            configurations they are replayed.
    """

    dt_s: float = 0.05
    duration_s: float | None = None
    ego_length_m: float | None = None
    ego_width_m: float | None = None
    rider_length_m: float | None = None
    rider_width_m: float | None = None
    stop_on_collision: bool = True
    kernel: Literal["numpy", "numba", "auto"] = "auto"
    ego_max_lat_accel_mps2: float = 4.0
    ego_path_speed_mps: float | None = None
    sfm_riders: str | tuple[str, ...] = "primary"

    def __post_init__(self) -> None:
        riders = self.sfm_riders
        if isinstance(riders, list | tuple):
            if not riders or not all(isinstance(r, str) and r for r in riders):
                raise ConfigError("sfm_riders must be 'primary', 'all' or a non-empty list of ids")
            object.__setattr__(self, "sfm_riders", tuple(riders))
        elif riders not in ("primary", "all"):
            raise ConfigError(
                f"sfm_riders must be 'primary', 'all' or a list of agent ids, got {riders!r}"
            )
        _finite("dt_s", self.dt_s, positive=True)
        _finite("ego_max_lat_accel_mps2", self.ego_max_lat_accel_mps2, positive=True)
        _choice("kernel", self.kernel, ("numpy", "numba", "auto"))
        if self.dt_s > 1.0:
            raise ConfigError(f"dt_s must be <= 1 s, got {self.dt_s}")
        for name in (
            "duration_s",
            "ego_length_m",
            "ego_width_m",
            "rider_length_m",
            "rider_width_m",
            "ego_path_speed_mps",
        ):
            v = getattr(self, name)
            if v is not None:
                _finite(name, v, positive=True)
        _bool("stop_on_collision", self.stop_on_collision)


# --------------------------------------------------------------------------------------
# The paper's five configurations (+ replay-speed)
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CaseConfig:
    """One simulation configuration: rider model + ego mode and their parameters.

    Attributes:
        name: label written into results ('replay', 'normal-cap', ...).
        rider: 'replay' (kinematic replay of the time-shifted recording) or 'sfm'.
        sfm: the social-force parameters (used when rider == 'sfm'). The field's default,
            SFMConfig(), is the paper's rider; the presets normal, aggressive, normal-cap,
            aggressive-cap use the calibrated one (SFM_PRESETS), paper-* the paper's.
        ego_mode: 'replay-speed' (the recorded speed profile along the recorded path),
            'pid' (PID cruise at v_d, no avoidance = policy 'none'), 'cap' (PID + CAP =
            policy 'paper-cap'), 'policy' (any other ``ego.policy``, run on the policy
            API). With ``ego.policy`` set the ego_mode follows from it (the policy is the
            one name of the controller; 'replay-speed' takes no policy);
            :attr:`policy_name` is the controller's name either way.
        ego: ego / PID / actuator parameters.
        cap: CAP parameters (used when ego_mode == 'cap').
        perception: the ego's sensor between the world and the policy
            (:class:`vei.policy.perception.PerceptionConfig`: range, field of view,
            occlusion, noise, detection probability, seed); None (default) or
            ``enabled: false`` = ideal perception (the paper's case). Its latency is
            ``cap.perception_delay_s``. Enabled, every closed-loop controller runs on the
            policy API (also 'none' / 'paper-cap'), which applies it.
    """

    name: str
    rider: RiderModel = "replay"
    sfm: SFMConfig = field(default_factory=SFMConfig)
    ego_mode: EgoMode = "pid"
    ego: EgoConfig = field(default_factory=EgoConfig)
    cap: CAPConfig = field(default_factory=CAPConfig)
    perception: Any = None

    def __post_init__(self) -> None:
        if self.perception is not None and type(self.perception).__name__ != "PerceptionConfig":
            raise ConfigError(
                f"perception must be a PerceptionConfig (vei.policy.perception) or a mapping, "
                f"got {type(self.perception).__name__}"
            )
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(f"name must be a non-empty string, got {self.name!r}")
        _choice("rider", self.rider, ("replay", "sfm"))
        if self.ego_mode in BUILTIN_POLICIES:
            raise ConfigError(
                f"ego_mode {self.ego_mode!r} is a policy: write ego: {{policy: {self.ego_mode}}}"
            )
        _choice("ego_mode", self.ego_mode, ("replay-speed", "pid", "cap", "policy"))
        pol = getattr(self.ego, "policy", None)
        if pol is not None:
            if self.ego_mode == "replay-speed":
                raise ConfigError(
                    f"ego.policy {pol!r} with ego_mode 'replay-speed': the replayed speed "
                    "profile takes no controller; drop one of them"
                )
            object.__setattr__(self, "ego_mode", KERNEL_POLICIES.get(pol, "policy"))
        elif self.ego_mode == "policy":
            raise ConfigError("ego_mode 'policy' needs ego.policy (a policy name or class)")
        for name, cls in (("sfm", SFMConfig), ("ego", EgoConfig), ("cap", CAPConfig)):
            if not isinstance(getattr(self, name), cls):
                raise ConfigError(f"{name} must be a {cls.__name__}")
        if self.ego_mode == "cap" and self.ego.max_decel_mps2 < -self.cap.a_min_mps2:
            raise ConfigError(
                f"ego.max_decel_mps2 ({self.ego.max_decel_mps2}) must be >= |cap.a_min_mps2| "
                f"({-self.cap.a_min_mps2}) so that the CAP's demand is reachable"
            )

    @property
    def policy_name(self) -> str:
        """The controller: ego.policy, else 'none' (pid), 'paper-cap' (cap), 'replay-speed'."""
        if self.ego.policy is not None:
            return self.ego.policy
        return {"pid": "none", "cap": "paper-cap"}.get(self.ego_mode, self.ego_mode)


#: Names of the paper's five configurations, in the paper's order (DESIGN.md table).
PAPER_CASES: tuple[str, ...] = ("replay", "normal", "aggressive", "normal-cap", "aggressive-cap")

CASE_PRESETS: dict[str, CaseConfig] = {
    "replay": CaseConfig(name="replay", rider="replay", ego_mode="pid"),
    "normal": CaseConfig(name="normal", rider="sfm", sfm=SFM_PRESETS["normal"], ego_mode="pid"),
    "aggressive": CaseConfig(
        name="aggressive", rider="sfm", sfm=SFM_PRESETS["aggressive"], ego_mode="pid"
    ),
    "normal-cap": CaseConfig(
        name="normal-cap", rider="sfm", sfm=SFM_PRESETS["normal"], ego_mode="cap"
    ),
    "aggressive-cap": CaseConfig(
        name="aggressive-cap", rider="sfm", sfm=SFM_PRESETS["aggressive"], ego_mode="cap"
    ),
    # Extra (not one of the paper's five): ego replays its recorded speed profile.
    "replay-speed": CaseConfig(name="replay-speed", rider="replay", ego_mode="replay-speed"),
    # The four SFM configurations with the paper's rider (k_des 100 N s/m, v0 5 m/s, ...).
    "paper-normal": CaseConfig(
        name="paper-normal", rider="sfm", sfm=SFM_PRESETS["paper"], ego_mode="pid"
    ),
    "paper-aggressive": CaseConfig(
        name="paper-aggressive", rider="sfm", sfm=SFM_PRESETS["paper-aggressive"], ego_mode="pid"
    ),
    "paper-normal-cap": CaseConfig(
        name="paper-normal-cap", rider="sfm", sfm=SFM_PRESETS["paper"], ego_mode="cap"
    ),
    "paper-aggressive-cap": CaseConfig(
        name="paper-aggressive-cap",
        rider="sfm",
        sfm=SFM_PRESETS["paper-aggressive"],
        ego_mode="cap",
    ),
}


def case_preset(preset: str, /, **overrides: Any) -> CaseConfig:
    """The named configuration (one of CASE_PRESETS), optionally with fields replaced.

    Example: ``case_preset("normal-cap", ego=EgoConfig(cruise_speed_mps=5.6))``.
    """
    if preset not in CASE_PRESETS:
        raise ConfigError(
            f"unknown configuration {preset!r}; expected one of {', '.join(CASE_PRESETS)}"
        )
    base = CASE_PRESETS[preset]
    return replace(base, **overrides) if overrides else base


@dataclass(frozen=True)
class RiderPopulationConfig:
    """Riders sampled from the population of a rider profile (``vei calibrate riders``).

    In a run or sweep file: ``rider: {profile: calibrated, sample: 100}``. Each sampled
    rider is a social-force rider with its own v0, k_des (= mass / tau), look-ahead, speed
    and acceleration limits, drawn from the profile population's log-normal (seeded;
    :func:`vei.calibrate.profile.sample_population`); A and b are the profile's.

    Attributes:
        profile: a rider profile file (JSON/YAML, format vei.rider_profile/1) or the name
            'calibrated' (the profile shipped with vei).
        sample: number of riders N (>= 1).
        category: the population: 'escooter', 'cyclist' or 'all' (a category the profile
            lacks falls back to 'all').
        seed: sampling seed: the same seed gives the same riders.
    """

    profile: str = "calibrated"
    sample: int = 1
    category: str = "escooter"
    seed: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.profile, str) or not self.profile:
            raise ConfigError(f"profile must be a file name or 'calibrated', got {self.profile!r}")
        for name in ("sample", "seed"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int):
                raise ConfigError(f"{name} must be an integer, got {v!r}")
        if self.sample < 1:
            raise ConfigError(f"sample must be >= 1, got {self.sample}")
        if self.seed < 0:
            raise ConfigError(f"seed must be >= 0, got {self.seed}")
        _choice("category", self.category, ("escooter", "cyclist", "all"))


@dataclass(frozen=True)
class RunConfig:
    """A run: one configuration, engine settings and the rider's time shift.

    Attributes:
        case: the configuration.
        sim: engine settings.
        time_shift: the primary rider's time shift [s] (positive = the rider comes later),
            or 'auto' (:func:`vei.experiments.timeshift.find_time_shift`).
        rider: optional rider population: the run's SFM rider is replaced by N riders
            sampled from a profile (:func:`vei.calibrate.population.population_cases`);
            None = the case's own rider.
    """

    case: CaseConfig
    sim: SimConfig = field(default_factory=SimConfig)
    time_shift: float | str = "auto"
    rider: RiderPopulationConfig | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.case, CaseConfig):
            raise ConfigError("case must be a CaseConfig")
        if not isinstance(self.sim, SimConfig):
            raise ConfigError("sim must be a SimConfig")
        if self.rider is not None and not isinstance(self.rider, RiderPopulationConfig):
            raise ConfigError("rider must be a mapping {profile, sample, category, seed}")
        if isinstance(self.time_shift, str):
            _choice("time_shift", self.time_shift, ("auto",))
        else:
            _finite("time_shift", self.time_shift)


_PRESETS_OF: dict[type, Mapping[str, Any]] = {SFMConfig: SFM_PRESETS, CaseConfig: CASE_PRESETS}


# --------------------------------------------------------------------------------------
# Loading
# --------------------------------------------------------------------------------------
def _build(cls: type[T], raw: Any, where: str) -> T:
    if isinstance(raw, cls):
        return raw
    if isinstance(raw, str) and cls in _PRESETS_OF:
        raw = {"preset": raw}
    if not isinstance(raw, Mapping):
        raise ConfigError(
            f"{where}: expected a mapping for {cls.__name__}, got {type(raw).__name__}"
        )
    raw = dict(raw)
    base: Any = None
    if "preset" in raw:
        presets = _PRESETS_OF.get(cls)
        name = raw.pop("preset")
        if presets is None:
            raise ConfigError(f"{where}: {cls.__name__} has no presets (key 'preset')")
        if name not in presets:
            raise ConfigError(
                f"{where}: unknown preset {name!r} for {cls.__name__}; expected one of {', '.join(presets)}"
            )
        base = presets[name]
        _check_speed_override(base, raw, where)
    known = {f.name: f for f in fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(raw) - set(known))
    if unknown:
        raise ConfigError(
            f"{where}: unknown key(s) {', '.join(unknown)} for {cls.__name__}; "
            f"expected some of {', '.join(known)}"
        )
    kwargs: dict[str, Any] = {}
    nested = {
        "sfm": SFMConfig,
        "ego": EgoConfig,
        "cap": CAPConfig,
        "case": CaseConfig,
        "sim": SimConfig,
    }
    if cls is RunConfig:  # CaseConfig.rider is a string; RunConfig.rider a population
        nested["rider"] = RiderPopulationConfig
    if cls is CaseConfig and raw.get("perception") is not None:
        from vei.policy.perception import PerceptionConfig  # the sensor model's own config

        nested["perception"] = PerceptionConfig
    for key, value in raw.items():
        sub = nested.get(key)
        if sub is RiderPopulationConfig and value is None:  # explicit "no population"
            kwargs[key] = None
            continue
        if sub is not None:
            if (
                base is not None
                and isinstance(value, Mapping)
                and "preset" not in value
                and getattr(base, key) is not None
            ):
                value = _override(getattr(base, key), value, f"{where}.{key}")
            kwargs[key] = _build(sub, value, f"{where}.{key}")
        else:
            if (
                isinstance(value, int)
                and not isinstance(value, bool)
                and key.endswith(
                    (
                        "_s",
                        "_m",
                        "_mps",
                        "_mps2",
                        "_n",
                        "_kg",
                        "_nspm",
                        "_per_m",
                        "factor",
                        "kp",
                        "ki",
                        "kd",
                        "limit",
                    )
                )
            ):
                value = float(value)
            kwargs[key] = value
    try:
        return replace(base, **kwargs) if base is not None else cls(**kwargs)
    except TypeError as exc:  # missing required field
        raise ConfigError(f"{where}: {exc}") from None
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None


def _check_speed_override(base_obj: Any, overrides: Mapping[str, Any], where: str) -> None:
    """A speed given over a rider that takes its speeds from the recording would be ignored
    silently (the calibrated default rider): refuse it unless speed_from_recording is said."""
    if not isinstance(base_obj, SFMConfig) or not base_obj.speed_from_recording:
        return
    given = sorted({"v0_mps", "max_speed_mps"} & set(overrides))
    if given and "speed_from_recording" not in overrides:
        raise ConfigError(
            f"{where}: {', '.join(given)} would be ignored: this rider takes its speeds from "
            "the recording (speed_from_recording: true, the calibrated default); add "
            "'speed_from_recording: false' to use the given speed, 'true' to keep it as the "
            "fallback of a rider that never moves, or start from 'preset: paper'"
        )


def _override(base_obj: Any, overrides: Mapping[str, Any], where: str) -> Any:
    cls = type(base_obj)
    _check_speed_override(base_obj, overrides, where)
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(unknown)} for {cls.__name__}")
    current = {f.name: getattr(base_obj, f.name) for f in fields(cls)}
    merged = {**current, **overrides}
    return _build(cls, merged, where)


def load_config(source: str | Path | Mapping[str, Any], cls: type[T]) -> T:
    """Load a configuration of class ``cls`` from a YAML/JSON file or a mapping.

    Unknown keys (at any nesting level) raise ConfigError naming the key and the file. A
    key ``preset`` (for SFMConfig and CaseConfig) starts from that named preset; the other
    keys override it, nested sections key by key. A bare string for a CaseConfig/SFMConfig
    section names a preset.

    Args:
        source: path to a .yaml/.yml/.json file, or an already parsed mapping.
        cls: SFMConfig, EgoConfig, CAPConfig, SimConfig, CaseConfig or RunConfig.
    Returns:
        The validated, frozen configuration.
    """
    where = "config"
    if isinstance(source, str | Path):
        path = Path(source)
        where = str(path)
        if not path.is_file():
            raise ConfigError(f"{path}: configuration file not found")
        text = path.read_text(encoding="utf-8")
        try:
            if path.suffix.lower() == ".json":
                raw = json.loads(text)
            else:
                import yaml

                raw = yaml.safe_load(text)
        except (ValueError, ImportError) as exc:  # yaml.YAMLError subclasses Exception
            raise ConfigError(f"{path}: cannot parse: {exc}") from None
        except Exception as exc:  # noqa: BLE001 - yaml errors
            raise ConfigError(f"{path}: cannot parse: {exc}") from None
    else:
        raw = source
    if not dataclasses.is_dataclass(cls):
        raise ConfigError(f"{cls!r} is not a configuration class")
    return _build(cls, raw, where)


def config_to_dict(cfg: Any) -> dict[str, Any]:
    """A configuration as a plain (JSON-serialisable) dict; ``load_config`` reads it back."""
    return dataclasses.asdict(cfg)
