"""Property-based tests: the TrafficMonitoring importer survives any bytes.

A miniature dataset is cut at test time from the real scenario klinikum_01_marktkauf_geradeaus
(in a temporary folder, never in the repository): its matching file, the car's INS around
the video at 20 Hz, and the camera rows of the car's own track and the e-scooter every
third frame. Each case mutates one file (bytes or one CSV cell); ``import_scenario``
must then write a valid interaction or raise vei.errors.InputError, nothing else.
Deterministic (``derandomize=True``); 200 + 200 = 400 cases.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.io.test_interaction_fuzz import _cell, _mutate, _mutation
from vei.datasets import trafficmonitoring as tm
from vei.errors import InputError

SCENARIO = "klinikum_01_marktkauf_geradeaus"
SETTINGS = dict(
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


@pytest.fixture(scope="module")
def mini(trafficmonitoring_root) -> Path:
    src = Path(trafficmonitoring_root) / tm.MEASUREMENTS_DIR
    root = Path(tempfile.mkdtemp(prefix="vei-tm-mini-"))
    meas = root / tm.MEASUREMENTS_DIR
    for sub in ("matching", "car_data", "videos/trajectory_output"):
        (meas / sub).mkdir(parents=True)
    match_name = f"{SCENARIO}{tm.MATCHING_SUFFIX}"
    shutil.copy(src / "matching" / match_name, meas / "matching" / match_name)
    matching = tm.read_matching(trafficmonitoring_root, SCENARIO)
    cam_name = f"{SCENARIO}{tm.TRAJECTORIES_SUFFIX}"
    cam = pd.read_csv(src / "videos" / "trajectory_output" / cam_name)
    keep = cam["track_id"].astype(str).isin([matching.relevant_track_id, "9"])
    cam = cam[keep & (cam["frame_id"] % 3 == 0)]
    cam.to_csv(meas / "videos" / "trajectory_output" / cam_name, index=False)
    ins = pd.read_csv(src / "car_data" / matching.ins_file_name)
    ins = ins.iloc[::5]
    tow = ins["gps_tow"].to_numpy()
    t_video = (
        matching.start_utc - tm.gps_to_utc(int(ins["week"].iloc[0]), float(tow[0]))
    ).total_seconds()
    span = cam["frame_id"].max() / tm.CAMERA_FPS
    sel = (tow - tow[0] >= t_video - 1.0) & (tow - tow[0] <= t_video + span + 1.0)
    ins[sel].to_csv(meas / "car_data" / matching.ins_file_name, index=False)
    tm.import_scenario(root, SCENARIO, root / "check")  # the unmutated miniature imports
    yield root
    shutil.rmtree(root, ignore_errors=True)


def _files(root: Path) -> list[Path]:
    meas = root / tm.MEASUREMENTS_DIR
    return sorted(p for p in meas.rglob("*.csv"))


def _check(root: Path) -> None:
    out = root / "out"
    try:
        tm.import_scenario(root, SCENARIO, out)
    except InputError as exc:
        assert str(exc).strip()
        return
    from vei.io.interaction import read_interaction

    assert len(read_interaction(out).annotations) > 0


class _Copy:
    def __init__(self, base: Path) -> None:
        self.tmp = Path(tempfile.mkdtemp(prefix="vei-tm-case-"))
        self.root = self.tmp / "d"
        shutil.copytree(base / "data", self.root / "data")

    def __enter__(self) -> Path:
        return self.root

    def __exit__(self, *exc) -> None:
        shutil.rmtree(self.tmp, ignore_errors=True)


@settings(max_examples=200, **SETTINGS)
@given(which=st.integers(0, 2), ops=st.lists(_mutation, min_size=1, max_size=4))
@pytest.mark.slow
def test_byte_mutations(mini, which, ops):
    with _Copy(mini) as root:
        path = _files(root)[which]
        path.write_bytes(_mutate(path.read_bytes(), ops))
        _check(root)


@settings(max_examples=200, **SETTINGS)
@given(which=st.integers(0, 2), row=st.integers(0, 400), col=st.integers(0, 20), cell=_cell)
@pytest.mark.slow
def test_csv_cells(mini, which, row, col, cell):
    with _Copy(mini) as root:
        path = _files(root)[which]
        lines = path.read_text().split("\n")
        r = row % max(1, len(lines) - 1)
        cells = lines[r].split(",")
        cells[col % len(cells)] = cell
        lines[r] = ",".join(cells)
        path.write_text("\n".join(lines), encoding="utf-8", errors="surrogatepass")
        _check(root)


def test_summary_says_when_each_track_is_seen(trafficmonitoring_root, tmp_path):
    s = tm.import_scenario_with_summary(trafficmonitoring_root, SCENARIO, tmp_path / "i")
    by_id = {t["track_id"]: t for t in s.track_times}
    from vei.io.interaction import read_interaction

    ann = read_interaction(s.out).annotations
    assert set(by_id) == set(ann["track_id"])
    for tid, g in ann.groupby("track_id"):
        assert by_id[tid]["first_s"] == pytest.approx(g["t_s"].min())
        assert by_id[tid]["last_s"] == pytest.approx(g["t_s"].max())
        assert by_id[tid]["n_annotations"] == len(g)
        assert by_id[tid]["category"] == g["category"].iloc[0]


@pytest.mark.parametrize(
    ("file", "column", "value", "row"),
    [
        ("ins", "week", "1e30", 1),  # was OverflowError: Python int too large to convert to C int
        ("ins", "week", "1000000", 1),  # was OverflowError: date value out of range
        ("ins", "gps_tow", "1e300", 3),
        ("ins", "rpy_z", "1e308", 1),  # was an error about annotations.csv of the output
        ("ins", "pos_y", "48.7", 2),  # degrees where radians are expected
        ("camera", "coordinate_world_x_opt", "1e300", 1),
        ("camera", "frame_id", "-5", 2),
    ],
)
def test_implausible_numbers_name_file_row_and_field(mini, file, column, value, row):
    with _Copy(mini) as root:
        files = _files(root)
        path = files[0] if file == "ins" else files[2]
        df = pd.read_csv(path, dtype=str)
        df.loc[row - 1, column] = value
        df.to_csv(path, index=False)
        with pytest.raises(InputError) as err:
            tm.import_scenario(root, SCENARIO, root / "out")
        assert err.value.field == column and err.value.row == row
        assert err.value.path.name == path.name
