import numpy as np
import pandas as pd
import pytest

from vei.boxes import box_gap
from vei.experiments.demo_data import (
    DEMO_TRACK_ID,
    DemoSpec,
    demo_interaction,
    write_demo_interaction,
)
from vei.geo.frame import LocalFrame
from vei.io.interaction import read_interaction

SPEC = DemoSpec()
FRAME = LocalFrame(SPEC.origin_lat_deg, SPEC.origin_lon_deg)


@pytest.fixture(scope="module")
def demo():
    return demo_interaction()


def test_deterministic_and_labelled_synthetic(demo):
    again = demo_interaction()
    pd.testing.assert_frame_equal(demo.ego, again.ego)
    pd.testing.assert_frame_equal(demo.annotations, again.annotations)
    assert "synthetic" in demo.meta.id
    assert demo.meta.source.startswith("synthetic")
    assert "SYNTHETIC" in demo.meta.notes
    other = demo_interaction(DemoSpec(seed=1))
    assert not np.allclose(other.annotations["x_m"], demo.annotations["x_m"])


def test_shaped_like_the_paper_case(demo):
    ego = demo.ego
    assert len(ego) == 251 and ego["t_s"].iloc[-1] == pytest.approx(25.0)  # 25 s at 10 Hz
    assert np.diff(ego["t_s"]).tolist() == pytest.approx([0.1] * 250)
    assert ego["speed_mps"].median() == pytest.approx(5.6, abs=0.05)
    assert ego["heading_deg"].median() == pytest.approx(90.0, abs=0.5)  # driving east
    # e-scooter truth: 4.0-4.8 m/s on the street, crossing from south of the lane to the north
    gt = demo.ground_truth
    x, y = FRAME.to_xy(gt["lat_deg"].to_numpy(), gt["lon_deg"].to_numpy())
    t = gt["t_s"].to_numpy()
    v = np.hypot(np.diff(x), np.diff(y)) / np.diff(t)
    assert v.min() >= 3.95 and v.max() <= 4.85
    assert y[0] == pytest.approx(-2.6, abs=0.01)
    assert y[-1] > 3.5  # past the north kerb of the two-lane street


def test_annotations_at_one_fps_in_the_camera_view(demo):
    ann = demo.annotations
    assert demo.meta.y_axis == "right" and demo.meta.annotation_rate_hz == 1.0
    assert np.allclose(ann["t_s"], np.round(ann["t_s"]))
    assert np.diff(ann["t_s"]).tolist() == [1.0] * (len(ann) - 1)
    assert len(ann) >= 10
    assert (ann["x_m"] > 0).all()
    assert (np.degrees(np.arctan2(np.abs(ann["y_m"]), ann["x_m"])) <= SPEC.fov_half_deg + 3).all()
    assert set(ann["track_id"]) == {DEMO_TRACK_ID}


def test_annotations_agree_with_ground_truth_within_the_noise(demo):
    ego = demo.ego.set_index("t_s")
    ann = demo.annotations
    e = ego.loc[ann["t_s"]]
    wx, wy = FRAME.ego_relative_to_world(
        e["lat_deg"], e["lon_deg"], e["heading_deg"], ann["x_m"], -ann["y_m"]
    )
    gt = demo.ground_truth.set_index("t_s").loc[ann["t_s"]]
    gx, gy = FRAME.to_xy(gt["lat_deg"].to_numpy(), gt["lon_deg"].to_numpy())
    err = np.hypot(wx - gx, wy - gy)
    assert np.sqrt(np.mean(err**2)) < 0.6
    assert err.max() < 1.5
    assert err.mean() > 0.02  # there is noise


def test_recording_itself_has_no_collision(demo):
    gt = demo.ground_truth
    ego = demo.ego
    ex, ey = FRAME.to_xy(ego["lat_deg"].to_numpy(), ego["lon_deg"].to_numpy())
    gx, gy = FRAME.to_xy(gt["lat_deg"].to_numpy(), gt["lon_deg"].to_numpy())
    assert box_gap(ex, ey, 0.0, 4.7, 1.85, gx, gy, 0.0, 1.2, 0.6).min() > 5.0


def test_written_folder_reads_back(tmp_path, demo):
    folder = write_demo_interaction(tmp_path / "demo")
    back = read_interaction(folder)
    assert back.meta.id == demo.meta.id
    assert len(back.annotations) == len(demo.annotations)
    assert back.annotations["x_m"].to_numpy() == pytest.approx(demo.annotations["x_m"].to_numpy())
    assert back.ground_truth is not None and len(back.ground_truth) == 251
