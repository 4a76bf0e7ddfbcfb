"""The risk spec's variation model fitted from a TrafficMonitoring dataset (issue 31.2/31.3).

``vei calibrate variation --root DATASET [--out spec.yaml]`` fits what the data can say and
takes the rest from cited sources (each value says which):

- **ego.cruise_speed_mps** (data): one cruise speed per *encounter* -- the instrumented
  car's median moving speed (> MOVING_MPS) over the INS drive each recording belongs to
  (:func:`encounter_cruise_speeds`) -- and the spread *between* encounters: the
  coefficient of variation ``std(v_i / median v)`` over the recordings (not the spread
  within one drive that :func:`vei.risk.fit.cruise_speed_spread` measures), widened by
  :func:`predictive_factor` so that its central interval predicts a *new* encounter from
  only nine (Student t; 0.31 -> 0.36 on the shared data). The spec keeps
  the mean at the scenario's recorded cruise speed; it is bounded above by the fastest
  speed the instrumented car drove at the site (the INS maximum over all drives; the
  German urban limit, 50 km/h = 13.9 m/s, StVO section 3 (3), is below it: the data allow
  a little more than the limit, nothing like 58 km/h).
- **rider speed** (data): conditional on the recorded rider. The rider's cruise speed is
  its own recorded median moving speed times ``exp(sigma z)``; sigma is the population's
  spread of a rider's speed over encounter-length windows (WINDOW_S, 3 s) around its own
  median moving speed (:func:`rider_speed_windows`; the root mean square of the log
  ratios, pooled over all rider tracks, widened by the predictive factor of the number of
  tracks). The speed limit scales with it by the rider's own
  recorded ratio p99 / median.
- **rider tau, look-ahead, acceleration limit** (data): the calibrated population
  (``vei calibrate riders``), as before.
- **speed bounds** (cited sources, widened to the data where the data go beyond them):
  an e-scooter's desired speed and speed limit <= 20 km/h (eKFV section 1 (1): German
  e-scooters are built for at most 20 km/h); a cyclist's <= 30 km/h (an assumption bounded
  by the German Naturalistic Cycling Study, Schleinitz et al. 2017, Safety Science 92:
  mean speeds 15.3 km/h on conventional bicycles, 17.4 km/h on pedelecs, 24.5 km/h on
  S-pedelecs; pedelec assistance stops at 25 km/h, EN 15194).
- **time_shift_s** (cited/assumed): the arrival window of :mod:`vei.risk.defaults`.

Leave one recording out (:func:`leave_one_out`): the model is refitted without a
recording, and the held-out recording's observed quantities (its encounter cruise speed;
its riders' window speeds) are checked against the refitted model's central 90 %
interval. The rate is reported per quantity (goal about 90 %).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

#: The car counts as moving above this speed [m/s] (the recorded 'median-moving' cruise).
MOVING_MPS = 0.5
#: Length of the windows a rider's speed is compared over [s] (an encounter's scale).
WINDOW_S = 3.0
#: Central interval validated by leave-one-out (90 %); a window counts when the rider
#: moves (> MOVING_MPS) in more than half of it.
INTERVAL = 0.90
#: Cited upper bounds of a rider's desired speed and speed limit [m/s] per category.
RIDER_SPEED_BOUND_MPS: dict[str, float] = {"escooter": 20.0 / 3.6, "cyclist": 30.0 / 3.6}
RIDER_BOUND_SOURCE = (
    "e-scooter 20 km/h: eKFV section 1 (1) (German e-scooters are built for at most 20 km/h); "
    "cyclist 30 km/h: assumption bounded by Schleinitz et al. 2017 (Safety Science 92, German "
    "Naturalistic Cycling Study: mean 15.3 km/h conventional, 17.4 km/h pedelec, 24.5 km/h "
    "S-pedelec; pedelec assistance ends at 25 km/h, EN 15194); widened to the fastest "
    "recorded rider of the category where it is faster"
)
#: The German urban speed limit [m/s] (StVO section 3 (3) 1.: 50 km/h), for comparison.
URBAN_LIMIT_MPS = 50.0 / 3.6
#: Lower truncation of the car's cruise speed [m/s] (a car that barely moves is not this
#: encounter; as the previous default).
CRUISE_MIN_MPS = 1.0
#: The name written into every fitted spec.
MODEL_NAME = "vei.calibrate.variation/1"


@dataclass(frozen=True)
class EncounterSpeed:
    """The instrumented car's cruise speed of one recording.

    Attributes: recording: scenario name. drive: INS file name. cruise_mps: median moving
    speed over the drive [m/s]. max_mps: its fastest sample [m/s].
    """

    recording: str
    drive: str
    cruise_mps: float
    max_mps: float


@dataclass(frozen=True)
class RiderSpeed:
    """One rider track's speeds.

    Attributes: recording, key (scenario/track), category. median_mps: median moving
    speed [m/s]. p99_mps: 99th percentile of its speed [m/s]. log_ratios: [W] log(window
    median speed / median_mps) of its WINDOW_S windows.
    """

    recording: str
    key: str
    category: str
    median_mps: float
    p99_mps: float
    log_ratios: FloatArray


def encounter_cruise_speeds(root: str | Path, recordings: Sequence[str] | None = None) -> list[
    EncounterSpeed
]:  # fmt: skip
    """One cruise speed per recording of a TrafficMonitoring root (module docstring).

    Raises:
        InputError: a matching or INS file cannot be read.
    """
    from vei.datasets.trafficmonitoring import list_scenarios
    from vei.datasets.trafficmonitoring_files import CAR_DATA_DIR, read_ins, read_matching

    root = Path(root)
    out = []
    for rec in recordings if recordings is not None else list_scenarios(root):
        m = read_matching(root, rec)
        v = read_ins(root / CAR_DATA_DIR / m.ins_file_name).speed_mps
        mv = v[v > MOVING_MPS]
        if mv.size < 2:
            continue
        out.append(EncounterSpeed(rec, m.ins_file_name, float(np.median(mv)), float(v.max())))
    return out


def rider_speed_windows(scenes: Sequence[Any], window_s: float = WINDOW_S) -> list[RiderSpeed]:
    """The speeds of every kept rider track of some scenes (vei.calibrate.tracks.load_scenes).

    A window of ``window_s`` counts when the rider moves in more than half of its samples;
    its speed is the median of the moving samples.
    """
    out = []
    for scene in scenes:
        for r in scene.riders:
            sp = r.speed_mps
            med = r.median_moving_speed_mps()
            if med <= 0:
                continue
            dt = float(r.t_s[1] - r.t_s[0]) if r.t_s.size > 1 else 0.05
            n = max(int(round(window_s / dt)), 1)
            ratios = []
            for i in range(0, sp.size - n + 1, n):
                w = sp[i : i + n]
                mv = w[w > MOVING_MPS]
                if mv.size > n // 2:
                    ratios.append(math.log(float(np.median(mv)) / med))
            out.append(
                RiderSpeed(
                    scene.scenario, r.key, r.category, med, float(np.percentile(sp, 99)),
                    np.asarray(ratios, dtype=np.float64),
                )
            )  # fmt: skip
    return out


@dataclass(frozen=True)
class VariationFit:
    """The fitted figures of a variation model.

    Attributes:
        cruise_cv: between-encounter coefficient of variation of the car's cruise speed.
        cruise_median_mps: median of the encounter cruise speeds [m/s].
        cruise_max_mps: upper bound of the cruise speed [m/s] (INS maximum over drives).
        n_encounters: encounters (recordings with a drive) fitted.
        rider_sigma_log: spread of a rider's window speed around its own (log) [-].
        n_riders, n_windows: rider tracks and windows fitted.
        rider_bounds_mps: {category: bound of desired speed and speed limit [m/s]}.
        recordings: the recordings fitted.
    """

    cruise_cv: float
    cruise_median_mps: float
    cruise_max_mps: float
    n_encounters: int
    rider_sigma_log: float
    n_riders: int
    n_windows: int
    rider_bounds_mps: dict[str, float] = field(default_factory=dict)
    recordings: tuple[str, ...] = ()

    def cruise_distribution(self, mean: Any = "recorded") -> dict[str, Any]:
        """The YAML form of ego.cruise_speed_mps's distribution (mean: 'recorded' or m/s)."""
        return {
            "dist": "normal",
            "mean": mean,
            "cv": round(self.cruise_cv, 4),
            "min": CRUISE_MIN_MPS,
            "max": round(self.cruise_max_mps, 2),
        }


