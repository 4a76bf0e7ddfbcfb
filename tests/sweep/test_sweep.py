"""Sweeps through the real engine on the synthetic demo scenario: results, resume, Ray."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vei.config import RunConfig, load_config
from vei.errors import ConfigError, InputError
from vei.sweep.run import (
    EngineEvaluator,
    done_ids,
    find_scenarios,
    most_critical,
    read_results,
    run_sweep,
    variant_params,
)
from vei.sweep.spec import row_params, spec_from_dict, variant_config, variants_table

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def demo_scenario(tmp_path_factory) -> Path:
    """The synthetic demo interaction, reconstructed (H7's generator -> H2's pipeline)."""
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


def _plane_spec(n_shift: int, n_speed: int, **extra) -> dict:
    return {
        "design": "grid",
        "base": "normal",
        "parameters": {
            "time_shift_s": {"min": -3.0, "max": 3.0, "num": n_shift},
            "ego.cruise_speed_mps": {"min": 3.0, "max": 9.0, "num": n_speed},
        },
        **extra,
    }


def test_small_sweep_writes_every_row_and_the_outputs(demo_scenario, tmp_path):
    spec = spec_from_dict(_plane_spec(7, 5))
    res = run_sweep(demo_scenario, spec, tmp_path / "out", chunk_size=8, progress=False)
    assert (res.n_variants, res.n_run, res.n_skipped) == (35, 35, 0)
    df = read_results(tmp_path / "out")
    table = variants_table(spec, "demo-indianapolis-synthetic")
    assert list(df["variant_id"]) == list(table["variant_id"])  # sorted by variant_index
    assert df["variant_id"].is_unique
    for col in (
        "seed",
        "time_shift_s",
        "ego.cruise_speed_mps",
        "collision",
        "safety_index",
        "min_gap_m",
    ):
        assert col in df.columns
    assert df["collision"].dtype == bool
    # paper's override: safety index 0 exactly where there is a collision
    assert (df.loc[df["collision"], "safety_index"] == 0.0).all()
    assert (df.loc[df["collision"], "min_gap_m"] == 0.0).all()
    assert (df.loc[~df["collision"], "min_gap_m"] > 0.0).all()
    # the landscape has both outcomes (the boundary lies inside the box)
    assert 0 < df["collision"].sum() < len(df)
    # absolute shift = automatic shift + offset
    manifest = json.loads((tmp_path / "out" / "sweep.json").read_text())
    assert manifest["status"] == "complete" and manifest["n_variants"] == 35
    auto = df["time_shift_applied_s"] - df["time_shift_s"]
    assert np.allclose(auto, auto.iloc[0]) and 0.0 < auto.iloc[0] < 25.0
    assert len(list((tmp_path / "out" / "parts").glob("part-*.parquet"))) == 5  # ceil(35 / 8)
    crit = pd.read_csv(tmp_path / "out" / "critical.csv")
    assert crit["collision"].iloc[0]  # collisions first
    assert (tmp_path / "out" / "riskmap.png").stat().st_size > 10_000


def test_critical_config_reruns_to_the_same_result(demo_scenario, tmp_path):
    from vei.io.scenario import read_scenario
    from vei.metrics import summarize
    from vei.sim.engine import simulate
    from vei.sim.state import VariantParams, prepare_scenario

    spec = spec_from_dict(_plane_spec(5, 3))
    run_sweep(demo_scenario, spec, tmp_path / "out", chunk_size=64, progress=False)
    df = read_results(tmp_path / "out")
    configs = sorted((tmp_path / "out" / "configs").glob("*.yaml"))
    assert len(configs) == min(20, len(df))
    scenario = read_scenario(demo_scenario)
    for path in configs[:4]:
        cfg = load_config(path, RunConfig)
        arrays = prepare_scenario(scenario, cfg.sim)  # its continuations' reach (issue 22)
        row = df[df["variant_id"] == path.stem].iloc[0]
        assert cfg.time_shift == pytest.approx(row["time_shift_applied_s"], abs=0)
        p = VariantParams.from_case(cfg.case, arrays, 1, time_shift_s=cfg.time_shift)
        again = summarize(simulate(arrays, p).to_trace())
        assert bool(again["collision"][0]) == bool(row["collision"])
        assert again["safety_index"][0] == pytest.approx(row["safety_index"], abs=1e-12)
        assert again["min_gap_m"][0] == pytest.approx(row["min_gap_m"], abs=1e-9)


def test_variant_params_equal_each_rows_own_configuration(demo_scenario):
    from vei.sim.state import VariantParams

    spec = spec_from_dict(
        {
            "design": "lhs",
            "n_samples": 24,
            "seed": 5,
            "base": "normal-cap",
            "parameters": {
                "time_shift_s": {"min": -2.0, "max": 2.0},
                "rider_model": {"choices": ["replay", "normal", "aggressive"]},
                "sfm.k_des_nspm": {"min": 60.0, "max": 140.0},
                "sfm.mass_kg": {"min": 70.0, "max": 120.0},
                "ego.policy": {"choices": ["paper-cap", "none"]},
                "cap.t_safe_s": {"min": 1.0, "max": 3.0},
                "cap.a_min_mps2": {"min": -7.5, "max": -3.0},
                "ego.cruise_speed_mps": {"min": 4.0, "max": 8.0},
                "cap.perception_delay_s": {"min": 0.0, "max": 0.5},
            },
        }
    )
    ev = EngineEvaluator(time_shift_reference="auto", base="normal-cap")
    prep = ev.prepare(demo_scenario)
    table = variants_table(spec, prep.scenario_id)
    batch = variant_params(
        table,
        prep.arrays,
        base="normal-cap",
        time_shift_reference="auto",
        auto_shift_s=prep.auto_shift_s,
    )
    assert batch.batch_size == 24
    for i, row in table.iterrows():
        cfg = variant_config(row_params(row, spec), spec, auto_shift_s=prep.auto_shift_s)
        one = VariantParams.from_case(cfg.case, prep.arrays, 1, time_shift_s=cfg.time_shift)
        for f in dataclasses.fields(one):
            if f.name == "labels":
                continue
            got, want = getattr(batch, f.name)[i], getattr(one, f.name)[0]
            if not isinstance(want, int | float | np.number | np.bool_):  # e.g. a policy
                assert got == want, f.name
                continue
            assert got == pytest.approx(want, rel=1e-15), f.name


def test_swept_v0_over_the_calibrated_default_is_the_riders_speed(demo_scenario):
    # The default rider takes v0 and its speed limit from its recording; a swept v0 replaces
    # that rule, in the batch as in each row's own configuration (limit: the preset's 4.72).
    from vei.sim.state import VariantParams

    spec = spec_from_dict(
        {"design": "grid", "parameters": {"sfm.v0_mps": {"min": 2.0, "max": 6.0, "num": 3}}}
    )
    ev = EngineEvaluator(time_shift_reference="auto", base="normal-cap")
    prep = ev.prepare(demo_scenario)
    table = variants_table(spec, prep.scenario_id)
    batch = variant_params(table, prep.arrays, auto_shift_s=prep.auto_shift_s)
    np.testing.assert_array_equal(batch.v0_mps, [2.0, 4.0, 6.0])
    np.testing.assert_array_equal(batch.max_speed_mps, [4.72] * 3)
    assert not batch.speed_from_recording.any()
    for i, row in table.iterrows():
        cfg = variant_config(row_params(row, spec), spec, auto_shift_s=prep.auto_shift_s)
        one = VariantParams.from_case(cfg.case, prep.arrays, 1, time_shift_s=cfg.time_shift)
        for f in dataclasses.fields(one):
            if f.name != "labels":
                assert getattr(batch, f.name)[i] == pytest.approx(getattr(one, f.name)[0]), f.name


@pytest.mark.slow
def test_results_do_not_depend_on_chunking_or_workers(demo_scenario, tmp_path):
    spec = spec_from_dict(
        {
            "design": "random",
            "n_samples": 30,
            "seed": 2,
            "parameters": {
                "time_shift_s": {"min": -2.0, "max": 2.0},
                "rider_model": {"choices": ["normal", "aggressive"]},
                "ego.policy": {"choices": ["paper-cap", "none"]},
            },
        }
    )
    a = run_sweep(demo_scenario, spec, tmp_path / "a", chunk_size=30, progress=False)
    b = run_sweep(demo_scenario, spec, tmp_path / "b", chunk_size=10, workers=2, progress=False)
    assert a.n_run == b.n_run == 30
    pd.testing.assert_frame_equal(read_results(tmp_path / "a"), read_results(tmp_path / "b"))


@pytest.mark.slow
def test_resume_after_partial_run_neither_loses_nor_duplicates(demo_scenario, tmp_path):
    spec = spec_from_dict(_plane_spec(6, 4, time_shift_reference="zero"))
    out = tmp_path / "out"
    first = run_sweep(demo_scenario, spec, out, chunk_size=10, max_chunks=1, progress=False)
    assert (first.n_run, first.n_skipped) == (10, 0)
    assert not (out / "results.parquet").exists()
    assert json.loads((out / "sweep.json").read_text())["status"] == "running"
    assert len(done_ids(out)) == 10
    # a writer killed mid-file leaves only a temporary: it is removed and ignored
    (out / "parts" / ".part-000099.parquet.abc.tmp").write_bytes(b"half")
    second = run_sweep(demo_scenario, spec, out, chunk_size=10, progress=False)
    assert (second.n_run, second.n_skipped) == (14, 10)
    assert sorted(p.name for p in (out / "parts").glob("part-*.parquet")) == [
        "part-000000.parquet",
        "part-000001.parquet",
        "part-000002.parquet",
    ]
    assert not list((out / "parts").glob(".*.tmp"))
    whole = run_sweep(demo_scenario, spec, tmp_path / "whole", chunk_size=24, progress=False)
    assert whole.n_run == 24
    pd.testing.assert_frame_equal(read_results(out), read_results(tmp_path / "whole"))
    # a third call has nothing left to do
    third = run_sweep(demo_scenario, spec, out, progress=False)
    assert (third.n_run, third.n_skipped) == (0, 24)


def test_refuses_another_spec_in_the_same_folder(demo_scenario, tmp_path):
    z = {"time_shift_reference": "zero"}
    run_sweep(demo_scenario, spec_from_dict(_plane_spec(2, 2, **z)), tmp_path / "o", progress=False)
    with pytest.raises(ConfigError, match="different spec"):
        run_sweep(
            demo_scenario, spec_from_dict(_plane_spec(3, 2, **z)), tmp_path / "o", progress=False
        )


def test_bad_arguments_and_missing_scenarios(demo_scenario, tmp_path):
    spec = spec_from_dict(_plane_spec(2, 2))
    with pytest.raises(ConfigError, match="engine"):
        run_sweep(demo_scenario, spec, tmp_path / "o", engine="spark")
    with pytest.raises(ConfigError, match="chunk_size"):
        run_sweep(demo_scenario, spec, tmp_path / "o", chunk_size=0)
    with pytest.raises(InputError, match="no such scenario"):
        find_scenarios(tmp_path / "nothing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="scenario folder"):
        find_scenarios(tmp_path / "empty")


def test_most_critical_order():
    df = pd.DataFrame(
        {
            "variant_id": list("abcd"),
            "collision": [False, True, False, True],
            "safety_index": [0.5, 0.0, 0.2, 0.0],
            "min_gap_m": [1.0, 0.0, 3.0, 0.0],
        }
    )
    assert list(most_critical(df, 3)["variant_id"]) == ["b", "d", "c"]


def _grid_neighbours_disagree(binned: dict, crossings: np.ndarray) -> None:
    """Every crossing lies on a lattice edge between two cell centres of the binned map
    whose collision shares fall on either side of 0.5."""
    xs, ys = np.asarray(binned["x_centres"]), np.asarray(binned["y_centres"])
    lab = np.asarray(binned["collision_share"], float) >= 0.5  # [Ky, Kx]
    for px, py in crossings:
        i = np.searchsorted(xs, px - 1e-9)
        j = np.searchsorted(ys, py - 1e-9)
        on_x = np.isclose(ys, py).any()  # crossing on a horizontal lattice edge
        if on_x:
            jj = int(np.argmin(np.abs(ys - py)))
            a, b = lab[jj, i - 1], lab[jj, i]
        else:
            ii = int(np.argmin(np.abs(xs - px)))
            a, b = lab[j - 1, ii], lab[j, ii]
        assert a != b, (px, py)


@pytest.mark.slow
def test_ten_thousand_variants_killed_and_resumed(demo_scenario, tmp_path):
    """The issue's must-show: 10^4 variants of the demo, SIGKILLed mid-run, resumed."""
    spec_path = tmp_path / "sweep.yaml"
    spec_path.write_text(
        "design: grid\nbase: normal\nparameters:\n"
        "  time_shift_s: {min: -3.0, max: 3.0, num: 100}\n"
        "  ego.cruise_speed_mps: {min: 3.0, max: 9.0, num: 100}\n"
    )
    out = tmp_path / "killed"
    cmd = [
        sys.executable,
        "-m",
        "vei.cli.main",
        "sweep",
        str(demo_scenario),
        "--spec",
        str(spec_path),
        "--out",
        str(out),
        "--chunk-size",
        "1000",
        "--no-progress",
    ]
    proc = subprocess.Popen(
        cmd, cwd=REPO, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    deadline = time.monotonic() + 120
    try:
        while len(list((out / "parts").glob("part-*.parquet"))) < 3:
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.monotonic() < deadline
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    n_parts = len(list((out / "parts").glob("part-*.parquet")))
    assert 3 <= n_parts < 10
    assert not (out / "results.parquet").exists()
    done = done_ids(out)
    assert len(done) == 1000 * n_parts

    from vei.sweep.spec import load_spec

    spec = load_spec(spec_path)
    resumed = run_sweep(demo_scenario, spec, out, chunk_size=1000, workers=2, progress=False)
    assert resumed.n_skipped == len(done) and resumed.n_run == 10_000 - len(done)
    run_sweep(demo_scenario, spec, tmp_path / "whole", chunk_size=2500, workers=2, progress=False)
    a, b = read_results(out), read_results(tmp_path / "whole")
    assert len(a) == 10_000 and a["variant_id"].is_unique
    pd.testing.assert_frame_equal(a, b)

    # the risk map's boundary lies between colliding and non-colliding neighbouring cells
    from vei.sweep.riskmap import sweep_risk_map

    drawn = sweep_risk_map(a, spec, tmp_path / "riskmap.png")
    assert (
        drawn is not None and drawn["x"] == "time_shift_s" and drawn["y"] == "ego.cruise_speed_mps"
    )
    # binned (issue 35.0): at most MAX_BINS_PER_AXIS cells per axis (20 x 20 here); the
    # boundary runs across the map, so it crosses at least one cell edge per column
    from vei.sweep.riskmap import MAX_BINS_PER_AXIS

    assert drawn["binned"]["collision_share"].shape == (MAX_BINS_PER_AXIS, MAX_BINS_PER_AXIS)
    assert len(drawn["crossings"]) >= MAX_BINS_PER_AXIS
    assert len(drawn["segments"]) >= MAX_BINS_PER_AXIS // 2
    _grid_neighbours_disagree(drawn["binned"], drawn["crossings"])


@pytest.mark.slow
def test_ray_gives_the_local_results_on_a_folder_of_scenarios(demo_scenario, tmp_path):
    pytest.importorskip("ray")
    from vei.io.scenario import read_scenario, write_scenario

    folder = tmp_path / "many"
    scen = read_scenario(demo_scenario)
    write_scenario(dataclasses.replace(scen, root=None), folder / "a")
    write_scenario(dataclasses.replace(scen, id="demo-copy-2", root=None), folder / "b")
    assert [p.name for p in find_scenarios(folder)] == ["a", "b"]
    spec = spec_from_dict(
        {
            "design": "lhs",
            "n_samples": 60,
            "seed": 9,
            "parameters": {
                "time_shift_s": {"min": -3.0, "max": 3.0},
                "ego.cruise_speed_mps": {"min": 3.0, "max": 9.0},
                "rider_model": {"choices": ["normal", "aggressive"]},
            },
        }
    )
    local = run_sweep(folder, spec, tmp_path / "local", chunk_size=16, progress=False)
    ray_run = run_sweep(
        folder, spec, tmp_path / "ray", engine="ray", workers=2, chunk_size=16, progress=False
    )
    assert local.n_variants == ray_run.n_variants == 120
    a, b = read_results(tmp_path / "local"), read_results(tmp_path / "ray")
    assert set(a["scenario_id"]) == {"demo-indianapolis-synthetic", "demo-copy-2"}
    pd.testing.assert_frame_equal(a, b)
    # the two copies of one recording give the same metrics for the same parameters
    m = [c for c in a.columns if c not in ("variant_id", "scenario_id", "seed")]
    pd.testing.assert_frame_equal(
        a[a["scenario_id"] == "demo-copy-2"][m].reset_index(drop=True),
        a[a["scenario_id"] == "demo-indianapolis-synthetic"][m].reset_index(drop=True),
    )


def test_sweep_risk_map_of_a_scattered_design(tmp_path):
    from vei.sweep.riskmap import sweep_risk_map

    spec = spec_from_dict(
        {
            "design": "random",
            "n_samples": 4000,
            "seed": 1,
            "parameters": {
                "time_shift_s": {"min": -3.0, "max": 3.0},
                "sfm.k_des_nspm": {"min": 50.0, "max": 150.0},
                "ego.cruise_speed_mps": {"min": 3.0, "max": 9.0},
            },
        }
    )
    df = variants_table(spec, "s")
    x, y = df["time_shift_s"].to_numpy(), df["ego.cruise_speed_mps"].to_numpy()
    df["collision"] = y > 6.0 + 0.5 * x  # known boundary in the plane the map picks
    df["safety_index"] = np.where(df["collision"], 0.0, 1.0)
    drawn = sweep_risk_map(df, spec, tmp_path / "rm.png")
    assert (drawn["x"], drawn["y"]) == ("time_shift_s", "ego.cruise_speed_mps")
    assert drawn["binned"]["count"].shape == (20, 20)  # sqrt(4000 / 10) bins per axis
    cx, cy = drawn["crossings"][:, 0], drawn["crossings"][:, 1]
    bin_h = 6.0 / 20
    # the 0.5 level of the collision share follows the line within about one bin
    assert np.abs(cy - (6.0 + 0.5 * cx)).max() < 1.5 * bin_h
    assert (tmp_path / "rm.png").stat().st_size > 10_000
