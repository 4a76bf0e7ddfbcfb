"""One truth for every rider (issue 32.4): a rider simulated as the primary threat has the
kinematics of the same rider replayed as another road user: its recorded speed and heading
where they are recorded. The V2X awareness messages (ETSI TS 103 300-3 clause 6.4.1,
triggered by changes of position, ground speed and heading) of each rider of a shared
recording come at the same times whichever rider is the primary."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vei.config import SimConfig, V2XConfig
from vei.policy.observation import category_code
from vei.policy.v2x import model

SCENARIO = "audi_08_klinikum_rechtsabbiegen_02"


@pytest.fixture(scope="module")
def scenario(trafficmonitoring_root, tmp_path_factory):
    from vei.datasets.trafficmonitoring import import_scenario
    from vei.io.interaction import read_interaction
    from vei.recon.pipeline import reconstruct

    base: Path = tmp_path_factory.mktemp("one_truth")
    import_scenario(trafficmonitoring_root, SCENARIO, base / "interaction", rate_hz=1.0)
    return reconstruct(read_interaction(base / "interaction"))


def _truth(scenario, rider_id: str):
    """Every rider's ground truth [6, T, N] as the policy API sees it (the primary from
    the engine's replay of it, the others from their recording) and their ids."""
    from vei.sim.engine import run_cases
    from vei.sim.observe import ground_truth, object_table
    from vei.sim.state import prepare_scenario

    sim = SimConfig()
    arrays = prepare_scenario(scenario, sim, rider_id=rider_id)
    res = run_cases(arrays, ["replay"])
    _, _, cats = object_table(arrays)
    ids = [arrays.rider_id, *arrays.riders.ids, *arrays.other_ids]
    out = []
    for k in range(arrays.n_steps):
        st = type("St", (), {})()
        st.k = k
        for name in ("x_m", "y_m", "yaw_rad", "vx_mps", "vy_mps", "active"):
            setattr(st, f"rider_{name}", getattr(res, f"rider_{name}")[:, k])
        out.append(ground_truth(st, arrays, slice(0, 1))[:, 0])
    return np.stack(out, axis=1), ids, cats, arrays.dt_s


def vam_times(scenario, rider_id: str) -> dict[str, list[float]]:
    """{rider: its VAM generation times [s]} with ``rider_id`` as the primary (every rider
    equipped, exact GNSS: the generation rules alone)."""
    truth, ids, cats, dt = _truth(scenario, rider_id)
    cfg = V2XConfig(enabled=True, position_error_std_m=0.0)
    cols = np.flatnonzero(np.isin(cats, [category_code(c) for c in cfg.sender_categories]))
    params = model.V2XParams.from_config(cfg, 1)
    keys = np.array([1])
    st = model.init_state(cfg, params, keys, cols)
    n = truth.shape[2]
    times: dict[str, list[float]] = {ids[c]: [] for c in cols}
    for k in range(truth.shape[1]):
        now = truth[:, k][:, None, :]
        w = model.World(
            x_m=now[0], y_m=now[1], yaw_rad=now[2], vx_mps=now[3], vy_mps=now[4],
            valid=now[5] > 0.5, length_m=np.ones(n), width_m=np.ones(n),
            is_vehicle=np.zeros(n, bool), ego_x_m=np.zeros(1), ego_y_m=np.zeros(1),
        )  # fmt: skip
        _, st, ev = model.step(cfg, params, st, w, cols, k, dt, keys)
        for j, c in enumerate(cols):
            if ev["sent"][0, j]:
                times[ids[c]].append(round(k * dt, 6))
    return times


def test_a_rider_sends_the_same_vams_as_primary_and_as_replayed_road_user(scenario):
    riders = [a.agent_id for a in scenario.agents if a.category in ("escooter", "cyclist")]
    assert len(riders) >= 2
    runs = {r: vam_times(scenario, r) for r in riders}
    for r in riders:
        as_primary = runs[r][r]
        assert len(as_primary) >= 3, r
        for other in riders:
            if other != r:
                assert runs[other][r] == as_primary, (r, "replayed with primary", other)


def test_the_primary_velocity_is_the_recorded_speed_along_the_recorded_heading(scenario):
    from vei.sim.riders import rider_track

    rid = scenario.primary_threat
    track, _ = rider_track(scenario, rid, "test")
    sp = track.data[:, track.col("speed_mps")]
    yaw = track.data[:, track.col("yaw_rad")]
    vx, vy = track.data[:, track.col("vx_mps")], track.data[:, track.col("vy_mps")]
    np.testing.assert_allclose(vx, sp * np.cos(yaw), atol=1e-9)
    np.testing.assert_allclose(vy, sp * np.sin(yaw), atol=1e-9)
    # the first sample too (formerly a one-sided finite difference of the positions)
    rec = scenario.track(rid)
    assert np.hypot(vx[0], vy[0]) == pytest.approx(float(rec["speed_mps"].iloc[0]), abs=1e-9)
