"""Where a contact happened: recorded behaviour, run-in or run-out (issue 31), by hand on
a labelled track, through the engine (both kernels equal) and through ``vei run`` of a
sweep's variants on a shared recording (the same label)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from vei.continuation.where import Route, route_of, run_where, secondary_party, where
from vei.types import CONTINUATION_COLUMN


def _scenario_with(track: pd.DataFrame):
    from types import SimpleNamespace

    return SimpleNamespace(track=lambda aid: track)


def _track() -> pd.DataFrame:
    """A rider along +x at 1 m/s: run-in t in [0, 0.9] (x -1 .. -0.1), recorded t in
    [1, 3] (x 0 .. 2), run-out t in [3.1, 4] (x 2.1 .. 3); 0.1 s samples."""
    t = np.round(np.arange(0.0, 4.0001, 0.1), 6)
    x = t - 1.0
    cont = (t < 1.0 - 1e-9) | (t > 3.0 + 1e-9)
    return pd.DataFrame({"t_s": t, "x_m": x, "y_m": np.zeros_like(t), CONTINUATION_COLUMN: cont})


def test_route_labels_its_samples():
    route = route_of(_scenario_with(_track()), "r")
    assert route.span_s == (1.0, 3.0)
    lab = dict(zip(np.round(route.points_m[:, 0], 6), route.label, strict=True))
    assert lab[-1.0] == 1 and lab[-0.1] == 1  # run-in
    assert lab[0.0] == 0 and lab[2.0] == 0  # recorded (both ends of the span)
    assert lab[2.1] == 2 and lab[3.0] == 2  # run-out


def test_replayed_by_time_social_force_by_position():
    route = route_of(_scenario_with(_track()), "r")
    t = [0.5, 1.0, 2.0, 3.0, 3.5, 2.0]
    xy = [[9.0, 9.0]] * 6  # a replayed rider's position is not looked at
    got = where(route, t, xy, [False] * 6, [True, True, True, True, True, False])
    assert list(got) == ["run-in", "recorded", "recorded", "recorded", "run-out", ""]
    # social force: before its span it rides its run-in replayed; then its position counts,
    # whatever its recording time (a slowed rider still on its recorded route is recorded)
    got = where(route, [0.5, 3.5, 2.0, 1.5], [[5.0, 0.0], [1.0, 0.3], [2.6, -0.2], [-0.5, 0.0]],
                [True] * 4, [True] * 4)  # fmt: skip
    assert list(got) == ["run-in", "recorded", "run-out", "run-in"]


def test_a_track_without_continuation_is_all_recorded():
    tr = _track().assign(**{CONTINUATION_COLUMN: False})
    route = route_of(_scenario_with(tr), "r")
    assert route.span_s == (0.0, 4.0)
    assert list(where(route, [0.5, 3.9], [[0, 0]] * 2, [False, True], [True, True])) == [
        "recorded",
        "recorded",
    ]
    empty = Route("x", (float("nan"), float("nan")))
    assert list(where(empty, [1.0], [[0, 0]], [False], [True])) == ["recorded"]


def test_secondary_contacts_label_the_other_road_user():
    assert secondary_party("ego", "car_3", "rider") == "car_3"
    assert secondary_party("rider", "ped_1", "rider") == "ped_1"
    assert secondary_party("car_1", "car_2", "rider") == "car_2"
    assert secondary_party("", "", "rider") == ""
    routes = {"rider": route_of(_scenario_with(_track()), "rider"),
              "car_3": route_of(_scenario_with(_track()), "car_3")}  # fmt: skip
    out = run_where(
        routes, "rider", collision_time_s=[2.2, np.nan], time_shift_s=[1.0, 0.0],
        rider_xy_m=[[0, 0], [0, 0]], rider_sfm=[False, False], secondary_time_s=[np.nan, 3.6],
        secondary_striker=["", "car_3"], secondary_struck=["", "ego"],
    )  # fmt: skip
    assert list(out["contact"]) == ["recorded", ""]  # recording time 2.2 - 1.0 = 1.2
    assert list(out["secondary"]) == ["", "run-out"]


def test_engine_labels_by_the_recording_time_both_kernels_alike():
    """The demo's replay rider: a contact at t_c with shift tau is on the rider's run-in
    exactly where t_c - tau precedes its first recorded sample (hand rule), and the
    compiled kernel says what the NumPy engine says."""
    pytest.importorskip("numba")
    from vei.config import SimConfig, case_preset
    from vei.experiments.demo_data import demo_interaction
    from vei.recon.pipeline import reconstruct
    from vei.sim.engine import simulate_metrics
    from vei.sim.state import VariantParams, prepare_scenario

    scen = reconstruct(demo_interaction())
    arrays = prepare_scenario(scen, SimConfig())
    lo, hi = arrays.routes[scen.primary_threat].span_s
    shifts = np.linspace(-6.0, 10.0, 33)
    params = VariantParams.concat(
        [VariantParams.from_case(case_preset(c), arrays, shifts.size, time_shift_s=shifts)
         for c in ("replay", "normal")]
    )  # fmt: skip
    names = ("collision", "collision_time_s", "contact_where", "collision_recorded")
    a = simulate_metrics(arrays, params, names=names, kernel="numba")
    b = simulate_metrics(arrays, params, names=names, kernel="numpy")
    pd.testing.assert_frame_equal(a, b)
    rep = a.iloc[: shifts.size]
    t_rec = rep["collision_time_s"].to_numpy() - shifts
    hit = rep["collision"].to_numpy(bool)
    expect = np.where(
        t_rec < lo - 1e-6, "run-in", np.where(t_rec > hi + 1e-6, "run-out", "recorded")
    )
    assert hit.sum() >= 5
    assert list(rep["contact_where"][hit]) == list(expect[hit])
    assert set(rep["contact_where"][hit]) == {"recorded", "run-in"}
    assert (a["collision_recorded"] == (a["contact_where"] == "recorded")).all()
    assert (a["contact_where"][~a["collision"]] == "").all()


@pytest.mark.slow
def test_vei_run_of_a_sweep_variant_shows_the_same_place(tmp_path, trafficmonitoring_root):
    """audi_08_klinikum_rechtsabbiegen_02, the cyclist turning beside the car, rider made
    social-force: shifts 4.4-4.6 s meet it on its recorded track, 4.8-5.2 s on its run-in
    (measured); each variant re-run with ``vei run`` gives the same label (and every other
    metric, bit for bit)."""
    from tests.experiments.rerun import assert_runs_equal_sweep
    from vei.cli.main import main
    from vei.sweep.run import read_results, run_sweep, write_variant_configs
    from vei.sweep.spec import spec_from_dict

    inter, scen = tmp_path / "inter", tmp_path / "scen"
    name = "audi_08_klinikum_rechtsabbiegen_02"
    assert main(["import", "trafficmonitoring", "--root", str(trafficmonitoring_root),
                 "--scenario", name, "--out", str(inter)]) == 0  # fmt: skip
    assert main(["reconstruct", str(inter), "--out", str(scen), "--no-figure"]) == 0
    spec = spec_from_dict(
        {"design": "grid", "base": "normal", "time_shift_reference": "zero",
         "parameters": {"time_shift_s": {"choices": [4.4, 4.6, 4.8, 5.0, 5.2]}}}
    )  # fmt: skip
    run_sweep(scen, spec, tmp_path / "sweep", progress=False)
    df = read_results(tmp_path / "sweep")
    assert {"recorded", "run-in"} <= set(df["contact_where"])
    paths = write_variant_configs(tmp_path / "configs", df, spec, None)
    assert assert_runs_equal_sweep(scen, paths, df, tmp_path / "runs") > 0
