"""Automatic time shift: make a crash-free recording critical (paper Section III-C).

The paper shifts "the timing of the interaction without changing the trajectory" until
the space-time paths overlap. We shift the primary rider's timing by tau (the rider at
engine time t is the recording at t - tau) and choose the tau that puts the rider's
centre onto the ego's front-bumper centre, the head-on hit the paper's replay shows.

The ego's motion is the one of the ``replay`` configuration (DESIGN.md): PID cruise at
v_d along the recorded ego path, computed by the engine itself (one variant, with the
rider kept out of the scene), so that ``replay`` meets the rider; the other four
configurations keep the same shift.

Search: for every tau on a grid of the engine step over all shifts that bring the rider's
span -- with its run-in and run-out (vei.continuation): the range grows with them -- into
the simulated span, the miss distance ``D(tau) = min_t |R(t - tau) - F(t)|`` (F = ego
front centre, R = rider centre, t over the steps where the shifted rider is on its
*recorded* route: a continuation lets the rider arrive and leave, it never makes a
recording critical) is computed in one array operation. The best
grid tau is refined by nested grids down to ~1 microsecond, with the times near the meeting
sampled at a twentieth of the step. Where
several shifts are equally good (e.g. a rider riding along the ego's path), the smallest
|tau| among those within ``tie_tolerance_m`` of the best wins.

Honesty: the result says whether the paths *meet* (``paths_meet``: the miss distance is
within ``meet_tolerance_m``, default half the ego's width plus half the rider's: the
rider's centre then lies within the width of the ego's front). On most real recordings
the rider's path never comes that close to the car's, and no shift makes it critical;
the callers print that with the miss distance and flag it in summary.json.
:func:`evaluate_time_shift` gives the same figures for a shift the user chose, and
refuses (InputError) a shift that keeps the rider out of the simulated span entirely.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from vei.config import CaseConfig, SimConfig, case_preset
from vei.errors import InputError
from vei.types import Scenario


@dataclass(frozen=True)
class TimeShiftResult:
    """Outcome of :func:`find_time_shift`.

    Attributes:
        time_shift_s: the shift tau [s] (positive = the rider comes later).
        miss_distance_m: min over time of |rider centre - ego front centre| at tau [m]
            (0 = an exact hit; large = the paths never meet).
        meet_time_s: engine time of that minimum [s].
        meet_x_m, meet_y_m: the ego's front centre then [m].
        cruise_speed_mps: the ego's cruise speed used [m/s].
        search_min_s, search_max_s: the searched range of tau [s] (both = tau for a
            given shift).
        meet_tolerance_m: miss distance up to which the paths count as meeting [m].
        rider_id: the shifted rider.
        rider_span_s: (start, end) of the rider's recording [s] (before the shift).
    """

    time_shift_s: float
    miss_distance_m: float
    meet_time_s: float
    meet_x_m: float
    meet_y_m: float
    cruise_speed_mps: float
    search_min_s: float
    search_max_s: float
    meet_tolerance_m: float = 1.2
    rider_id: str = ""
    rider_span_s: tuple[float, float] = (float("nan"), float("nan"))

    @property
    def paths_meet(self) -> bool:
        """The rider's centre comes within meet_tolerance_m of the ego's front centre."""
        return bool(self.miss_distance_m <= self.meet_tolerance_m)

    def recorded_window_s(self) -> tuple[float, float]:
        """(lo, hi) [s]: the offsets from this shift (rider later by delta) that keep the
        rider on its *recorded* span when the car reaches the meeting point: at the
        meeting the rider is at recording time ``r_m - delta`` (``r_m = meet_time_s -
        time_shift_s``), on the recording for ``r_m - delta`` in ``rider_span_s``. Empty
        (lo > hi) where the paths never meet (nan then)."""
        if not self.paths_meet:
            return (float("nan"), float("nan"))
        r_m = self.meet_time_s - self.time_shift_s
        r0, r1 = self.rider_span_s
        return (float(r_m - r1), float(r_m - r0))

    def __float__(self) -> float:
        return self.time_shift_s

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {
            "time_shift_s": self.time_shift_s,
            "miss_distance_m": self.miss_distance_m,
            "meet_time_s": self.meet_time_s,
            "meet_x_m": self.meet_x_m,
            "meet_y_m": self.meet_y_m,
            "cruise_speed_mps": self.cruise_speed_mps,
            "search_min_s": self.search_min_s,
            "search_max_s": self.search_max_s,
            "meet_tolerance_m": self.meet_tolerance_m,
            "paths_meet": self.paths_meet,
            "rider_id": self.rider_id,
            "rider_span_s": list(self.rider_span_s),
            "recorded_window_s": list(self.recorded_window_s()),
            "risk_basis": "recorded behaviour" if self.paths_meet else "continuations",
        }

    def message(self) -> str:
        """One line for the terminal: the shift and whether the paths meet. It is about
        the *recorded* paths (the rider replayed, the ego at its cruise speed without
        avoidance), not about any simulated run, and says so (issue 32.4)."""
        if self.paths_meet:
            return (
                f"recorded paths: time shift {self.time_shift_s:+.2f} s: {self.rider_id} meets "
                f"the ego's front (miss {self.miss_distance_m:.2f} m at t = "
                f"{self.meet_time_s:.2f} s)"
            )
        return (
            f"NOT CRITICAL (the recorded paths, not a run's outcome): no time shift makes "
            f"the paths meet; at the best shift "
            f"({self.time_shift_s:+.2f} s) {self.rider_id} passes {self.miss_distance_m:.2f} m from "
            f"the ego's front (needs <= {self.meet_tolerance_m:.2f} m); try --make-critical "
            "timing+path"
            if self.search_min_s != self.search_max_s
            else f"NOT CRITICAL (the recorded paths, not a run's outcome): with the given "
            f"time shift {self.time_shift_s:+.2f} s {self.rider_id} "
            f"passes {self.miss_distance_m:.2f} m from the ego's front at best (t = "
            f"{self.meet_time_s:.2f} s; needs <= {self.meet_tolerance_m:.2f} m)"
        )


def parse_time_shift(value: str | float) -> str | float:
    """Parse ``--time-shift auto|SECONDS``: 'auto' or a finite float [s] (InputError otherwise)."""
    if isinstance(value, int | float) and not isinstance(value, bool):
        v = float(value)
    else:
        text = str(value).strip().lower()
        if text == "auto":
            return "auto"
        try:
            v = float(text)
        except ValueError:
            raise InputError(
                f"expected 'auto' or a number of seconds, got {value!r}", field="time-shift"
            ) from None
    if not np.isfinite(v):
        raise InputError(f"time shift must be finite, got {value!r}", field="time-shift")
    return v


@dataclass(frozen=True)
class EgoFront:
    """The ego's front-centre trajectory under a configuration, rider kept away.

    Attributes:
        t_s: [T] engine times [s]. fx_m, fy_m: [T] front-centre positions [m].
        cruise_speed_mps: v_d used [m/s]. rider_t0_s, rider_t_end_s: the rider's span [s]
            (with its run-in and run-out: when it is in the scene).
        t_tab_s, x_tab_m, y_tab_m: the rider's track (uniform table) [M].
        meet_tolerance_m: (ego width + rider width) / 2 [m]. rider_id: the rider.
        rec_t0_s, rec_t_end_s: the span of its *recorded* samples [s]: the paths meet on
            the recorded route only (a continuation is an extrapolation: it lets the rider
            arrive and leave, it does not make a recording critical).
    """

    t_s: np.ndarray
    fx_m: np.ndarray
    fy_m: np.ndarray
    cruise_speed_mps: float
    rider_t0_s: float
    rider_t_end_s: float
    t_tab_s: np.ndarray
    x_tab_m: np.ndarray
    y_tab_m: np.ndarray
    meet_tolerance_m: float
    rider_id: str
    dt_s: float
    rec_t0_s: float = -np.inf
    rec_t_end_s: float = np.inf

    def recorded_xy(self) -> tuple[np.ndarray, np.ndarray]:
        """([M'], [M']) the rider's positions on its recorded route [m] (no continuation)."""
        keep = (self.t_tab_s >= self.rec_t0_s - 1e-9) & (self.t_tab_s <= self.rec_t_end_s + 1e-9)
        return self.x_tab_m[keep], self.y_tab_m[keep]

    def miss(
        self, taus: np.ndarray, times: np.ndarray, fxs: np.ndarray, fys: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """[n_tau] miss distances (inf: the rider's recorded route never in the run) and
        the index of the closest time."""
        out = np.full(taus.shape, np.inf)
        arg = np.zeros(taus.shape, dtype=np.intp)
        chunk = max(1, int(1_000_000 // max(times.size, 1)))
        lo = max(self.rider_t0_s, self.rec_t0_s)
        hi = min(self.rider_t_end_s, self.rec_t_end_s)
        for i in range(0, taus.size, chunk):
            tt = times[None, :] - taus[i : i + chunk, None]
            inside = (tt >= lo - 1e-9) & (tt <= hi + 1e-9)
            dx = np.interp(tt, self.t_tab_s, self.x_tab_m) - fxs[None, :]
            dy = np.interp(tt, self.t_tab_s, self.y_tab_m) - fys[None, :]
            d = np.where(inside, np.hypot(dx, dy), np.inf)
            arg[i : i + chunk] = np.argmin(d, axis=1)
            out[i : i + chunk] = d[np.arange(d.shape[0]), arg[i : i + chunk]]
        return out, arg


def ego_front(
    scenario: Scenario, *, sim: SimConfig | None = None, case: CaseConfig | str = "replay"
) -> EgoFront:
    """Simulate the ego alone under ``case`` (rider shifted out of the span) and return its
    front-centre trajectory with the rider's recording (see :class:`EgoFront`)."""
    from vei.sim.engine import simulate
    from vei.sim.state import VariantParams, prepare_scenario

    sim = sim or SimConfig()
    arrays = prepare_scenario(scenario, sim)
    cfg = case if isinstance(case, CaseConfig) else case_preset(case)
    t = arrays.t_s
    tr = arrays.rider_track
    away = float(t[-1] - tr.t0_s + 1e3)
    params = VariantParams.from_case(cfg, arrays, 1, time_shift_s=away)
    res = simulate(arrays, params, kernel=sim.kernel)
    hl = 0.5 * arrays.ego_length_m
    ex, ey, eyaw = res.ego_x_m[0], res.ego_y_m[0], res.ego_yaw_rad[0]
    m = tr.data.shape[0]
    return EgoFront(
        t_s=t,
        fx_m=ex + hl * np.cos(eyaw),
        fy_m=ey + hl * np.sin(eyaw),
        cruise_speed_mps=float(params.cruise_speed_mps[0]),
        rider_t0_s=float(tr.t0_s),
        rider_t_end_s=float(tr.t_end_s),
        t_tab_s=tr.t0_s + np.arange(m) * tr.dt_s,
        x_tab_m=tr.data[:, tr.col("x_m")],
        y_tab_m=tr.data[:, tr.col("y_m")],
        meet_tolerance_m=0.5 * (arrays.ego_width_m + arrays.rider_width_m),
        rider_id=arrays.rider_id,
        dt_s=arrays.dt_s,
        rec_t0_s=float(arrays.rider_recorded_span_s[0]),
        rec_t_end_s=float(arrays.rider_recorded_span_s[1]),
    )


def _result(
    front: EgoFront,
    tau: float,
    miss_m: float,
    t_meet: float,
    fx: float,
    fy: float,
    lo: float,
    hi: float,
) -> TimeShiftResult:
    return TimeShiftResult(
        time_shift_s=float(tau),
        miss_distance_m=float(miss_m),
        meet_time_s=float(t_meet),
        meet_x_m=float(fx),
        meet_y_m=float(fy),
        cruise_speed_mps=front.cruise_speed_mps,
        search_min_s=float(lo),
        search_max_s=float(hi),
        meet_tolerance_m=front.meet_tolerance_m,
        rider_id=front.rider_id,
        rider_span_s=(
            max(front.rec_t0_s, front.rider_t0_s),
            min(front.rec_t_end_s, front.rider_t_end_s),
        ),
    )


def evaluate_time_shift(
    scenario: Scenario,
    time_shift_s: float,
    *,
    sim: SimConfig | None = None,
    case: CaseConfig | str = "replay",
    front: EgoFront | None = None,
) -> TimeShiftResult:
    """The miss distance of a given shift (same figures as :func:`find_time_shift`).

    Raises InputError when the shift keeps the rider's recording entirely outside the
    simulated span, naming both spans and the range of shifts that would not.

    Args:
        scenario: the scenario. time_shift_s: the shift [s]. sim, case: as find_time_shift.
        front: a precomputed :func:`ego_front` (optional).
    Returns:
        TimeShiftResult with search_min_s = search_max_s = time_shift_s.
    """
    f = front or ego_front(scenario, sim=sim, case=case)
    tau = float(time_shift_s)
    t = f.t_s
    a, b = f.rider_t0_s + tau, f.rider_t_end_s + tau
    if b < t[0] - 1e-9 or a > t[-1] + 1e-9:
        raise InputError(
            f"time shift {tau:+g} s keeps rider {f.rider_id} out of the run: its recording spans "
            f"[{max(f.rec_t0_s, f.rider_t0_s):.2f}, {min(f.rec_t_end_s, f.rider_t_end_s):.2f}] s"
            + (
                f" ([{f.rider_t0_s:.2f}, {f.rider_t_end_s:.2f}] s with its run-in and run-out)"
                if (f.rider_t0_s, f.rider_t_end_s) != (f.rec_t0_s, f.rec_t_end_s)
                and np.isfinite(f.rec_t0_s)
                else ""
            )
            + f", shifted [{a:.2f}, {b:.2f}] s, the "
            f"simulated span is [{t[0]:.2f}, {t[-1]:.2f}] s; shifts in "
            f"[{t[0] - f.rider_t_end_s:.2f}, {t[-1] - f.rider_t0_s:.2f}] s keep it in",
            path=f"scenario {scenario.id}",
            field="time-shift",
        )
    d, arg = f.miss(np.array([tau]), t, f.fx_m, f.fy_m)
    k = int(arg[0])
    return _result(f, tau, float(d[0]), float(t[k]), f.fx_m[k], f.fy_m[k], tau, tau)


def find_time_shift(
    scenario: Scenario,
    *,
    sim: SimConfig | None = None,
    case: CaseConfig | str = "replay",
    search_range_s: tuple[float, float] | None = None,
    tie_tolerance_m: float = 0.05,
    front: EgoFront | None = None,
) -> TimeShiftResult:
    """The rider time shift that makes the replayed paths meet (see the module doc).

    Args:
        scenario: the reconstructed scenario (primary threat = the rider to shift).
        sim: engine settings (step, span, footprints).
        case: the configuration whose ego motion is used (default 'replay'; pass your own
            replay CaseConfig when you override e.g. the cruise speed).
        search_range_s: (min, max) shifts to search [s]; default: every shift that puts
            some of the rider's recorded span inside the simulated span.
        tie_tolerance_m: shifts within this miss distance of the best count as ties.
        front: a precomputed :func:`ego_front` (optional).
    Returns:
        TimeShiftResult (``float(result)`` is the shift; ``paths_meet`` says whether any
        shift makes the rider's centre reach the ego's front).
    """
    f = front or ego_front(scenario, sim=sim, case=case)
    t, fx, fy = f.t_s, f.fx_m, f.fy_m
    lo, hi = (
        (float(t[0] - f.rider_t_end_s), float(t[-1] - f.rider_t0_s))
        if search_range_s is None
        else search_range_s
    )
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi < lo:
        raise InputError(f"invalid time-shift search range ({lo}, {hi})", field="search_range_s")
    dt = f.dt_s
    # The grid is anchored where the shifts that bring the *recorded* route into the run
    # begin, and runs on in whole steps to the range's ends: the same grid points with or
    # without continuations (and whatever their length), so the same shift is found.
    anchor, top = lo, hi
    if search_range_s is None:  # (a recorded end within 1 us of the track's is the track's)
        if f.rec_t_end_s < f.rider_t_end_s - 1e-6:
            anchor = max(lo, float(t[0] - f.rec_t_end_s))
        if f.rec_t0_s > f.rider_t0_s + 1e-6:
            top = min(hi, float(t[-1] - f.rec_t0_s))
    k0 = int(np.floor((anchor - lo) / dt + 1e-9))
    taus = anchor + np.arange(-k0, int(np.floor((hi - anchor) / dt + 1e-9)) + 1) * dt

    d_grid, arg_grid = f.miss(taus, t, fx, fy)
    if not np.isfinite(d_grid).any():
        raise InputError(
            "the rider's recording never overlaps the simulated span",
            path=f"scenario {scenario.id}",
        )
    best = float(d_grid.min())
    ties = np.flatnonzero(d_grid <= best + tie_tolerance_m)
    # Among ties, prefer the smallest |tau|; refine around it (times near the meeting).
    i0 = int(ties[np.argmin(np.abs(taus[ties]))])
    tau0 = float(taus[i0])
    t_meet = float(t[arg_grid[i0]])
    fine_t = np.arange(max(t[0], t_meet - 2.0), min(t[-1], t_meet + 2.0) + 1e-9, dt / 20.0)
    ffx = np.interp(fine_t, t, fx)
    ffy = np.interp(fine_t, t, fy)
    step_s, centre = dt / 4.0, tau0
    for _ in range(4):  # dt/4 -> dt/80 -> dt/1600 -> dt/32000 resolution
        cand = np.clip(centre + np.arange(-20, 21) * step_s, anchor, top)
        d_fine, arg = f.miss(cand, fine_t, ffx, ffy)
        fbest = float(d_fine.min())
        fties = np.flatnonzero(d_fine <= fbest + 1e-9)
        j = int(fties[np.argmin(np.abs(cand[fties] - tau0))])
        centre = float(cand[j])
        step_s /= 20.0
    k = int(arg[j])
    return _result(f, cand[j], d_fine[j], fine_t[k], ffx[k], ffy[k], lo, hi)
