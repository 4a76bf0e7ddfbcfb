"""Leave-one-scenario-out validation of the calibrated rider: closed-loop ADE / FDE.

For every scenario with rider tracks: fit on the tracks of the other scenarios
(:func:`vei.calibrate.fit.fit_tracks`), build the population, and roll out every window of
the held-out tracks (start every 0.5 s at a moving sample, full horizon inside the track,
3 s and 5 s) with:

- ``CV``: constant velocity (the smoothed velocity at the start);
- ``CA``: constant acceleration (smoothed velocity and acceleration at the start);
- ``CS-path``: constant start speed along the rider's recorded path (knows the route,
  like the SFM; a stronger baseline than CV);
- ``SFM paper``: the paper's uncalibrated rider (v0 5 m/s, k_des 100 N s/m, 95 kg,
  look-ahead 5 m, A 100 N, b 3.5 1/m, no limits);
- ``SFM calibrated``: the rule vei applies to a recorded rider
  (:func:`vei.calibrate.profile.params_for_recorded_rider`): speed parameters from the
  held-out rider's own recording (median moving speed, 99th percentile), the rest from
  the training population (its category's, or all riders' when the training set has no
  rider of that category);
- ``SFM start-speed``: as calibrated, but v0 (and the speed limit, if lower) from the
  speed at the window's start, i.e. only what CV knows of the rider's speed (causal);
- ``SFM population``: every parameter from the training population's medians (nothing of
  the held-out rider but its start state and path).

Every SFM variant follows the rider's recorded path (look-ahead goal), as in the engine.
ADE = mean Euclidean error over the horizon's steps, FDE = error at its end; the table
averages over all held-out windows (every scenario's windows pooled).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from vei.calibrate.fit import MASS_KG, PAPER_A_N, PAPER_B_PER_M, SIGMA_M, fit_tracks
from vei.calibrate.profile import (
    _population,
    build_profile,
    cruise_v0_mps,
    params_for_recorded_rider,
)
from vei.calibrate.rollout import (
    Windows,
    displacement_errors,
    make_windows,
    pack_paths,
    rollout_ca,
    rollout_cv,
    rollout_path_cs,
    rollout_sfm,
)
from vei.calibrate.tracks import RiderTrack, SceneTracks
from vei.errors import InputError
from vei.io.progress import progress

FloatArray = npt.NDArray[np.float64]

MODELS: tuple[str, ...] = (
    "CV",
    "CA",
    "CS-path",
    "SFM paper",
    "SFM calibrated",
    "SFM start-speed",
    "SFM population",
)
PAPER_PARAMS: dict[str, float] = {
    "v0_mps": 5.0,
    "k_des_nspm": 100.0,
    "mass_kg": 95.0,
    "sigma_m": 1.0,
    "lookahead_m": 5.0,
    "a_veh_n": PAPER_A_N,
    "b_veh_per_m": PAPER_B_PER_M,
    "max_accel_mps2": np.inf,
    "max_speed_mps": np.inf,
}


@dataclass(frozen=True)
class ValidationTable:
    """Result of :func:`validate_loso`.

    Attributes:
        horizons_s: the horizons [s]. models: row names (MODELS).
        ade_m, fde_m: {model: {horizon: mean over windows}} [m].
        n_windows: {horizon: number of held-out windows}. folds: held-out scenarios.
        per_category: {category: {model: {horizon: ADE}}}.
        n_windows_by_category: {category: {horizon: windows}}.
    """

    horizons_s: tuple[float, ...]
    models: tuple[str, ...]
    ade_m: dict[str, dict[float, float]]
    fde_m: dict[str, dict[float, float]]
    n_windows: dict[float, int]
    folds: tuple[str, ...]
    per_category: dict[str, dict[str, dict[float, float]]]
    n_windows_by_category: dict[str, dict[float, int]]

    def gain(self, model: str, baseline: str, horizon_s: float) -> float:
        """Relative ADE reduction of ``model`` against ``baseline`` at a horizon (0.2 = 20 %)."""
        return 1.0 - self.ade_m[model][horizon_s] / self.ade_m[baseline][horizon_s]

    def format(self) -> str:
        """The table as text (one row per model, ADE / FDE per horizon)."""
        head = f"{'model':16s}" + "".join(f"  ADE@{h:g}s  FDE@{h:g}s" for h in self.horizons_s)
        lines = [head, "-" * len(head)]
        for m in self.models:
            cells = "".join(
                f"  {self.ade_m[m][h]:7.2f}  {self.fde_m[m][h]:7.2f}" for h in self.horizons_s
            )
            lines.append(f"{m:16s}{cells}")
        lines.append(
            "windows: "
            + ", ".join(f"{h:g} s: {self.n_windows[h]}" for h in self.horizons_s)
            + f"; held-out scenarios: {len(self.folds)}"
        )
        for cat, per in self.per_category.items():
            n = self.n_windows_by_category[cat]
            cells = "; ".join(
                f"{h:g} s ({n[h]} windows): "
                + ", ".join(f"{m} {per[m][h]:.2f}" for m in ("CV", "SFM paper", "SFM calibrated"))
                for h in self.horizons_s
                if n[h]
            )
            lines.append(f"ADE {cat}: {cells or 'no window'}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form."""

        def key(d: dict[float, float] | dict[float, int]) -> dict[str, float | int | None]:
            return {f"{h:g}": (v if np.isfinite(v) else None) for h, v in d.items()}

        return {
            "horizons_s": list(self.horizons_s),
            "ade_m": {m: key(v) for m, v in self.ade_m.items()},
            "fde_m": {m: key(v) for m, v in self.fde_m.items()},
            "n_windows": key(self.n_windows),
            "folds": list(self.folds),
            "n_windows_by_category": {c: key(v) for c, v in self.n_windows_by_category.items()},
            "per_category": {
                c: {m: key(v) for m, v in d.items()} for c, d in self.per_category.items()
            },
        }


