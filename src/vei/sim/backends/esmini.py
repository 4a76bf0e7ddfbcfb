"""esmini backend: vei's closed loop inside esmini, the reference OpenSCENARIO player.

Per run (one configuration):

1. vei writes the run's scenario as OpenSCENARIO with
   :func:`vei.export.openscenario.export_openscenario`: the map as ``LogicFile`` (when the
   scenario has one), every replayed road user on its timed trajectory sampled at the
   engine's steps, the rider too under ``replay`` (time-shifted), and the ego with only
   its initial pose and speed (``ego_controller='simulator'``: something else drives it).
   After loading, the file's ego is replaced by an object of the same name and box that
   only vei places (``SE_DeleteObject`` + ``SE_AddObjectWithBoundingBox``), so that no
   story action in the file moves it or changes its speed.
2. esmini loads the file through ``libesminiLib.so`` (:mod:`.esmini_lib`, ctypes;
   headless, console off, its log in the run's folder, collision detection on).
3. Each step of ``dt``: vei's controllers (:class:`~vei.sim.backends.base.ClosedLoop`:
   ego PID + CAP, social-force rider) compute the ego's and the rider's next states;
   the backend reports the ego's pose and speed (``SE_ReportObjectPosXYH`` /
   ``SE_ReportObjectSpeed``), and the social-force rider's pose, speed and velocity (the
   rider is added with ``SE_AddObjectWithBoundingBox`` when it enters and deleted when
   it leaves); ``SE_StepDT(dt)`` moves the replayed road users (and the replayed rider)
   along their trajectories; then every state is read back (``SE_GetObjectState``,
   ``SE_GetObjectVelocityGlobalXYZ``) with esmini's collisions of the ego
   (``SE_GetObjectCollision``), and fed to the controllers: the ego, the rider (CAP
   perception, social forces, box collisions) and the others (contacts).

The ego's acceleration: esmini keeps the speed that is reported, not a vehicle model;
where it holds the reported speed, the measured acceleration is the one the ego model
produced it with (else the difference quotient of esmini's speeds).

esmini keeps one scenario per process (global state): runs load and close one after the
other, and a second concurrent session is a BackendError. Files go into a temporary
folder (removed at the end) or ``EsminiSettings.work_dir`` (kept).
"""

from __future__ import annotations

import math
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.config import SimConfig
from vei.errors import BackendError, ConfigError, InputError
from vei.sim.backends.base import (
    Backend,
    ClosedLoop,
    EgoMeasurement,
    Measurement,
    RiderMeasurement,
    TickCommand,
)
from vei.sim.backends.esmini_lib import (
    CATEGORY_BICYCLE,
    OBJECT_TYPE_PEDESTRIAN,
    OBJECT_TYPE_VEHICLE,
    EsminiSession,
    new_log_dir,
)
from vei.types import EGO_CATEGORY, EGO_ID, AgentInfo, Scenario

#: Heights of the ego's and the added rider's boxes [m] (esmini needs them; vei's are 2-D).
EGO_HEIGHT_M = 1.5
RIDER_HEIGHT_M = 1.7
_SPAN_EPS = 1e-9


@dataclass(frozen=True)
class EsminiSettings:
    """How to run esmini.

    Attributes:
        root: the esmini folder (holding bin/ and lib/); None: ``$VEI_ESMINI``, else
            ``../shared/tools/esmini`` (see :func:`vei.esmini.find_esmini`).
        osc_version: OpenSCENARIO version of the files written ('1.0' ... '1.3').
        collision: use esmini's collision detection as a contact sensor (in addition to
            vei's oriented-box test of the measured poses).
        work_dir: folder for the runs' .xosc files and esmini's logs (kept); None: a
            temporary folder, removed at the end.
    """

    root: str | Path | None = None
    osc_version: str = "1.2"
    collision: bool = True
    work_dir: str | Path | None = None

    def __post_init__(self) -> None:
        from vei.export.openscenario import OSC_VERSIONS

        if self.osc_version not in OSC_VERSIONS:
            raise ConfigError(
                f"osc_version must be one of {', '.join(OSC_VERSIONS)}, got {self.osc_version!r}"
            )
        if not isinstance(self.collision, bool):
            raise ConfigError(f"collision must be true or false, got {self.collision!r}")


