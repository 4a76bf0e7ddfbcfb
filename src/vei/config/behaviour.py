"""Settings of the road users' behaviour beyond the paper: the rider's yield / go decision
at a conflict with the car (:class:`DecisionConfig`) and the recorded road users that react
(:class:`TrafficConfig`: cars driven by the Intelligent Driver Model when the ego deviates
from its recording, pedestrians driven by the social-force model of pedestrians).
Re-exported by :mod:`vei.config`; sections ``decision`` and ``traffic`` of a case.

Imports nothing of vei but errors and the settings table (see DESIGN.md, dependency
direction). The models are in :mod:`vei.models.decision_core`,
:mod:`vei.models.traffic_core`; docs/riders.md and docs/traffic.md give the sources.
"""

from __future__ import annotations

from dataclasses import dataclass

from vei.config.settings import check_section

# --------------------------------------------------------------------------------------
# Rider decisions: gap acceptance at a conflict with the car
# --------------------------------------------------------------------------------------
#: Critical gap [s] of the decision variable DTA (the car's time to arrive at the conflict
#: zone minus the rider's): 0 s, the arrive-first rule. The maximum-likelihood logistic fit
#: with Firth's penalty on the shared TrafficMonitoring recordings (``vei calibrate
#: decisions``: 3 cases, 2 go and 1 yield, separated completely) gives -0.01 s (90 %
#: bootstrap -0.22 .. +1.36 s), which the data cannot tell from 0; docs/riders.md.
FITTED_CRITICAL_GAP_S = 0.0
#: Logistic scale [s] of a population's critical gaps (P(go | DTA) = 1 / (1 + exp(-(DTA -
#: t_c) / s))): 2.0 s, the same fit's (2.03 s), set by Firth's penalty, not identified by
#: three separated cases; what a sampled population spreads (a rider at its 5 % quantile,
#: t_c - 5.9 s, hardly ever yields).
FITTED_GAP_SCALE_S = 2.0


@dataclass(frozen=True)
class DecisionConfig:
    """The social-force rider's yield / go decision at a conflict with the car.

    Where the rider's recorded path crosses the ego's path ahead of both (a *conflict*:
    the zone where the car's swept strip and the rider's overlap), the rider compares the
    times both need to reach the zone: the *offered gap* ``DTA = TTA_car - TTA_rider`` (the
    difference in time-to-arrival, the decision variable of cyclist yielding models:
    Mohammadi, Bianchi Piccinini, Dozza 2023, Accid. Anal. Prev., DOI
    10.1016/j.aap.2023.107156). Once it is within ``horizon_s`` of the zone it decides:
    *go* when DTA >= its critical gap t_c (it keeps going until it has crossed), else
    *yield*: it lets the car pass first, braking towards a stop ``stop_margin_m`` short
    of the zone only where it would otherwise enter it before the car has left it; while
    yielding it decides again every step and goes once the gap is acceptable (the car
    has passed, or has stopped for it). Off (``enabled: false``, the default) the rider is
    the paper's social force alone. docs/riders.md.

    Attributes:
        enabled: the rider decides (social-force riders only; a replayed rider replays).
        critical_gap_s: the rider's critical gap t_c [s] on DTA (negative: it goes even in
            front of a car that arrives first). Default: the population median fitted on
            the shared recordings (:data:`FITTED_CRITICAL_GAP_S`).
        gap_scale_s: logistic scale s [s] of the population's critical gaps (a sampled
            population's spread; the engine uses each rider's own t_c). Not an engine
            setting.
        horizon_s: the rider decides when its time to arrive at the zone is at most this
            [s]. 4 s: a rider at 4 m/s decides 16 m ahead, beyond the comfortable stopping
            distance at 2 m/s^2 (4 m).
        yield_decel_mps2: deceleration of a yielding rider's stop [m/s^2]: 2.0, the
            comfortable yield deceleration of cyclists and e-scooter riders (an
            assumption below the bicycle design value for wet pavement: friction 0.25,
            i.e. 0.25 g = 2.45 m/s^2, AASHTO 1999, Guide for the Development of Bicycle
            Facilities, stopping sight distance); the rider's force cap
            (``sfm.max_accel_mps2``) still bounds it.
        stop_margin_m: the yielding rider stops this far [m] short of the conflict zone.
        clear_margin_m: the car has left the zone once its rear is this far [m] beyond it.
    """

    enabled: bool = False
    critical_gap_s: float = FITTED_CRITICAL_GAP_S
    gap_scale_s: float = FITTED_GAP_SCALE_S
    horizon_s: float = 4.0
    yield_decel_mps2: float = 2.0
    stop_margin_m: float = 0.5
    clear_margin_m: float = 1.0

    def __post_init__(self) -> None:
        check_section(self, "decision")  # the declared settings (vei.config.settings)
        from vei.config.models import _finite

        _finite("decision.gap_scale_s", self.gap_scale_s, positive=True)