def predictive_factor(n: int) -> float:
    """Widening of a spread fitted on n independent units so that its central INTERVAL
    interval is a prediction interval for a new unit (Student t, n - 1 degrees of
    freedom, times sqrt(1 + 1/n), over the normal quantile); 1 for large n."""
    from scipy.stats import norm, t

    if n < 2:
        raise ValueError(f"a predictive spread needs >= 2 units, got {n}")
    q = (1 + INTERVAL) / 2
    return float(t.ppf(q, n - 1) * math.sqrt(1 + 1 / n) / norm.ppf(q))


def fit_variation(cruise: Sequence[EncounterSpeed], riders: Sequence[RiderSpeed]) -> VariationFit:
    """Fit the variation figures from encounter cruise speeds and rider speeds.

    Raises:
        InputError: fewer than two encounters or no rider window to fit.
    """
    from vei.errors import InputError

    if len(cruise) < 2:
        raise InputError(f"needs >= 2 recordings with an INS drive to fit, got {len(cruise)}")
    ratios = np.concatenate([r.log_ratios for r in riders]) if riders else np.zeros(0)
    if ratios.size == 0:
        raise InputError("no rider track with a moving window of the data set to fit")
    v = np.array([c.cruise_mps for c in cruise])
    med = float(np.median(v))
    bounds = {}
    for cat, b in RIDER_SPEED_BOUND_MPS.items():
        fastest = [r.p99_mps for r in riders if r.category == cat]
        bounds[cat] = round(max([b, *fastest]), 3)
    return VariationFit(
        cruise_cv=float(np.std(v / med)) * predictive_factor(len(v)),
        cruise_median_mps=med,
        cruise_max_mps=float(max(c.max_mps for c in cruise)),
        n_encounters=len(cruise),
        rider_sigma_log=float(np.sqrt(np.mean(ratios**2))) * predictive_factor(max(len(riders), 2)),
        n_riders=len(riders),
        n_windows=int(ratios.size),
        rider_bounds_mps=bounds,
        recordings=tuple(sorted({c.recording for c in cruise} | {r.recording for r in riders})),
    )


