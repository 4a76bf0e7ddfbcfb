"""The scenarios an environment draws its episodes from, prepared once.

:func:`load_world` reads the configured source (the built-in demo, a scenario folder or a
folder of them, a ``vei catalogue``) into a :class:`World`: per scenario the engine's
:class:`vei.sim.state.ScenarioArrays`, the one-variant :class:`VariantParams` of the
configuration with the agent in the ego's seat, the automatic time shift, and the
``rider_on_road`` raster of its own OpenDRIVE map.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.config import CaseConfig
from vei.errors import ConfigError, InputError
from vei.gym.config import EnvConfig
from vei.sim.params import EGO_POLICY, VariantParams
from vei.sim.state import ScenarioArrays, prepare_scenario
from vei.types import Scenario

FloatArray = npt.NDArray[np.float64]
#: Cell of the drivable-area raster behind ``rider_on_road`` [m].
ROAD_CELL_M = 0.25
#: Margin of the raster around every trajectory of the scenario [m].
ROAD_MARGIN_M = 20.0


@dataclass(frozen=True)
class RoadRaster:
    """Drivable area of a map on a grid: ``on[i, j]`` for the cell of (x0 + j cell, y0 + i cell).

    Attributes:
        x0_m, y0_m: the grid's lower-left corner [m] (scenario plane). cell_m: cell size [m].
        on: [ny, nx] uint8, 1 where the cell centre lies on a drivable lane.
    """

    x0_m: float
    y0_m: float
    cell_m: float
    on: npt.NDArray[np.uint8]

    def lookup(self, x_m: npt.ArrayLike, y_m: npt.ArrayLike) -> npt.NDArray[np.uint8]:
        """1 where (x, y) [m] lies in a drivable cell, 0 elsewhere (outside the grid too)."""
        x = np.asarray(x_m, dtype=np.float64)
        y = np.asarray(y_m, dtype=np.float64)
        j = np.floor((x - self.x0_m) / self.cell_m)
        i = np.floor((y - self.y0_m) / self.cell_m)
        ny, nx = self.on.shape
        ok = (i >= 0) & (i < ny) & (j >= 0) & (j < nx)
        out = np.zeros(x.shape, dtype=np.uint8)
        out[ok] = self.on[i[ok].astype(np.intp), j[ok].astype(np.intp)]
        return out


def road_raster(scenario: Scenario, xodr: Path) -> RoadRaster:
    """The drivable-area raster of ``xodr`` over the scenario's trajectories (+ margin)."""
    import shapely

    from vei.maps import load_roads

    area = load_roads(xodr).drivable_area
    traj = scenario.trajectories
    x0 = float(traj["x_m"].min()) - ROAD_MARGIN_M
    y0 = float(traj["y_m"].min()) - ROAD_MARGIN_M
    nx = int(np.ceil((float(traj["x_m"].max()) + ROAD_MARGIN_M - x0) / ROAD_CELL_M))
    ny = int(np.ceil((float(traj["y_m"].max()) + ROAD_MARGIN_M - y0) / ROAD_CELL_M))
    xs = x0 + (np.arange(nx) + 0.5) * ROAD_CELL_M
    ys = y0 + (np.arange(ny) + 0.5) * ROAD_CELL_M
    gx, gy = np.meshgrid(xs, ys)
    shapely.prepare(area)
    on = shapely.contains_xy(area, gx.ravel(), gy.ravel()).reshape(ny, nx).astype(np.uint8)
    return RoadRaster(x0, y0, ROAD_CELL_M, on)


@dataclass(frozen=True)
class WorldScenario:
    """One scenario of a world.

    Attributes:
        name: the scenario's id (a catalogue's encounter id).
        folder: where it was read from (None for the in-memory demo).
        arrays: the engine's arrays. params: the configuration with the agent as the ego
            (ego_mode 'policy'), one variant, time shift 0.
        base_shift_s: the automatic time shift [s] (an episode adds the spread's draw).
        road: the drivable-area raster, or None when road features are off.
        scenario: the Scenario itself (for rendering).
    """

    name: str
    folder: Path | None
    arrays: ScenarioArrays
    params: VariantParams
    base_shift_s: float
    road: RoadRaster | None
    scenario: Scenario = field(repr=False)


@dataclass(frozen=True)
class World:
    """Every scenario of an environment and its configuration."""

    config: EnvConfig
    scenarios: tuple[WorldScenario, ...]

    @property
    def n(self) -> int:
        """Number of scenarios S."""
        return len(self.scenarios)

    @property
    def max_others(self) -> int:
        """The most replayed road users of any scenario."""
        return max(len(w.arrays.other_ids) for w in self.scenarios)


class AgentSeat:
    """The policy object in the ego's seat of the environment's variants (vei.policy API).

    The environment hands the engine the agent's demand itself (vei.sim.observe.Demand);
    this object only makes the variants policy variants and, when called by a
    :class:`vei.sim.observe.PolicyDriver`, keeps the Observation it was shown.
    """

    name = "vei.gym agent"

    def __init__(self) -> None:
        self.last_observation: Any = None

    def init_state(self, batch_size: int) -> None:
        """No memory."""
        return None

    def act(self, obs: Any, state: Any) -> tuple[Any, Any]:
        """Keep ``obs``; demand 0 (the environment supplies the real demand)."""
        from vei.policy.base import PolicyAction

        self.last_observation = obs
        return PolicyAction(accel_mps2=np.zeros(obs.batch_size)), state