def _wrap_near(angle: float, ref: float) -> float:
    """``angle`` shifted by a multiple of 2 pi to lie within pi of ``ref`` [rad]."""
    if not math.isfinite(ref):
        return math.atan2(math.sin(angle), math.cos(angle))
    return ref + math.remainder(angle - ref, 2.0 * math.pi)


def scenario_map(scenario: Scenario) -> Path | None:
    """The scenario's OpenDRIVE file, or None when it has no map.

    Raises:
        InputError: the scenario names a map that is not there.
    """
    rel = scenario.maps.get("opendrive")
    if not rel:
        return None
    if scenario.root is None:
        raise InputError("the scenario's folder is unknown: cannot find its map", field="maps")
    path = scenario.root / rel
    if not path.is_file():
        raise InputError("OpenDRIVE map not found", path=path, field="maps")
    return path


def run_trajectories(loop: ClosedLoop) -> tuple[pd.DataFrame, list[AgentInfo]]:
    """What esmini plays in one run, as export_openscenario's input.

    Rows at the engine's steps t = k dt: the replayed road users while the recording has
    them, the rider under 'replay' while its shifted recording has it (the engine's own
    replay positions), and the ego at t = 0 (its initial pose and speed) and at the run's
    last step (so the scenario lasts the whole run; the ego is 'simulator'-controlled).

    Returns:
        (trajectories with t_s, agent_id, category, x_m, y_m, yaw_rad, speed_mps; the
        AgentInfo of each agent with the engine's footprints).
    """
    a, st, dt = loop.arrays, loop.state, loop.dt_s
    n = a.n_steps
    cols = ["t_s", "agent_id", "category", "x_m", "y_m", "yaw_rad", "speed_mps"]
    ego0 = (float(st.ego_x_m[0]), float(st.ego_y_m[0]), float(st.ego_yaw_rad[0]))
    v0 = float(st.ego_v_mps[0])
    parts = [
        pd.DataFrame(
            [
                (0.0, EGO_ID, EGO_CATEGORY, *ego0, v0),
                ((n - 1) * dt, EGO_ID, EGO_CATEGORY, *ego0, v0),
            ],
            columns=cols,
        )
    ]
    agents = [AgentInfo(EGO_ID, EGO_CATEGORY, float(a.ego_length_m), float(a.ego_width_m))]
    t = np.arange(n) * dt
    for j, oid in enumerate(a.other_ids):
        act = np.asarray(a.other_active[:n, j], dtype=bool)
        if not act.any():
            continue
        parts.append(
            pd.DataFrame(
                {
                    "t_s": t[act],
                    "agent_id": oid,
                    "category": a.other_categories[j],
                    "x_m": a.other_x_m[:n, j][act],
                    "y_m": a.other_y_m[:n, j][act],
                    "yaw_rad": a.other_yaw_rad[:n, j][act],
                    "speed_mps": a.other_speed_mps[:n, j][act],
                }
            )
        )
        agents.append(
            AgentInfo(
                oid, a.other_categories[j], float(a.other_length_m[j]), float(a.other_width_m[j])
            )
        )
    if loop.rider_replayed:
        tr = a.rider_track
        t_rec = t - loop.time_shift_s
        span = (t_rec >= tr.t0_s - _SPAN_EPS) & (t_rec <= tr.t_end_s + _SPAN_EPS)
        if span.sum() >= 1:
            i, w = tr.index(t_rec[span])
            x, y, yaw, v = tr.values_at(i, w, "x_m", "y_m", "yaw_rad", "speed_mps")
            parts.append(
                pd.DataFrame(
                    {
                        "t_s": t[span],
                        "agent_id": a.rider_id,
                        "category": a.rider_category,
                        "x_m": x,
                        "y_m": y,
                        "yaw_rad": yaw,
                        "speed_mps": v,
                    }
                )
            )
            agents.append(
                AgentInfo(
                    a.rider_id, a.rider_category, float(a.rider_length_m), float(a.rider_width_m)
                )
            )
    return pd.concat(parts, ignore_index=True)[cols], agents


