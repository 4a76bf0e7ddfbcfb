import json
from datetime import UTC, datetime

import numpy as np
import pandas as pd
import pytest

from vei.errors import InputError
from vei.io.scenario import read_scenario, scenario_json, write_scenario
from vei.types import TRAJECTORY_COLUMNS, AgentInfo, Scenario


def _scenario() -> Scenario:
    t = np.arange(5) / 20.0
    traj = pd.concat(
        [
            pd.DataFrame(
                {
                    "t_s": t,
                    "agent_id": "ego",
                    "source_track_id": None,
                    "category": "ego",
                    "x_m": 5.0 * t,
                    "y_m": 0.0,
                    "yaw_rad": 0.0,
                    "speed_mps": 5.0,
                }
            ),
            pd.DataFrame(
                {
                    "t_s": t[1:],
                    "agent_id": "escooter_7",
                    "source_track_id": "7",
                    "category": "escooter",
                    "x_m": 20.0,
                    "y_m": 3.0 - 2.0 * t[1:],
                    "yaw_rad": -np.pi / 2,
                    "speed_mps": 2.0,
                }
            ),
        ],
        ignore_index=True,
    )
    keyframes = pd.DataFrame(
        {
            "t_s": [0.05, 0.2],
            "agent_id": "escooter_7",
            "x_m": 20.0,
            "y_m": [2.9, 2.6],
            "yaw_rad": -np.pi / 2,
        }
    )
    return Scenario(
        id="s1",
        projection="+proj=tmerc +lat_0=48.7665000000 +lon_0=11.4334000000 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs",
        origin_lat_deg=48.7665,
        origin_lon_deg=11.4334,
        start_time_utc=datetime(2021, 2, 9, 12, 40, 35, 690000, tzinfo=UTC),
        rate_hz=20.0,
        bounds={"south_deg": 48.76, "west_deg": 11.43, "north_deg": 48.77, "east_deg": 11.44},
        agents=(
            AgentInfo("ego", "ego", 4.7, 1.85),
            AgentInfo("escooter_7", "escooter", 1.2, 0.6, "7"),
        ),
        primary_threat="escooter_7",
        trajectories=traj,
        keyframes=keyframes,
        maps={"opendrive": "map.xodr"},
        extra={"reconstruction_error": {"riders": {"mean_rmse_m": 0.25}}},
    )


def test_round_trip(tmp_path):
    sc = _scenario()
    out = write_scenario(sc, tmp_path / "scen")
    back = read_scenario(out)
    assert back.id == sc.id and back.projection == sc.projection
    assert (back.origin_lat_deg, back.origin_lon_deg) == (sc.origin_lat_deg, sc.origin_lon_deg)
    assert back.start_time_utc == sc.start_time_utc
    assert back.rate_hz == 20.0 and back.bounds == sc.bounds
    assert back.agents == sc.agents
    assert back.primary_threat == "escooter_7" and back.maps == sc.maps
    assert back.extra == sc.extra
    cols = [c for c in TRAJECTORY_COLUMNS if c != "source_track_id"]
    pd.testing.assert_frame_equal(back.trajectories[cols], sc.trajectories[cols], check_dtype=False)
    assert list(back.trajectories.columns) == list(TRAJECTORY_COLUMNS)
    # The ego has no source track (null in Parquet).
    src = back.trajectories["source_track_id"]
    assert src.isna().tolist() == [True] * 5 + [False] * 4
    assert src.dropna().tolist() == ["7"] * 4
    pd.testing.assert_frame_equal(back.keyframes, sc.keyframes, check_dtype=False)
    assert back.root == out
    doc = json.loads((out / "scenario.json").read_text())
    assert doc["format"] == "vei.scenario/1"
    assert doc["origin"] == {"lat_deg": 48.7665, "lon_deg": 11.4334}
    assert doc["start_time_utc"] == "2021-02-09T12:40:35.690000Z"
    assert doc["agents"][1] == {
        "agent_id": "escooter_7",
        "category": "escooter",
        "length_m": 1.2,
        "width_m": 0.6,
        "source_track_id": "7",
    }


