"""vei import tracks on SYNTHETIC files in each format's exact column layout (issue 35.1).

Every file here is made up by the test (names say synthetic); the column layouts are the
published ones: the inD family's (levelXdata format 1.1, ika-rwth-aachen/drone-dataset-tools
src/tracks_import.py), SinD's (its Format.md; SIND-Vis-tool/utils/DataReader.py asserts the
header), Argoverse 2's (written by the av2 package's own serializer).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest
from pyproj import Proj

from vei.cli.main import main
from vei.datasets import ind, sind
from vei.datasets.world_import import build_interaction
from vei.datasets.world_tracks import Reach, egos_in_reach
from vei.errors import InputError, NoRidersError
from vei.geo.frame import LocalFrame
from vei.geo.grid import UtmGrid
from vei.io.interaction import read_interaction, write_interaction
from vei.recon.pipeline import reconstruct

#: The published headers, verbatim.
IND_TRACKS_HEADER = (
    "recordingId,trackId,frame,trackLifetime,xCenter,yCenter,heading,width,length,xVelocity,"
    "yVelocity,xAcceleration,yAcceleration,lonVelocity,latVelocity,lonAcceleration,latAcceleration"
)
IND_META_HEADER = "recordingId,trackId,initialFrame,finalFrame,numFrames,width,length,class"
IND_REC_HEADER = (
    "recordingId,locationId,frameRate,speedLimit,weekday,startTime,duration,numTracks,"
    "numVehicles,numVRUs,latLocation,lonLocation,xUtmOrigin,yUtmOrigin,orthoPxToMeter"
)
SIND_VEH_HEADER = (
    "track_id,frame_id,timestamp_ms,agent_type,x,y,vx,vy,yaw_rad,heading_rad,length,width,"
    "ax,ay,v_lon,v_lat,a_lon,a_lat"
)
SIND_PED_HEADER = "track_id,frame_id,timestamp_ms,agent_type,x,y,vx,vy,ax,ay"
#: inD's Bendplatz (locationId 1) UTM origin and approximate location.
X0, Y0, LAT, LON = 293487.1224, 5629712.0, 50.78207, 6.07116
RATE = 25.0


def _ind_rows():
    """SYNTHETIC: car 1 east at 8 m/s along y = 0, a bicycle (2) north at 4 m/s along
    x = 10 crossing its path, a motorcycle (3) far away (150 m), a parked car (4) beside the
    bicycle, a car (5) 200 m away, an e-scooter (6) written in the layout, a pedestrian (7)."""
    rows = []

    def add(tid, cls, x0, y0, vx, vy, n, w=0.0, length=0.0):
        h = math.degrees(math.atan2(vy, vx)) if (vx or vy) else 0.0
        for k in range(n):
            t = k / RATE
            rows.append(dict(trackId=tid, frame=k, **{"class": cls}, xCenter=x0 + vx * t, yCenter=y0 + vy * t,
                             heading=h, xVelocity=vx, yVelocity=vy, width=w, length=length))  # fmt: skip

    add(1, "car", -40.0, 0.0, 8.0, 0.0, 200, 1.8, 4.5)
    add(2, "bicycle", 10.0, -20.0, 0.0, 4.0, 250)
    add(3, "motorcycle", 150.0, 150.0, 5.0, 0.0, 100)
    add(4, "car", 12.0, 5.0, 0.0, 0.0, 250, 1.8, 4.5)
    add(5, "car", 200.0, -200.0, 0.0, 8.0, 200, 1.8, 4.5)
    add(6, "escooter", 12.0, -15.0, 0.0, 3.0, 150)
    add(7, "pedestrian", 0.0, 6.0, 1.0, 0.0, 150)
    return pd.DataFrame(rows)


@pytest.fixture()
def ind_folder(tmp_path):
    folder = tmp_path / "synthetic_ind"
    ind.write_recording(folder, 3, _ind_rows(), frame_rate_hz=RATE, x_utm_origin_m=X0, y_utm_origin_m=Y0,
                        lat_location_deg=LAT, lon_location_deg=LON)  # fmt: skip
    return folder


def test_ind_writer_uses_the_published_headers(ind_folder):
    assert (ind_folder / "03_tracks.csv").read_text().splitlines()[0] == IND_TRACKS_HEADER
    assert (ind_folder / "03_tracksMeta.csv").read_text().splitlines()[0] == IND_META_HEADER
    assert (ind_folder / "03_recordingMeta.csv").read_text().splitlines()[0] == IND_REC_HEADER
    assert ind.list_recordings(ind_folder) == ["03"]


def test_ind_units_frames_and_classes(ind_folder):
    rec = ind.read_recording(ind_folder, "03")
    cats = rec.category_of()
    assert cats["2"] == "cyclist" and cats["3"] == "cyclist" and cats["6"] == "escooter"
    assert cats["7"] == "pedestrian" and cats["1"] == "vehicle"
    car = rec.track("1")
    assert car["t_s"].iloc[1] == pytest.approx(1 / RATE)  # frame / frameRate
    assert car["speed_mps"].iloc[0] == pytest.approx(8.0)
    assert car["length_m"].iloc[0] == pytest.approx(4.5)
    assert rec.track("2")["length_m"].isna().all()  # the family's 0 = no box = unknown
    # position: UTM 32N (zone of lat/lon location) of xCenter + xUtmOrigin, by pyproj directly
    utm = Proj(proj="utm", zone=32, ellps="WGS84")
    lon, lat = utm(X0 - 40.0, Y0, inverse=True)
    assert car["lat_deg"].iloc[0] == pytest.approx(lat, abs=1e-9)
    assert car["lon_deg"].iloc[0] == pytest.approx(lon, abs=1e-9)
    # heading 0 = grid east; pyproj's convergence (grid north from true north, clockwise)
    conv = utm.get_factors(lon, lat).meridian_convergence
    assert car["heading_deg"].iloc[0] == pytest.approx(90.0 + conv, abs=1e-3)
    assert -2.4 < conv < -2.2  # Aachen is 2.9 deg west of zone 32's central meridian


def test_reach_picks_the_moving_car_near_riders(ind_folder):
    rec = ind.read_recording(ind_folder, "03")
    egos = egos_in_reach(rec)
    assert [e.ego_id for e in egos] == ["1"]  # 4 is parked, 5 is 200 m from every rider
    assert egos[0].riders == ("2", "6")
    # the bicycle crosses 10 m ahead of the car's start line: the car passes x = 10 at 6.25 s
    # when the bicycle is at y = 5: gap ~ hypot(0, 5) at the 5 Hz reach sampling
    assert 3.0 < egos[0].min_gap_m < 5.5
    # with a reach of 250 m the motorcycle comes within reach of car 5 (closest ~228 m)
    assert [e.ego_id for e in egos_in_reach(rec, Reach(gap_m=250.0))] == ["1", "5"]


def test_world_interaction_keeps_world_positions(ind_folder, tmp_path):
    rec = ind.read_recording(ind_folder, "03")
    inter = build_interaction(rec, "1")
    assert inter.meta.frame == "world"
    # riders only by default; every rider recorded meanwhile, the far motorcycle too
    assert set(inter.annotations["track_id"]) == {"2", "3", "6"}
    folder = write_interaction(inter, tmp_path / "inter")
    back = read_interaction(folder)
    pd.testing.assert_frame_equal(back.annotations, inter.annotations.sort_values(["track_id", "t_s"]).reset_index(drop=True), check_dtype=False)  # fmt: skip
    scen = reconstruct(back)
    assert scen.extra["reconstruction"]["annotation_frame"].startswith("world")
    # no ego-relative round trip: keyframes are the dataset's positions projected, exactly
    plane = LocalFrame.from_proj_string(scen.projection)
    kf = scen.keyframes[scen.keyframes["source_track_id"] == "2"]
    ann = back.annotations[back.annotations["track_id"] == "2"]
    x, y = plane.to_xy(ann["lat_deg"].to_numpy(), ann["lon_deg"].to_numpy())
    assert np.abs(kf["x_m"].to_numpy() - x).max() < 1e-9
    assert np.abs(kf["y_m"].to_numpy() - y).max() < 1e-9
    # the bicycle crosses the car's path 10 m ahead at t = 5 s: distances are preserved
    grid = UtmGrid(32, False, X0, Y0)
    lat0, lon0 = grid.to_latlon(10.0, 0.0)
    px, py = plane.to_xy(lat0, lon0)
    bike = scen.track("cyclist_2")
    row = bike.iloc[int(np.argmin(np.abs(bike["t_s"].to_numpy() - 5.0)))]
    assert math.hypot(row["x_m"] - px, row["y_m"] - py) < 0.01
    no_riders = dataclasses.replace(
        rec, tracks=rec.tracks[~rec.tracks["category"].isin(["cyclist", "escooter"])]
    )
    with pytest.raises(NoRidersError):
        build_interaction(no_riders, "1")
    with pytest.raises(InputError, match="not a car"):
        build_interaction(rec, "2")


def test_rate_writes_ground_truth(ind_folder):
    rec = ind.read_recording(ind_folder, "03")
    inter = build_interaction(rec, "1", rate_hz=1.0, road_users="all")
    assert inter.ground_truth is not None
    t = inter.annotations[inter.annotations["track_id"] == "2"]["t_s"].to_numpy()
    assert np.allclose(t, np.arange(t.size))
    assert "7" in set(inter.annotations["track_id"]) and "4" in set(inter.annotations["track_id"])


@pytest.mark.parametrize(
    ("file", "col", "bad", "row"),
    [("03_tracks.csv", "xCenter", "abc", 5), ("03_tracksMeta.csv", "class", "hovercraft", 2),
     ("03_recordingMeta.csv", "frameRate", "", 1)],
)  # fmt: skip
def test_cli_bad_ind_file_exits_2_naming_file_row_column(
    ind_folder, tmp_path, capsys, file, col, bad, row
):
    path = ind_folder / file
    df = pd.read_csv(path, dtype=str, keep_default_na=False)
    df.loc[row - 1, col] = bad
    df.to_csv(path, index=False)
    code = main(
        [
            "import",
            "tracks",
            "--format",
            "ind",
            "--root",
            str(ind_folder),
            "--out",
            str(tmp_path / "o"),
        ]
    )
    assert code == 2
    err = capsys.readouterr().err
    assert file in err and f"row {row}" in err and col in err


def test_cli_imports_every_ego(ind_folder, tmp_path, capsys):
    main(
        [
            "import",
            "tracks",
            "--format",
            "ind",
            "--root",
            str(ind_folder),
            "--out",
            str(tmp_path / "o"),
        ]
    )
    assert (tmp_path / "o" / "03__ego1" / "interaction.json").is_file()
    assert "1 interaction(s)" in capsys.readouterr().out


# ------------------------------------------------------------------------------- SinD


@pytest.fixture()
def sind_folder(tmp_path):
    """SYNTHETIC SinD record: a car east, a tricycle and a motorcycle crossing, a pedestrian."""
    rows = []
    for tid, cls, x0, y0, vx, vy, n in ((12, "car", -30.0, -2.0, 7.0, 0.0, 80), (34, "tricycle", 5.0, -25.0, 0.0, 3.0, 100),
                                        (23, "motorcycle", -5.0, 20.0, 0.0, -6.0, 60)):  # fmt: skip
        for k in range(n):
            t = k * 0.1001
            rows.append(dict(track_id=tid, frame_id=k, timestamp_ms=round(t * 1000, 1), agent_type=cls,
                             x=x0 + vx * t, y=y0 + vy * t, vx=vx, vy=vy, yaw_rad=math.atan2(vy, vx),
                             length=4.5 if cls == "car" else 1.8, width=1.8 if cls == "car" else 0.8))  # fmt: skip
    ped = [dict(track_id="P1", frame_id=k, timestamp_ms=k * 100.1, x=8.0, y=8.0 - 1.2 * k * 0.1001, vx=0.0, vy=-1.2)
           for k in range(50)]  # fmt: skip
    folder = tmp_path / "synthetic_sind_record"
    sind.write_recording(folder, pd.DataFrame(rows), pd.DataFrame(ped))
    return folder


def test_sind_layout_classes_and_plane(sind_folder):
    assert (sind_folder / "Veh_smoothed_tracks.csv").read_text().splitlines()[0] == SIND_VEH_HEADER
    assert (sind_folder / "Ped_smoothed_tracks.csv").read_text().splitlines()[0] == SIND_PED_HEADER
    rec = sind.read_recording(sind_folder, origin_deg=(39.08, 117.2))
    cats = rec.category_of()
    assert cats["34"] == "cyclist" and cats["23"] == "cyclist" and cats["P1"] == "pedestrian"
    assert rec.rate_hz == pytest.approx(1 / 0.1001, rel=1e-3)
    inter = build_interaction(rec, "12")
    assert inter.meta.origin_lat_deg == 39.08
    scen = reconstruct(inter)
    # the declared origin makes the scenario plane SinD's own ground frame
    tri = scen.keyframes[scen.keyframes["source_track_id"] == "34"]
    assert np.allclose(tri["x_m"], 5.0, atol=1e-6)
    ego = scen.track("ego")
    assert ego["y_m"].to_numpy() == pytest.approx(-2.0, abs=1e-6)


def test_sind_bad_agent_type_names_row_and_column(sind_folder):
    path = sind_folder / "Veh_smoothed_tracks.csv"
    df = pd.read_csv(path, dtype=str)
    df.loc[6, "agent_type"] = "hovercraft"
    df.to_csv(path, index=False)
    with pytest.raises(InputError) as exc:
        sind.read_recording(sind_folder)
    assert exc.value.row == 7 and exc.value.field == "agent_type" and exc.value.path == path