# --------------------------------------------------------------------------------------
# Road users that react: IDM cars, social-force pedestrians
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TrafficConfig:
    """Recorded road users that react to the simulated ones.

    Cars (``cars_react``): every recorded vehicle whose path shares or crosses the ego's
    is replayed exactly while nothing deviates; when the road user ahead of it on its path
    (the ego, or another reacting car) is where the recording would ask it to brake more
    than it did (its Intelligent Driver Model acceleration towards the actual leader
    falls ``trigger_mps2`` below the one towards the recorded leader), the driver reacts
    after ``reaction_time_s`` and from then on drives along its recorded path by
    ``a = min(a_intent, a_IDM)``: its recorded intent ``a_rec + (v_rec - v) / T`` (its own
    recorded speed profile, a speed deficit closed within one time headway) bounded by the
    IDM (Treiber, Hennecke, Helbing 2000, Phys. Rev. E 62:1805) towards the leader,
    ``a [1 - (v / v0)^delta - (s* / s)^2]``, ``s* = s0 + max(0, v T + v dv / (2 sqrt(a b)))``,
    within [-max_decel, a]. Parameters: Treiber & Kesting, *Traffic Flow Dynamics* (2013),
    the city values of its Table 11.2 as in MovSim's book scenario (v0 15 m/s, T 1.0 s,
    s0 2 m, a 1.0 m/s^2, b 1.5 m/s^2, delta 4). docs/traffic.md.

    Pedestrians (``pedestrians``): every recorded pedestrian walks by the social-force
    model of pedestrians (Helbing & Molnar 1995, Phys. Rev. E 51:4282; circular form of
    Helbing, Farkas, Vicsek 2000, Nature 407:487) along its recorded path at its recorded
    speed, repelled by the ego, the riders and the other pedestrians; the riders' repulsion
    from pedestrians then acts on the simulated pedestrians.

    Attributes:
        cars_react: recorded cars on or across the ego's path react (IDM).
        idm_desired_speed_mps: IDM v0 [m/s] (15 m/s = 54 km/h, city).
        idm_time_headway_s: IDM T [s] (1.0, city).
        idm_min_gap_m: IDM s0 [m] (2.0).
        idm_max_accel_mps2: IDM a [m/s^2] (1.0, city).
        idm_comfort_decel_mps2: IDM b [m/s^2] (1.5, city).
        idm_delta: IDM acceleration exponent delta (4).
        max_decel_mps2: the reacting car's hardest braking [m/s^2]: 8.0, the ego's full
            brake (``ego.max_decel_mps2``), inside what tyres allow on dry asphalt: peak
            road adhesion 0.8-0.9 (7.8-8.8 m/s^2; Wong 2008, Theory of Ground Vehicles,
            4th ed., Table 1.3).
        reaction_time_s: the driver's reaction time [s]: 1.0 (Johansson & Rumar 1971,
            surprise-corrected brake reaction: median 0.9 s; Green 2000: 0.7-0.75 s
            expected, 1.25 s unexpected but common such as a lead car's brake lights).
        trigger_mps2: the deviation that the driver notices [m/s^2] (0.5: a quarter of
            the comfortable deceleration; smaller differences are the IDM's own
            disagreement with the recorded driver).
        pedestrians: recorded pedestrians walk by the social force (else replayed).
        ped_tau_s: pedestrians' relaxation time tau [s] (0.5, Helbing & Molnar 1995).
        ped_a_n: pedestrians' repulsion strength A [N] (2000, Helbing et al. 2000).
        ped_b_m: its range B [m] (0.08, Helbing et al. 2000).
        ped_mass_kg: pedestrian mass [kg] (80, Helbing et al. 2000).
        ped_lambda: anisotropy lambda (0.75, Helbing et al. 2005: a pedestrian reacts a
            quarter less to what is behind it).
        ped_radius_m: a pedestrian's body radius [m] (0.3, within Helbing et al. 2000's
            0.25-0.35 m).
        ped_vehicle_range_m: range B of the repulsion from a vehicle or rider [m] (0.5:
            a pedestrian steps aside about a metre before contact; not in the literature,
            which models pedestrians among pedestrians).
    """

    cars_react: bool = False
    idm_desired_speed_mps: float = 15.0
    idm_time_headway_s: float = 1.0
    idm_min_gap_m: float = 2.0
    idm_max_accel_mps2: float = 1.0
    idm_comfort_decel_mps2: float = 1.5
    idm_delta: float = 4.0
    max_decel_mps2: float = 8.0
    reaction_time_s: float = 1.0
    trigger_mps2: float = 0.5
    pedestrians: bool = False
    ped_tau_s: float = 0.5
    ped_a_n: float = 2000.0
    ped_b_m: float = 0.08
    ped_mass_kg: float = 80.0
    ped_lambda: float = 0.75
    ped_radius_m: float = 0.3
    ped_vehicle_range_m: float = 0.5

    def __post_init__(self) -> None:
        check_section(self, "traffic")  # the declared settings (vei.config.settings)
