"""The backend-independent closed loop: what a measurement does to the controllers' state."""

from __future__ import annotations

import numpy as np
import pytest

from tests.sim.backends.conftest import MEETING_SHIFT_S, crossing_scenario
from vei.config import case_preset
from vei.errors import ConfigError
from vei.sim.backends.base import (
    ClosedLoop,
    EgoMeasurement,
    Measurement,
    RiderMeasurement,
    resolve_case_list,
)


def _ideal(cmd) -> EgoMeasurement:
    return EgoMeasurement(cmd.ego_x_m, cmd.ego_y_m, cmd.ego_yaw_rad, cmd.ego_v_mps, cmd.ego_a_mps2)


def test_measured_ego_sets_the_arc_length_by_projection():
    """The crossing's ego path is the line y = -1.5 from x = 0: a measured ego 0.5 m ahead
    of the engine's prediction is 0.5 m further along; 0.3 m to the side, no further."""
    loop = ClosedLoop(crossing_scenario(), case_preset("normal"), time_shift_s=MEETING_SHIFT_S)
    st = loop.state
    loop.observe(EgoMeasurement(float(st.ego_x_m[0]), -1.5, 0.0, 5.6, 0.0))
    cmd = loop.command()
    s_pred = float(loop.state.ego_s_m[0])
    assert s_pred == pytest.approx(cmd.ego_x_m)  # s = x on this path
    loop.observe(EgoMeasurement(cmd.ego_x_m + 0.5, -1.5, 0.0, 5.0, -1.0))
    assert float(loop.state.ego_s_m[0]) == pytest.approx(s_pred + 0.5, abs=1e-6)
    assert float(loop.state.ego_v_mps[0]) == 5.0 and float(loop.state.ego_a_mps2[0]) == -1.0
    cmd = loop.command()
    s_pred = float(loop.state.ego_s_m[0])
    loop.observe(EgoMeasurement(cmd.ego_x_m, -1.2, 0.0, 5.0, 0.0))
    assert float(loop.state.ego_s_m[0]) == pytest.approx(s_pred, abs=1e-6)
    assert float(loop.state.ego_y_m[0]) == -1.2


def test_measured_rider_replaces_the_state_while_active_and_not_after_a_collision():
    import dataclasses

    base = case_preset("normal-cap")  # with a perception delay: the CAP's buffer is used
    case = dataclasses.replace(base, cap=dataclasses.replace(base.cap, perception_delay_s=0.2))
    loop = ClosedLoop(crossing_scenario(), case, time_shift_s=MEETING_SHIFT_S)
    assert loop.state.hist.shape[1] > 1
    cmd = None
    st = loop.state
    meas = EgoMeasurement(float(st.ego_x_m[0]), float(st.ego_y_m[0]), 0.0, 5.6, 0.0)
    rider = RiderMeasurement(99.0, 99.0, 0.0, 1.0, 0.0, 1.0)
    loop.observe(Measurement(meas, rider=rider))  # rider not in the scene yet: ignored
    first = loop.arrays.rider_track.data[0]  # waits at its run-in's first pose (issue 22)
    assert float(loop.state.rider_x_m[0]) == first[0]
    assert float(loop.state.rider_x_m[0]) == pytest.approx(40.0)
    while cmd is None or not cmd.rider_active:
        cmd = loop.command()
        if not cmd.rider_active:
            loop.observe(_ideal(cmd))
    # the rider entered near (40, -12 - its run-in): a measurement replaces the engine's pose
    loop.observe(Measurement(_ideal(cmd), rider=RiderMeasurement(40.2, -12.0, 1.5, 0.0, 4.0, 4.0)))
    assert float(loop.state.rider_x_m[0]) == 40.2
    assert float(loop.state.rider_speed_mps[0]) == 4.0
    # the perception buffer holds the measured pose too
    hist = loop.state.hist
    assert hist[0, loop.state.k % hist.shape[1], 0] == 40.2
    # a contact latches the collision; then measured riders no longer move it
    loop.command()
    loop.observe(Measurement(_ideal(loop.command()), contact_rider=True))
    assert bool(loop.state.collided[0])
    frozen = float(loop.state.rider_x_m[0])
    loop.command()
    loop.observe(Measurement(_ideal(loop.command()), rider=RiderMeasurement(0, 0, 0, 0, 0, 0)))
    assert float(loop.state.rider_x_m[0]) == frozen


def test_measured_others_latch_contacts_and_enter_the_time_series():
    """The replayed cyclist c1 rides west along y = 1.5 from x = 150 at 5 m/s."""
    loop = ClosedLoop(crossing_scenario(), case_preset("replay"), time_shift_s=0.0)
    st = loop.state
    ego = EgoMeasurement(float(st.ego_x_m[0]), float(st.ego_y_m[0]), 0.0, 5.6, 0.0)
    far = np.array([[150.0, 1.5, np.pi, 5.0]])
    loop.observe(Measurement(ego, others=far))
    assert not loop.state.hit_other.any()
    # the simulator has the cyclist overlapping the ego: latched (box test)
    cmd = loop.command()
    on_ego = np.array([[cmd.ego_x_m + 1.0, cmd.ego_y_m, np.pi, 5.0]])
    loop.observe(Measurement(_ideal(cmd), others=on_ego))
    assert loop.state.hit_other[0, 0]
    # a contact reported by the simulator latches too
    loop2 = ClosedLoop(crossing_scenario(), case_preset("replay"), time_shift_s=0.0)
    loop2.observe(Measurement(ego, contact_others=(0,)))
    assert loop2.state.hit_other[0, 0]
    frame = loop.to_frame()
    c1 = frame[frame["agent_id"] == "c1"]
    assert c1["x_m"].tolist()[:2] == [150.0, pytest.approx(cmd.ego_x_m + 1.0)]


def test_case_list():
    assert [c.name for c in resolve_case_list("normal")] == ["normal"]
    with pytest.raises(ConfigError):
        resolve_case_list([])