def _scenario_folders(path: Path) -> list[Path]:
    if (path / "scenario.json").is_file():
        return [path]
    subs = (
        sorted(p for p in path.iterdir() if (p / "scenario.json").is_file())
        if path.is_dir()
        else []
    )
    if not subs:
        raise InputError(
            "not a scenario folder (no scenario.json) and no sub-folder is one "
            "(write one with 'vei reconstruct --out')",
            path=path,
        )
    return subs


def _catalogue(path: Path) -> list[tuple[str, Path, float | None]]:
    """(encounter id, scenario folder, stored automatic time shift [s] or None) per encounter of a
    catalogue, in the table's order of first appearance: the table has one row per
    encounter and configuration (sweep variants), the world one scenario per encounter."""
    import pandas as pd

    from vei.catalogue.store import TABLE, encounter_dir

    table = path / TABLE
    if not table.is_file():
        raise InputError(f"not a vei catalogue (no {TABLE}); run 'vei catalogue' first", path=path)
    rows = pd.read_parquet(table, columns=["encounter_id", "time_shift_auto_s"])
    if rows.empty:
        raise InputError("the catalogue has no encounter", path=table)
    rows["encounter_id"] = rows["encounter_id"].astype(str)
    spread = rows.groupby("encounter_id", sort=False)["time_shift_auto_s"].agg(["min", "max"])
    bad = spread[~np.isclose(spread["min"], spread["max"], rtol=0.0, atol=1e-9, equal_nan=True)]
    if not bad.empty:
        eid = str(bad.index[0])
        raise InputError(
            f"encounter {eid!r} has rows with different automatic time shifts "
            f"({bad.loc[eid, 'min']:g} .. {bad.loc[eid, 'max']:g} s); expected one per encounter",
            path=table,
            field="time_shift_auto_s",
        )
    first = rows.drop_duplicates("encounter_id", keep="first")
    return [  # a missing stored shift (NaN) is found again from the scenario
        (eid, encounter_dir(path, eid) / "scenario", None if np.isnan(shift) else float(shift))
        for eid, shift in zip(first["encounter_id"], first["time_shift_auto_s"], strict=True)
    ]


def _agent_params(case: CaseConfig, arrays: ScenarioArrays, seat: AgentSeat) -> VariantParams:
    base = VariantParams.from_case(case, arrays, 1)
    return base.with_values(
        ego_mode=EGO_POLICY,
        policy=np.array([seat], dtype=object),
        perception=np.array([base.perception[0]], dtype=object),
    )


def _prepare(
    config: EnvConfig, seat: AgentSeat, name: str, folder: Path | None, shift: float | None
) -> WorldScenario:
    """One scenario of the world: read, its map raster, the engine's arrays, its shift."""
    from vei.io.scenario import read_scenario
    from vei.sim.timeshift import find_time_shift

    if folder is None:  # the built-in demo, reconstructed into a temporary folder (~2 s)
        from vei.experiments.demo_map import write_demo_scenario

        folder = write_demo_scenario(Path(tempfile.mkdtemp(prefix="vei-gym-demo-")) / "demo")
    scen = read_scenario(folder)
    if name == "":
        name = scen.id
    road = None
    if config.road_features:
        rel = scen.maps.get("opendrive")
        xodr = None if rel is None else folder / rel
        if xodr is None or not xodr.is_file():
            raise InputError(
                "the scenario has no road map (map.xodr), which the observation's "
                "rider_on_road needs: reconstruct it with 'vei reconstruct --map', or set "
                "road_features=False",
                path=folder,
                field="maps.opendrive",
            )
        road = road_raster(scen, xodr)
    arrays = prepare_scenario(scen, config.sim)
    if shift is None:
        shift = float(find_time_shift(scen, sim=config.sim))
    case = config.case
    assert isinstance(case, CaseConfig)
    return WorldScenario(name, folder, arrays, _agent_params(case, arrays, seat), shift, road, scen)


#: A world of at least this many scenarios reports its loading (vei.io.progress): one
#: scenario with its map takes ~1 s, the demo ~3 s (it is reconstructed first), a
#: catalogue ~1 s per encounter, so every world says what it is doing.
PROGRESS_MIN_SCENARIOS = 1


def load_world(config: EnvConfig, seat: AgentSeat, *, progress: bool | None = None) -> World:
    """Read the configured scenarios (see the module docstring): one per scenario folder,
    one per catalogue encounter (not per catalogue row).

    Args:
        config: the environment's settings. seat: the agent's policy object.
        progress: None: report the loading (vei.io.progress: a bar on a terminal, a line
            every 10 s in a log) when the world has >= PROGRESS_MIN_SCENARIOS scenarios;
            False: silent; True: always.

    Raises:
        InputError: a folder that is no scenario (or catalogue), a scenario without a map
            while ``road_features`` is on (naming the folder and the way out).
    """
    from vei.io.progress import progress as report

    entries: list[tuple[str, Path | None, float | None]] = []
    if config.source == "demo":
        entries.append(("demo", None, None))
    elif config.source == "folder":
        assert config.path is not None
        entries += [("", folder, None) for folder in _scenario_folders(config.path)]
    else:
        assert config.path is not None
        entries += list(_catalogue(config.path))
    if not entries:
        raise ConfigError("the environment has no scenario")
    on = len(entries) >= PROGRESS_MIN_SCENARIOS if progress is None else progress
    out = []
    with report("vei.gym: preparing scenarios", len(entries), unit="scenarios",
                enabled=None if on else False) as rep:  # fmt: skip
        for name, folder, shift in entries:
            out.append(_prepare(config, seat, name, folder, shift))
            rep.advance()
    return World(config, tuple(out))


__all__ = [
    "PROGRESS_MIN_SCENARIOS",
    "AgentSeat",
    "RoadRaster",
    "World",
    "WorldScenario",
    "load_world",
    "road_raster",
]