@dataclass(frozen=True)
class CoverageRow:
    """One held-out recording's check.

    Attributes: recording; quantity ('ego cruise speed' / 'rider window speed'); n:
    observations; inside: how many fell in the refitted model's central interval.
    """

    recording: str
    quantity: str
    n: int
    inside: int


@dataclass(frozen=True)
class Coverage:
    """Leave-one-recording-out coverage of the central :data:`INTERVAL` interval."""

    rows: tuple[CoverageRow, ...]

    def rate(self, quantity: str | None = None) -> float:
        """Share of the held-out observations inside (one quantity or all); nan if none."""
        rows = [r for r in self.rows if quantity is None or r.quantity == quantity]
        n = sum(r.n for r in rows)
        return sum(r.inside for r in rows) / n if n else math.nan

    def counts(self, quantity: str | None = None) -> tuple[int, int]:
        """(inside, n) over the rows of one quantity (or all)."""
        rows = [r for r in self.rows if quantity is None or r.quantity == quantity]
        return sum(r.inside for r in rows), sum(r.n for r in rows)

    def quantities(self) -> list[str]:
        """The quantities checked, in order of appearance."""
        return list(dict.fromkeys(r.quantity for r in self.rows))

    def summary(self) -> str:
        """One line: the rate per quantity, e.g. for the spec's model.validation."""
        parts = []
        for q in self.quantities():
            k, n = self.counts(q)
            parts.append(f"{q} {k}/{n} ({100 * k / n:.0f} %)")
        return f"leave-one-recording-out, central {100 * INTERVAL:.0f} % interval: " + "; ".join(
            parts
        )

    def table(self) -> str:
        """The coverage table (Markdown)."""
        lines = [
            f"| held-out recording | quantity | n | inside central {100 * INTERVAL:.0f} % | rate |",
            "|---|---|---:|---:|---:|",
        ]
        for r in self.rows:
            lines.append(
                f"| {r.recording} | {r.quantity} | {r.n} | {r.inside} | {100 * r.inside / r.n:.0f} % |"
            )
        for q in self.quantities():
            k, n = self.counts(q)
            lines.append(f"| **all** | {q} | {n} | {k} | **{100 * k / n:.0f} %** |")
        return "\n".join(lines) + "\n"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "interval": INTERVAL,
            "rows": [r.__dict__ for r in self.rows],
            "rates": {q: self.rate(q) for q in self.quantities()},
        }


def cruise_interval(fit: VariationFit, centre_mps: float) -> tuple[float, float]:
    """The central INTERVAL interval [m/s] of the fitted cruise-speed distribution
    centred on ``centre_mps`` (truncated as the spec is)."""
    from vei.config.distributions import parse_distribution

    d = parse_distribution(fit.cruise_distribution(centre_mps), "cruise").resolve(centre_mps)
    lo, hi = d.ppf(np.array([(1 - INTERVAL) / 2, (1 + INTERVAL) / 2]))
    return float(lo), float(hi)