def write_run_xosc(loop: ClosedLoop, out_dir: Path, *, xodr: Path | None, osc_version: str) -> Path:
    """Write one run's OpenSCENARIO file (see :func:`run_trajectories`) into ``out_dir``."""
    from vei.export.openscenario import export_openscenario

    traj, agents = run_trajectories(loop)
    # every step is a vertex: esmini plays the engine's samples; the ego is vei's to place
    return export_openscenario(
        traj, agents, out_dir, xodr=xodr, osc_version=osc_version,
        name=f"vei_{loop.case.name}".replace("/", "_"),
        ego_controller="simulator", vertex_rate_hz=None,
    )  # fmt: skip


class EsminiBackend(Backend):
    """vei's closed loop hosted by esmini through libesminiLib.so (see the module doc)."""

    name = "esmini"

    def __init__(self, settings: EsminiSettings | None = None) -> None:
        self.settings = settings or EsminiSettings()
        self._library: Path | None = None
        self._dir: Path | None = None
        self._temp = False
        self._xodr: Path | None = None
        self._session: EsminiSession | None = None
        self._loop: ClosedLoop | None = None
        self._runs = 0
        #: per run: {'config', 'xosc', 'log_bytes', 'contacts_rider', 'others_max_dev_m'}
        self.reports: list[dict[str, Any]] = []

    # ------------------------------------------------------------------ session
    def start(self, scenario: Scenario, sim: SimConfig) -> None:
        """Find the library, the scenario's map and a folder for the files."""
        from vei.esmini import find_esmini

        self._library = find_esmini(self.settings.root).require_library()
        self._xodr = scenario_map(scenario)
        if self.settings.work_dir is not None:
            self._dir = Path(self.settings.work_dir)
            self._dir.mkdir(parents=True, exist_ok=True)
            self._temp = False
        else:
            self._dir = new_log_dir()
            self._temp = True

    def close(self) -> None:
        """Close any open scenario; remove the temporary folder."""
        self.unload()
        if self._temp and self._dir is not None:
            shutil.rmtree(self._dir, ignore_errors=True)
        self._dir = None

    # ------------------------------------------------------------------ one run
    def load(self, loop: ClosedLoop) -> Measurement:
        """Write the run's .xosc, load it in esmini, return the world at t = 0."""
        if self._library is None or self._dir is None:
            raise BackendError("esmini backend: start() was not called")
        self._runs += 1
        out = self._dir / f"run{self._runs:02d}_{loop.case.name}"
        xosc = write_run_xosc(loop, out, xodr=self._xodr, osc_version=self.settings.osc_version)
        try:
            self._session = EsminiSession(
                self._library, xosc, out / "esmini.log", collision=self.settings.collision
            )
        except BackendError as exc:
            if not self._temp:
                raise
            raise BackendError(
                f"{exc} (the run's files are in a temporary folder that vei removes; keep them "
                "with EsminiSettings(work_dir=...))"
            ) from exc
        self._loop = loop
        loop.steering = False  # the ego is placed, not steered
        s = self._session
        a = loop.arrays
        # The file's ego (Init pose, its path for a player driving it) is replaced by an
        # object of the same name and box that only vei places: no story action of the
        # file can move it or change its speed.
        file_ego = s.object_id(EGO_ID)
        if file_ego is None:
            raise BackendError(f"esmini did not create the ego from {xosc}")
        s.delete_object(file_ego)
        ego = s.add_object(EGO_ID, float(a.ego_length_m), float(a.ego_width_m), EGO_HEIGHT_M)
        self._ego = ego
        self._other_names = list(a.other_ids)
        self._other_oid: dict[int, int] = {}
        self._rider_oid: int | None = None
        self._rider_added = False
        self._k = 0
        self._prev_v = float(loop.state.ego_v_mps[0])
        self._dev = np.zeros(len(a.other_ids))
        self._contacts = 0
        self.reports.append({"config": loop.case.name, "xosc": str(xosc)})
        st0 = loop.state
        s.report(
            ego,
            float(st0.ego_x_m[0]),
            float(st0.ego_y_m[0]),
            float(st0.ego_yaw_rad[0]),
            self._prev_v,
        )
        st = s.state(ego)
        meas = self._measure(
            ego_ref=(
                float(loop.state.ego_yaw_rad[0]),
                self._prev_v,
                float(loop.state.ego_a_mps2[0]),
            ),
            rider_ref=float(loop.state.rider_yaw_rad[0]),
        )
        if (
            abs(st.x - float(loop.state.ego_x_m[0])) + abs(st.y - float(loop.state.ego_y_m[0]))
            > 1e-3
        ):
            raise BackendError(
                f"esmini placed the ego at ({st.x:.3f}, {st.y:.3f}), not at its initial position "
                f"({float(loop.state.ego_x_m[0]):.3f}, {float(loop.state.ego_y_m[0]):.3f}) ({xosc})"
            )
        return meas

    def step(self, command: TickCommand) -> Measurement:
        """Report the ego (and a social-force rider), advance esmini by dt, measure."""
        s, loop = self._require()
        if not math.isfinite(command.ego_x_m):
            raise BackendError("esmini backend: the command carries no ego pose")
        s.report(
            self._ego, command.ego_x_m, command.ego_y_m, command.ego_yaw_rad, command.ego_v_mps
        )
        if command.rider_controlled:
            self._place_rider(s, loop, command)
        s.step(loop.dt_s)
        self._k += 1
        return self._measure(
            ego_ref=(command.ego_yaw_rad, command.ego_v_mps, command.ego_a_mps2),
            rider_ref=command.rider_yaw_rad,
        )

    def unload(self) -> None:
        """Close the run's scenario in esmini (and note its log size)."""
        if self._session is not None:
            self._session.close()
            if self.reports:
                log = self._session.log_path
                self.reports[-1]["log_bytes"] = log.stat().st_size if log.is_file() else 0
                self.reports[-1]["contacts_rider"] = self._contacts
                self.reports[-1]["others_max_dev_m"] = dict(
                    zip(self._other_names, map(float, self._dev), strict=True)
                )
            self._session = None
        self._loop = None

    # ------------------------------------------------------------------ helpers
    def _require(self) -> tuple[EsminiSession, ClosedLoop]:
        if self._session is None or self._loop is None:
            raise BackendError("esmini backend: no scenario loaded")
        return self._session, self._loop

    def _place_rider(self, s: EsminiSession, loop: ClosedLoop, c: TickCommand) -> None:
        a = loop.arrays
        if c.rider_active:
            if self._rider_oid is None:
                ped = a.rider_category == "pedestrian"
                self._rider_oid = s.add_object(
                    a.rider_id, float(a.rider_length_m), float(a.rider_width_m), RIDER_HEIGHT_M,
                    object_type=OBJECT_TYPE_PEDESTRIAN if ped else OBJECT_TYPE_VEHICLE,
                    category=0 if ped else CATEGORY_BICYCLE,
                )  # fmt: skip
                self._rider_added = True
            s.report(
                self._rider_oid, c.rider_x_m, c.rider_y_m, c.rider_yaw_rad, c.rider_speed_mps,
                velocity_mps=(c.rider_vx_mps, c.rider_vy_mps),
            )  # fmt: skip
        elif self._rider_oid is not None and self._rider_added:
            s.delete_object(self._rider_oid)
            self._rider_oid = None

    def _lookup(self, s: EsminiSession, name: str) -> int | None:
        return s.object_id(name)

    def _measure(self, *, ego_ref: tuple[float, float, float], rider_ref: float) -> Measurement:
        s, loop = self._require()
        a, k = loop.arrays, self._k
        yaw_ref, v_ref, a_ref = ego_ref
        st = s.state(self._ego)
        v = float(st.speed)
        acc = a_ref if abs(v - v_ref) <= 1e-9 else (v - self._prev_v) / loop.dt_s
        self._prev_v = v
        ego = EgoMeasurement(float(st.x), float(st.y), _wrap_near(float(st.h), yaw_ref), v, acc)
        # the rider: added by vei (social force) or played from the file (replay)
        if self._rider_oid is None and loop.rider_replayed:
            self._rider_oid = self._lookup(s, a.rider_id)
        rider = None
        if self._rider_oid is not None:
            rs = s.state(self._rider_oid)
            vx, vy = s.velocity(self._rider_oid)
            rider = RiderMeasurement(
                float(rs.x),
                float(rs.y),
                _wrap_near(float(rs.h), rider_ref),
                vx,
                vy,
                abs(float(rs.speed)),  # esmini's speed is signed along the heading
            )
        # the replayed road users (while the recording has them)
        others = np.full((len(a.other_ids), 4), np.nan)
        for j, name in enumerate(a.other_ids):
            if not bool(a.other_active[k, j]):
                continue
            oid = self._other_oid.get(j)
            if oid is None:
                oid = self._lookup(s, name)
                if oid is None:
                    continue
                self._other_oid[j] = oid
            os_ = s.state(oid)
            others[j] = (
                os_.x,
                os_.y,
                _wrap_near(float(os_.h), float(a.other_yaw_rad[k, j])),
                abs(float(os_.speed)),
            )
            dev = math.hypot(os_.x - a.other_x_m[k, j], os_.y - a.other_y_m[k, j])
            self._dev[j] = max(self._dev[j], dev)
        contact_rider = False
        contact_others: list[int] = []
        if self.settings.collision:
            by_id = {oid: j for j, oid in self._other_oid.items()}
            for hit in s.collisions(self._ego):
                if self._rider_oid is not None and hit == self._rider_oid:
                    contact_rider = True
                elif hit in by_id:
                    contact_others.append(by_id[hit])
        if contact_rider and bool(loop.state.rider_active[0]):
            self._contacts += 1
        return Measurement(
            ego=ego,
            rider=rider,
            contact_rider=contact_rider,
            contact_others=tuple(contact_others),
            others=others,
        )


def run_cases_frame(
    scenario: Scenario,
    cases: Any,
    time_shift_s: float,
    sim: SimConfig,
    *,
    settings: EsminiSettings | None = None,
) -> pd.DataFrame:
    """The case study's backend signature (vei.experiments.casestudy.Runner) on esmini."""
    from vei.sim.backends.base import run_backend

    return run_backend(
        EsminiBackend(settings), scenario, list(cases), time_shift_s=time_shift_s, sim=sim
    )


def esmini_runner(root: str | Path | None = None, **settings: Any):
    """A case-study Runner bound to an esmini folder: ``run_casestudy(..., backend=esmini_runner(dir))``.

    ``settings`` are further EsminiSettings fields. The returned function is named
    'esmini' (the backend name in summaries).
    """
    cfg = EsminiSettings(root=root, **settings)

    def esmini(scenario: Scenario, cases: Any, time_shift_s: float, sim: SimConfig) -> pd.DataFrame:
        return run_cases_frame(scenario, cases, time_shift_s, sim, settings=cfg)

    return esmini
