"""A run's configuration: the engine (:class:`SimConfig`), the named configurations
(:class:`CaseConfig`, :data:`CASE_PRESETS`), rider populations and :class:`RunConfig`.

The model sections they hold (rider, ego, CAP) are in :mod:`vei.config.models`, the
metrics' in :mod:`vei.config.metrics`, perception's in :mod:`vei.config.perception`; files
are read by :mod:`vei.config.load`. Every class validates itself on construction and raises
:class:`vei.errors.ConfigError`.

Imports nothing of vei but errors and vei.config (see DESIGN.md, dependency direction).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Literal

from vei.config.behaviour import DecisionConfig, TrafficConfig
from vei.config.continuation import ContinuationConfig
from vei.config.metrics import MetricsConfig
from vei.config.models import (
    BUILTIN_POLICIES,
    KERNEL_POLICIES,
    SFM_PRESETS,
    CAPConfig,
    EgoConfig,
    EgoMode,
    RiderModel,
    SFMConfig,
    _bool,
    _choice,
    _finite,
)
from vei.config.perception import PerceptionConfig
from vei.config.v2x import V2XConfig
from vei.errors import ConfigError


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
        continuation: run-in and run-out of every road user but the ego
            (:class:`vei.config.continuation.ContinuationConfig`, vei.continuation):
            added by :func:`vei.sim.state.prepare_scenario` to every scenario that has none.
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
    continuation: ContinuationConfig = field(default_factory=ContinuationConfig)

    def __post_init__(self) -> None:
        if not isinstance(self.continuation, ContinuationConfig):
            raise ConfigError("continuation must be a ContinuationConfig (a mapping of its fields)")
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
            (:class:`vei.config.perception.PerceptionConfig`: range, field of view,
            occlusion, noise, detection probability, seed); None (default) or
            ``enabled: false`` = ideal perception (the paper's case). Its latency is
            ``cap.perception_delay_s``. Enabled, every closed-loop controller runs on the
            policy API (also 'none' / 'paper-cap'), which applies it.
        decision: the social-force rider's yield / go decision at a conflict with the car
            (:class:`vei.config.behaviour.DecisionConfig`; off by default: the paper's
            rider).
        traffic: recorded road users that react (:class:`vei.config.behaviour.
            TrafficConfig`: IDM cars, social-force pedestrians; off by default: replayed).
        v2x: VRU awareness messages from equipped riders, fused with the perception
            (:class:`vei.config.v2x.V2XConfig`, docs/v2x.md); off by default. Enabled,
            every closed-loop controller runs on the policy API, which applies it.
    """

    name: str
    rider: RiderModel = "replay"
    sfm: SFMConfig = field(default_factory=SFMConfig)
    ego_mode: EgoMode = "pid"
    ego: EgoConfig = field(default_factory=EgoConfig)
    cap: CAPConfig = field(default_factory=CAPConfig)
    perception: PerceptionConfig | None = None
    decision: DecisionConfig = field(default_factory=DecisionConfig)
    traffic: TrafficConfig = field(default_factory=TrafficConfig)
    v2x: V2XConfig = field(default_factory=V2XConfig)

    def __post_init__(self) -> None:
        if not isinstance(self.v2x, V2XConfig):
            raise ConfigError(
                f"v2x must be a V2XConfig (vei.config.v2x) or a mapping, got {type(self.v2x).__name__}"
            )
        if self.perception is not None and not isinstance(self.perception, PerceptionConfig):
            raise ConfigError(
                f"perception must be a PerceptionConfig (vei.config.perception) or a mapping, "
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
        for name, cls in (
            ("sfm", SFMConfig),
            ("ego", EgoConfig),
            ("cap", CAPConfig),
            ("decision", DecisionConfig),
            ("traffic", TrafficConfig),
        ):
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
            or 'auto' (:func:`vei.sim.timeshift.find_time_shift`).
        rider: optional rider population: the run's SFM rider is replaced by N riders
            sampled from a profile (:func:`vei.calibrate.population.population_cases`);
            None = the case's own rider.
        metrics: the metrics' settings (:class:`vei.config.metrics.MetricsConfig`: TTC
            zones, DRAC ceiling and reaction time, masses, injury-risk coefficients,
            mitigation share; docs/metrics.md); ``vei run --config`` scores with it.
    """

    case: CaseConfig
    sim: SimConfig = field(default_factory=SimConfig)
    time_shift: float | str = "auto"
    rider: RiderPopulationConfig | None = None
    metrics: MetricsConfig = field(default_factory=MetricsConfig)

    def __post_init__(self) -> None:
        if not isinstance(self.case, CaseConfig):
            raise ConfigError("case must be a CaseConfig")
        if not isinstance(self.sim, SimConfig):
            raise ConfigError("sim must be a SimConfig")
        if not isinstance(self.metrics, MetricsConfig):
            raise ConfigError("metrics must be a MetricsConfig (a mapping of its fields)")
        if self.rider is not None and not isinstance(self.rider, RiderPopulationConfig):
            raise ConfigError("rider must be a mapping {profile, sample, category, seed}")
        if isinstance(self.time_shift, str):
            _choice("time_shift", self.time_shift, ("auto",))
        else:
            _finite("time_shift", self.time_shift)