def test_extra_files_are_written_inside_and_failure_leaves_nothing(tmp_path):
    sc = _scenario()
    out = write_scenario(sc, tmp_path / "a", extra_files={"note.txt": lambda p: p.write_text("hi")})
    assert (out / "note.txt").read_text() == "hi"

    def boom(path):
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        write_scenario(sc, tmp_path / "b", extra_files={"x": boom})
    assert not (tmp_path / "b").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["a"]


def _write_then(tmp_path, edit):
    out = write_scenario(_scenario(), tmp_path / "s")
    doc = json.loads((out / "scenario.json").read_text())
    edit(doc)
    (out / "scenario.json").write_text(json.dumps(doc))
    return out


@pytest.mark.parametrize(
    ("edit", "field", "match"),
    [
        (lambda d: d.pop("projection"), "projection", "missing key"),
        (lambda d: d.update(projection="+proj=utm +zone=32"), "projection", "tmerc"),
        (lambda d: d.update(format="vei.scenario/9"), "format", "unsupported"),
        (lambda d: d.update(rate_hz=-1), "rate_hz", "> 0"),
        (lambda d: d["origin"].update(lat_deg=40.0), "origin", "differs"),
        (lambda d: d.update(start_time_utc="yesterday"), "start_time_utc", "ISO 8601"),
        (
            lambda d: d["agents"][1].update(category="tram"),
            "agents[1].category",
            "unknown category",
        ),
        (lambda d: d["agents"][1].update(width_m=0), "agents[1].length_m", "> 0"),
        (lambda d: d.update(primary_threat="cyclist_1"), "primary_threat", "not an agent"),
        (lambda d: d["bounds"].pop("east_deg"), "bounds", "invalid bounds"),
    ],
)
def test_invalid_scenario_json_names_the_field(tmp_path, edit, field, match):
    out = _write_then(tmp_path, edit)
    with pytest.raises(InputError, match=match) as err:
        read_scenario(out)
    assert err.value.field == field
    assert err.value.path == out / "scenario.json"


def test_invalid_trajectories_name_row_and_field(tmp_path):
    out = write_scenario(_scenario(), tmp_path / "s")
    traj = pd.read_parquet(out / "trajectories.parquet")
    traj.loc[6, "x_m"] = np.nan
    traj.to_parquet(out / "trajectories.parquet", index=False)
    with pytest.raises(InputError) as err:
        read_scenario(out)
    assert (err.value.row, err.value.field) == (7, "x_m")

    traj = pd.read_parquet(out / "trajectories.parquet").drop(columns=["yaw_rad"])
    traj.to_parquet(out / "trajectories.parquet", index=False)
    with pytest.raises(InputError, match="missing column") as err:
        read_scenario(out)
    assert err.value.field == "yaw_rad"

    traj = _scenario().trajectories.copy()
    traj.loc[2, "agent_id"] = "ghost"
    traj.to_parquet(out / "trajectories.parquet", index=False)
    with pytest.raises(InputError, match="not listed") as err:
        read_scenario(out)
    assert (err.value.row, err.value.field) == (3, "agent_id")

    traj = _scenario().trajectories.copy()
    traj.loc[3, "t_s"] = 0.0
    traj.to_parquet(out / "trajectories.parquet", index=False)
    with pytest.raises(InputError, match="strictly increasing") as err:
        read_scenario(out)
    assert (err.value.row, err.value.field) == (4, "t_s")


def test_not_a_scenario_folder(tmp_path):
    with pytest.raises(InputError, match="no scenario.json"):
        read_scenario(tmp_path)
    (tmp_path / "scenario.json").write_text("{oops")
    with pytest.raises(InputError, match="not valid JSON"):
        read_scenario(tmp_path)


def test_extra_must_not_shadow_core_keys():
    sc = _scenario()
    bad = Scenario(**{**sc.__dict__, "extra": {"rate_hz": 3}})
    with pytest.raises(ValueError, match="core keys"):
        scenario_json(bad)
