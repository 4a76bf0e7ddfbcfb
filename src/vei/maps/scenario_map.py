"""Give a reconstructed scenario its road map (paper Section III-B, steps 2-3).

bounds -> configured OSM source -> OpenDRIVE in the scenario's own plane, then the
alignment check: the share of ego samples that lie on a drivable lane.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from vei.geo import Bounds, LocalFrame
from vei.maps.attach import MapConfig, attach_map
from vei.maps.roads import RoadGeometry, drivable_share, load_roads
from vei.types import EGO_ID, Scenario


def add_map(
    scenario: Scenario,
    workdir: str | Path,
    *,
    source: str | Path = "auto",
    config: MapConfig | None = None,
) -> tuple[Scenario, dict[str, Path], RoadGeometry]:
    """Build the scenario's map in ``workdir`` and return the scenario that names it.

    Args:
        scenario: a reconstructed scenario (its bounds and projection define the region
            and the plane of the map).
        workdir: folder the map files are built in (created).
        source: 'auto' (``$VEI_OSM_SOURCE`` else Overpass), 'overpass', or a file: OSM
            extract (.osm/.osm.pbf), SUMO network (.net.xml[.gz]) or OpenDRIVE (.xodr).
        config: map build settings (default :meth:`MapConfig.from_env`).
    Returns:
        (scenario with ``maps`` = {'opendrive': 'map.xodr', ...} and ``extra['map']``
        holding the build report and ``ego_on_drivable_share`` in [0, 1],
        {file name: built path} to copy into the scenario folder,
        the lane geometry for drawing).
    """
    work = Path(workdir)
    info = attach_map(
        Bounds.from_dict(scenario.bounds),
        LocalFrame.from_proj_string(scenario.projection),
        work,
        source=source,
        config=config,
    )
    roads = load_roads(work / info["opendrive"])
    ego = scenario.trajectories[scenario.trajectories["agent_id"] == EGO_ID]
    share = drivable_share(
        roads, ego["x_m"].to_numpy(dtype=np.float64), ego["y_m"].to_numpy(dtype=np.float64)
    )
    files = {
        name: work / name
        for key in ("opendrive", "osm", "sumo_net")
        if (name := info.get(key)) is not None
    }
    maps = {key: info[key] for key in ("opendrive", "osm", "sumo_net") if info.get(key)}
    extra = dict(scenario.extra)
    extra["map"] = {**info, "ego_on_drivable_share": float(share)}
    return dataclasses.replace(scenario, maps=maps, extra=extra), files, roads
