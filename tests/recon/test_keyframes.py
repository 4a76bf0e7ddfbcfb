import math

import numpy as np
import pandas as pd
import pytest

from vei.recon.keyframes import KEYFRAME_COLUMNS, agent_id_for, build_keyframes, motion_yaw


def test_motion_yaw_hand_values():
    # One-sided differences at the ends, central ones (previous -> next) in between:
    # k=1: (0,0)->(4,2) = atan(1/2); k=2: (2,0)->(4,4) = atan(2).
    xy = np.array([[0.0, 0.0], [2.0, 0.0], [4.0, 2.0], [4.0, 4.0]])
    yaw = np.degrees(motion_yaw(xy))
    assert yaw == pytest.approx(
        [0.0, math.degrees(math.atan(0.5)), math.degrees(math.atan(2.0)), 90.0]
    )


def test_motion_yaw_holds_through_jitter_and_standing():
    xy = np.array([[0.0, 0.0], [0.0, 2.0], [0.1, 2.1], [0.05, 2.05], [0.1, 2.0]])
    yaw = np.degrees(motion_yaw(xy, min_move_m=0.5))
    # Keyframes 0 and 1 see the 2 m move north (k=1: (0,0)->(0.1,2.1)); 2-4 only jitter
    # (< 0.5 m between neighbours) and take the nearest valid yaw, keyframe 1's.
    assert yaw[:2] == pytest.approx([90.0, math.degrees(math.atan2(2.1, 0.1))])
    assert yaw[2:] == pytest.approx([yaw[1]] * 3)
    assert motion_yaw(np.zeros((3, 2))) == pytest.approx([0.0, 0.0, 0.0])


def test_build_keyframes_ids_yaw_sources_and_majority_category():
    world = pd.DataFrame(
        {
            "t_s": [1.0, 0.0, 2.0, 0.0, 1.0],
            "track_id": ["7", "7", "7", "9", "9"],
            "category": ["escooter", "escooter", "cyclist", "cyclist", "cyclist"],
            "x_m": [1.0, 0.0, 2.0, 5.0, 5.0],
            "y_m": [0.0, 0.0, 0.0, 0.0, 3.0],
            "yaw_rad": [np.nan, np.nan, 1.0, np.nan, np.nan],
        }
    )
    kf = build_keyframes(world)
    assert list(kf.columns) == list(KEYFRAME_COLUMNS)
    a = kf[kf["agent_id"] == "escooter_7"]
    assert a["t_s"].tolist() == [0.0, 1.0, 2.0]
    assert a["yaw_rad"].tolist() == pytest.approx([0.0, 0.0, 1.0])
    assert a["yaw_source"].tolist() == ["motion", "motion", "annotation"]
    b = kf[kf["agent_id"] == "cyclist_9"]
    assert b["yaw_rad"].tolist() == pytest.approx([math.pi / 2, math.pi / 2])
    assert agent_id_for("escooter", "7") == "escooter_7"
    assert set(kf["source_track_id"]) == {"7", "9"}