def _sfm_params_recorded(
    profile: dict, tracks: Sequence[RiderTrack], win: Windows
) -> dict[str, FloatArray]:
    rows = []
    for tr in tracks:
        rows.append(
            params_for_recorded_rider(
                profile,
                tr.category,
                tr.median_moving_speed_mps(),
                float(np.quantile(tr.speed_mps, 0.99)),
            )
        )
    return {k: np.array([rows[j][k] for j in win.track]) for k in rows[0]}


def _start_speed(p: dict[str, FloatArray], win: Windows) -> dict[str, FloatArray]:
    sp = np.hypot(win.vx0_mps, win.vy0_mps)
    q = dict(p)
    q["v0_mps"] = cruise_v0_mps(sp, p["lookahead_m"], SIGMA_M)
    q["max_speed_mps"] = np.maximum(p["max_speed_mps"], sp)
    return q


def _sfm_params_population(
    profile: dict, tracks: Sequence[RiderTrack], win: Windows
) -> dict[str, FloatArray]:
    rows = []
    for tr in tracks:
        med = _population(profile, tr.category)["median"]
        rows.append(
            {
                "v0_mps": float(med["v0_mps"]),
                "k_des_nspm": MASS_KG / float(med["tau_s"]),
                "mass_kg": MASS_KG,
                "sigma_m": SIGMA_M,
                "lookahead_m": float(med["lookahead_m"]),
                "max_speed_mps": float(med["max_speed_mps"]),
                "max_accel_mps2": float(med["max_accel_mps2"]),
                "a_veh_n": float(profile["vehicle_repulsion"]["a_veh_n"]),
                "b_veh_per_m": float(profile["vehicle_repulsion"]["b_veh_per_m"]),
            }
        )
    return {k: np.array([rows[j][k] for j in win.track]) for k in rows[0]}


