"""The esmini backend: vei's closed loop inside esmini (libesminiLib.so, really loaded)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tests.sim.backends.conftest import MEETING_SHIFT_S, crossing_scenario
from vei.config import PAPER_CASES, case_preset
from vei.errors import BackendError, ConfigError, DependencyError
from vei.sim.backends.base import run_backend
from vei.sim.backends.builtin import BuiltinBackend
from vei.sim.backends.esmini import EsminiBackend, EsminiSettings, run_trajectories
from vei.sim.backends.esmini_lib import EsminiSession
from vei.sim.engine import run_cases
from vei.types import TIMESERIES_COLUMNS

NUMERIC = ("t_s", "x_m", "y_m", "yaw_rad", "speed_mps", "accel_mps2")


def _assert_same_series(got, ref, atol):
    assert list(got.columns) == list(TIMESERIES_COLUMNS)
    assert len(got) == len(ref)
    for col in ("config", "agent_id", "category", "active", "collided", "cap_state"):
        assert got[col].tolist() == ref[col].tolist(), col
    for col in NUMERIC:
        np.testing.assert_allclose(got[col], ref[col], atol=atol, err_msg=col)


#: The five configurations with the paper's rider, under their usual names: with it the
#: crossing has a run that keeps clear (aggressive-cap), which the contact check needs;
#: with the calibrated default (the crossing rider's recorded 4.4 m/s) all five collide.
PAPER_RIDER_CASES = [
    case_preset(n) if n == "replay" else replace(case_preset(f"paper-{n}"), name=n)
    for n in PAPER_CASES
]


@pytest.fixture(scope="module")
def crossing_runs(tmp_path_factory, esmini):
    """The five configurations (paper's rider) of the crossing scenario (with its map) on
    esmini, files kept."""
    from tests.sim.backends.conftest import write_straight_xodr

    root = tmp_path_factory.mktemp("crossing")
    write_straight_xodr(root / "map.xodr")
    scenario = crossing_scenario(root)
    work = tmp_path_factory.mktemp("esmini-work")
    backend = EsminiBackend(EsminiSettings(root=esmini.root, work_dir=work))
    got = run_backend(backend, scenario, PAPER_RIDER_CASES, time_shift_s=MEETING_SHIFT_S)
    ref = run_cases(scenario, PAPER_RIDER_CASES, time_shift_s=MEETING_SHIFT_S).to_frame()
    return scenario, backend, got, ref, work


def test_builtin_backend_through_the_interface_equals_the_batched_engine():
    """The interface loop with the ideal plant reproduces run_cases for all five configs."""
    scenario = crossing_scenario()
    ref = run_cases(scenario, list(PAPER_CASES), time_shift_s=MEETING_SHIFT_S).to_frame()
    got = run_backend(BuiltinBackend(), scenario, list(PAPER_CASES), time_shift_s=MEETING_SHIFT_S)
    _assert_same_series(got, ref, atol=1e-6)


def test_esmini_closed_loop_equals_the_builtin_engine(crossing_runs):
    _, _, got, ref, _ = crossing_runs
    # esmini holds the reported poses exactly (doubles) and plays the replayed users on
    # their trajectories, whose vertices the export rounds to 0.1 mm and 1e-5 rad
    _assert_same_series(got, ref, atol=1e-4)
    coll = got[got["agent_id"] == "ego"].groupby("config", sort=False)["collided"].any()
    # the crossing is critical: everything but the aggressive rider with the CAP collides
    assert coll.to_dict() == {
        "replay": True,
        "normal": True,
        "aggressive": True,
        "normal-cap": True,
        "aggressive-cap": False,
    }


def test_esmini_plays_the_replayed_users_and_reports_contacts(crossing_runs):
    _, backend, _, _, work = crossing_runs
    assert [r["config"] for r in backend.reports] == list(PAPER_CASES)
    for rep in backend.reports:
        # the replayed cyclist, read back from esmini, is where the recording has it
        assert rep["others_max_dev_m"]["c1"] < 1e-4  # the export rounds to 0.1 mm
        # esmini's log is small (no warnings flood)
        assert 0 < rep["log_bytes"] < 64_000
    # esmini's own collision detection saw the ego hit the rider in the colliding runs
    contacts = {r["config"]: r["contacts_rider"] for r in backend.reports}
    assert contacts["aggressive-cap"] == 0 and contacts["normal"] > 0
    # files stay in work_dir; the map is referenced as the LogicFile next to the .xosc
    xosc = work / "run01_replay" / "vei_replay.xosc"
    text = xosc.read_text()
    assert 'LogicFile filepath="map.xodr"' in text and (xosc.parent / "map.xodr").is_file()
    assert "s7" in text  # under replay esmini plays the (time-shifted) rider
    assert "s7" not in (work / "run02_normal" / "vei_normal.xosc").read_text()


def test_run_trajectories_hold_the_engine_samples():
    from vei.config import case_preset
    from vei.sim.backends.base import ClosedLoop

    loop = ClosedLoop(crossing_scenario(), case_preset("replay"), time_shift_s=MEETING_SHIFT_S)
    traj, agents = run_trajectories(loop)
    assert {a.agent_id for a in agents} == {"ego", "c1", "s7"}
    ego = traj[traj["agent_id"] == "ego"]
    assert ego["t_s"].tolist() == [0.0, pytest.approx((loop.n_steps - 1) * loop.dt_s)]
    rider = traj[traj["agent_id"] == "s7"]
    # recorded from t = 2 s to 7 s, shifted by 2.5 s: t = 4.5 ... 9.5 s in the run, with its
    # run-in before and its run-out after (issue 22; within the run's span)
    tr = loop.arrays.rider_track
    assert loop.arrays.rider_recorded_span_s == pytest.approx((2.0, 7.0))
    t_end = (loop.n_steps - 1) * loop.dt_s
    assert rider["t_s"].min() == pytest.approx(max(0.0, tr.t0_s + 2.5), abs=0.051)
    assert rider["t_s"].max() == pytest.approx(min(t_end, tr.t_end_s + 2.5), abs=0.051)
    assert tr.t0_s < 2.0 and tr.t_end_s > 7.0
    first = rider.iloc[int(np.argmin(np.abs(rider["t_s"].to_numpy() - 4.5)))]
    assert (first["x_m"], first["y_m"]) == pytest.approx((40.0, -12.0))


def test_a_file_esmini_refuses_is_a_backend_error_and_frees_the_slot(tmp_path, esmini):
    bad = tmp_path / "bad.xosc"
    bad.write_text("<OpenSCENARIO><FileHeader/></OpenSCENARIO>")
    lib = esmini.require_library()
    with pytest.raises(BackendError, match="could not load") as exc:
        EsminiSession(lib, bad, tmp_path / "log.txt")
    assert "bad.xosc" in str(exc.value)
    with pytest.raises(BackendError, match="no scenario file"):
        EsminiSession(lib, tmp_path / "missing.xosc", tmp_path / "log.txt")
    # a scenario whose map esmini cannot read: esmini's own words, no crash
    scn = tmp_path / "badmap"
    scn.mkdir()
    (scn / "map.xodr").write_text("not OpenDRIVE")
    backend = EsminiBackend(EsminiSettings(root=esmini.root))
    with pytest.raises(BackendError, match="Failed to load OpenDRIVE file .*map.xodr"):
        run_backend(backend, crossing_scenario(scn), "normal", time_shift_s=0.0)
    # the process is fine and esmini loads the next file
    scenario = crossing_scenario()
    frame = run_backend(
        EsminiBackend(EsminiSettings(root=esmini.root)), scenario, "normal", time_shift_s=0.0
    )
    assert set(frame["config"]) == {"normal"}
    assert not list(tmp_path.glob("*.dat"))


def test_one_esmini_scenario_per_process(tmp_path, esmini, crossing_runs):
    _, _, _, _, work = crossing_runs
    lib = esmini.require_library()
    xosc = work / "run02_normal" / "vei_normal.xosc"
    with EsminiSession(lib, xosc, tmp_path / "a.txt") as first:
        assert first.object_id("ego") is not None
        with pytest.raises(BackendError, match="one scenario per process"):
            EsminiSession(lib, xosc, tmp_path / "b.txt")
    with EsminiSession(lib, xosc, tmp_path / "c.txt") as again:  # released on close
        again.step(0.05)
        assert again.time_s == pytest.approx(0.05)


def test_settings_and_missing_esmini(tmp_path):
    with pytest.raises(ConfigError, match="osc_version"):
        EsminiSettings(osc_version="2.0")
    backend = EsminiBackend(EsminiSettings(root=tmp_path / "nowhere"))
    with pytest.raises(DependencyError, match="esmini"):
        run_backend(backend, crossing_scenario(), "replay")


@pytest.mark.parametrize("osc_version", ["1.0", "1.3"])
def test_other_openscenario_versions_play_the_same_loop(osc_version, esmini, tmp_path):
    from tests.sim.backends.conftest import write_straight_xodr

    write_straight_xodr(tmp_path / "map.xodr")
    scenario = crossing_scenario(tmp_path)
    cases = ["replay", "aggressive-cap"]
    backend = EsminiBackend(EsminiSettings(root=esmini.root, osc_version=osc_version))
    got = run_backend(backend, scenario, cases, time_shift_s=MEETING_SHIFT_S)
    ref = run_cases(scenario, cases, time_shift_s=MEETING_SHIFT_S).to_frame()
    _assert_same_series(got, ref, atol=1e-4)
    assert all(r["others_max_dev_m"]["c1"] < 1e-4 for r in backend.reports)