def leave_one_out(cruise: Sequence[EncounterSpeed], riders: Sequence[RiderSpeed]) -> Coverage:
    """Leave each recording out, refit, and check its observations (module docstring).

    The held-out encounter's cruise speed is checked against the refitted distribution
    centred on the other encounters' median (a new encounter at the site); each held-out
    rider window against ``exp(+-z sigma)`` around its rider's own median speed.
    """
    from scipy.stats import norm

    z = float(norm.ppf((1 + INTERVAL) / 2))
    recs = sorted({c.recording for c in cruise} | {r.recording for r in riders})
    rows = []
    for rec in recs:
        c_in = [c for c in cruise if c.recording != rec]
        r_in = [r for r in riders if r.recording != rec]
        fit = fit_variation(c_in, r_in)
        held = [c for c in cruise if c.recording == rec]
        if held:
            lo, hi = cruise_interval(fit, fit.cruise_median_mps)
            k = sum(lo <= c.cruise_mps <= hi for c in held)
            rows.append(CoverageRow(rec, "ego cruise speed", len(held), int(k)))
        ratios = [r.log_ratios for r in riders if r.recording == rec]
        w = np.concatenate(ratios) if ratios else np.zeros(0)
        if w.size:
            k = int(np.sum(np.abs(w) <= z * fit.rider_sigma_log))
            rows.append(CoverageRow(rec, "rider window speed", int(w.size), k))
    return Coverage(tuple(rows))


def spec_mapping(fit: VariationFit, coverage: Coverage, dataset: str) -> dict[str, Any]:
    """The fitted risk spec (the YAML mapping of :func:`vei.risk.variation.parse_variation`).

    Args:
        fit: the fit on every recording. coverage: its leave-one-out check.
        dataset: the dataset's name or path, for ``model.fitted_from``.
    """
    from vei.risk.defaults import default_variation

    time_shift = default_variation()["time_shift_s"]
    return {
        "base": "normal-cap",
        "time_shift_reference": "auto",
        "seed": 0,
        "variation": {
            "time_shift_s": time_shift,
            "ego.cruise_speed_mps": fit.cruise_distribution(),
            "rider": {
                "profile": "calibrated",
                "category": "auto",
                "speed": "recorded",
                "speed_sigma_log": round(fit.rider_sigma_log, 4),
                "max_speed_mps": dict(fit.rider_bounds_mps),
            },
        },
        "model": {
            "name": f"{MODEL_NAME} fitted on {dataset}",
            "fitted_from": f"{len(fit.recordings)} recordings: {fit.n_encounters} INS drives, "
            f"{fit.n_riders} rider tracks ({fit.n_windows} windows of {WINDOW_S:g} s)",
            "validation": coverage.summary(),
        },
    }


def spec_text(fit: VariationFit, coverage: Coverage, dataset: str) -> str:
    """The fitted spec as commented YAML: which value comes from data, which from a source."""
    import yaml

    head = [
        f"# Risk spec fitted by vei calibrate variation ({MODEL_NAME}) on {dataset}.",
        "# Data (this dataset):",
        f"#   ego.cruise_speed_mps: mean = the scenario's recorded cruise speed; cv "
        f"{fit.cruise_cv:.4f} = spread between {fit.n_encounters} encounters (one median "
        "moving speed per recording's INS drive), widened to a prediction interval;",
        f"#     max {fit.cruise_max_mps:.2f} m/s = the fastest the instrumented car drove here "
        f"(urban limit {URBAN_LIMIT_MPS:.1f} m/s, StVO section 3 (3), for comparison).",
        f"#   rider.speed_sigma_log {fit.rider_sigma_log:.4f}: a rider's speed over "
        f"{WINDOW_S:g} s windows around its own recorded speed ({fit.n_windows} windows, "
        f"{fit.n_riders} tracks).",
        "#   rider tau, look-ahead, acceleration limit: the calibrated population "
        "(vei calibrate riders).",
        "# Cited sources:",
        f"#   rider.max_speed_mps: {RIDER_BOUND_SOURCE}.",
        "#   time_shift_s: the arrival window of vei.risk.defaults (docs/risk.md).",
        f"# Leave-one-recording-out: {coverage.summary()}.",
    ]
    body = yaml.safe_dump(spec_mapping(fit, coverage, dataset), sort_keys=False, width=100)
    return "\n".join(head) + "\n" + body


def calibrate_variation(root: str | Path) -> tuple[VariationFit, Coverage]:
    """Fit the variation model on a TrafficMonitoring root and validate it (module
    docstring). Raises InputError for a dataset that cannot be read or fitted."""
    from vei.calibrate.tracks import load_scenes

    cruise = encounter_cruise_speeds(root)
    riders = rider_speed_windows(load_scenes(root))
    return fit_variation(cruise, riders), leave_one_out(cruise, riders)