def validate_loso(
    scenes: Sequence[SceneTracks],
    horizons_s: Sequence[float] = (3.0, 5.0),
    *,
    stride_s: float = 0.5,
    dt_s: float = 0.05,
) -> ValidationTable:
    """Leave-one-scenario-out validation (see the module docstring).

    Args:
        scenes: every scenario's tracks (:func:`vei.calibrate.tracks.load_scenes`).
        horizons_s: rollout horizons [s]. stride_s: spacing of window starts [s].
        dt_s: engine step [s].
    Returns:
        The ValidationTable.
    """
    by_name = {s.scenario: s for s in scenes}
    folds = [s.scenario for s in scenes if s.riders]
    hs = tuple(float(h) for h in horizons_s)
    if len(folds) < 2:
        raise InputError(
            f"leave-one-scenario-out needs rider tracks in >= 2 scenarios, found {len(folds)}"
        )
    errs: dict[str, dict[float, list[FloatArray]]] = {m: {h: [] for h in hs} for m in MODELS}
    fdes: dict[str, dict[float, list[FloatArray]]] = {m: {h: [] for h in hs} for m in MODELS}
    cats: dict[float, list[npt.NDArray[np.object_]]] = {h: [] for h in hs}
    with progress("validate (leave one scenario out)", len(folds), unit="folds") as rep:
        for held in folds:
            train = [t for s in scenes if s.scenario != held for t in s.riders]
            test = list(by_name[held].riders)
            result = fit_tracks(train, by_name, dt_s=dt_s, bootstrap=0)
            profile = build_profile(result, {"held_out": held})
            paths = pack_paths(test)
            for h in hs:
                win = make_windows(test, by_name, paths, h, stride_s, dt_s)
                if win.size == 0:
                    continue
                preds = {
                    "CV": rollout_cv(win),
                    "CA": rollout_ca(win),
                    "CS-path": rollout_path_cs(paths, win),
                    "SFM paper": rollout_sfm(paths, win, PAPER_PARAMS),
                    "SFM calibrated": rollout_sfm(
                        paths, win, _sfm_params_recorded(profile, test, win)
                    ),
                    "SFM start-speed": rollout_sfm(
                        paths, win, _start_speed(_sfm_params_recorded(profile, test, win), win)
                    ),
                    "SFM population": rollout_sfm(
                        paths, win, _sfm_params_population(profile, test, win)
                    ),
                }
                for m, (x, y) in preds.items():
                    a, f = displacement_errors(win, x, y)
                    errs[m][h].append(a)
                    fdes[m][h].append(f)
                cats[h].append(np.array([test[j].category for j in win.track], dtype=object))
            rep.advance()
    empty = [h for h in hs if not errs["CV"][h]]
    if empty:
        raise InputError(
            f"no held-out window of {', '.join(f'{h:g} s' for h in empty)}: the tracks are "
            "shorter than that horizon",
            field="--horizons",
        )
    ade = {m: {h: float(np.concatenate(errs[m][h]).mean()) for h in hs} for m in MODELS}
    fde = {m: {h: float(np.concatenate(fdes[m][h]).mean()) for h in hs} for m in MODELS}
    nwin = {h: int(sum(a.size for a in errs["CV"][h])) for h in hs}
    per_cat: dict[str, dict[str, dict[float, float]]] = {}
    n_cat: dict[str, dict[float, int]] = {}
    for c in ("escooter", "cyclist"):
        n_cat[c] = {h: int(np.sum(np.concatenate(cats[h]) == c)) if cats[h] else 0 for h in hs}
        per_cat[c] = {}
        for m in MODELS:
            per_cat[c][m] = {}
            for h in hs:
                e = np.concatenate(errs[m][h])
                sel = np.concatenate(cats[h]) == c
                per_cat[c][m][h] = float(e[sel].mean()) if sel.any() else float("nan")
    return ValidationTable(hs, MODELS, ade, fde, nwin, tuple(folds), per_cat, n_cat)
