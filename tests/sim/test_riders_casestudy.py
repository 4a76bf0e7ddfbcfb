"""Case studies with several social-force riders (synthetic and a real recording)."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json

import numpy as np
import pandas as pd
import pytest

from vei.cli.main import main
from vei.config import PAPER_CASES, PAPER_SFM, SFM_PRESETS, SimConfig, case_preset
from vei.errors import ConfigError
from vei.experiments.casestudy import run_casestudy, write_casestudy
from vei.sim.testing import TrackSpec, crossing_scenario

REAL = "stadtmitte_12_audi_geradeaus_03"


def _cli(args: list[str]) -> tuple[int, str]:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
        code = main(args)
    return code, buf.getvalue()


def _two_rider_scenario():
    """The crossing scenario (rider1 crosses the ego's lane at x = 60 m) with a second
    e-scooter riding towards rider1's crossing line along y = 8 from x = 75."""
    t = np.arange(40, 301) / 20.0
    x = 75.0 - 1.8 * (t - 2.0)
    e2 = TrackSpec("escooter", t, x, np.full_like(t, 8.0), np.full_like(t, np.pi),
                   np.full_like(t, 1.8))  # fmt: skip
    return crossing_scenario(others=[("e2", e2)])


def _paper_cases():
    """The paper's five configurations with the paper's riders (whatever the presets' are)."""
    out = []
    for name in PAPER_CASES:
        case = case_preset(name)
        if case.rider == "sfm":
            sfm = SFM_PRESETS["paper-aggressive"] if "aggressive" in name else PAPER_SFM
            case = dataclasses.replace(case, sfm=sfm)
        out.append(case)
    return out


@pytest.fixture(scope="module")
def two_rider_result():
    return run_casestudy(
        _two_rider_scenario(), cases=_paper_cases(), sim=SimConfig(sfm_riders="all")
    )


def test_two_sfm_riders_case_study(two_rider_result, tmp_path) -> None:
    r = two_rider_result
    assert r.sfm_riders == ("rider1", "e2")
    tab = r.riders
    assert list(tab["config"].unique()) == list(PAPER_CASES)
    assert len(tab) == 2 * len(PAPER_CASES)
    e2 = tab[tab["rider"] == "e2"].set_index("config")
    # replay: e2 is its recording; SFM configurations: its own simulated ride (v0 5 m/s
    # instead of the recorded 1.8 m/s: it leaves its recording behind, reaches the end of
    # its path early and waits there until its recording is over).
    fr = r.frame
    assert e2.loc["replay", "max_deviation_m"] < 1e-9
    for cfg in PAPER_CASES[1:]:
        assert e2.loc[cfg, "max_deviation_m"] > 5.0, cfg
        sp = fr[(fr["agent_id"] == "e2") & (fr["config"] == cfg)]["speed_mps"]
        assert sp.max() > 4.0 and sp.iloc[-1] < 0.2, cfg
    # The time series hold e2's simulated poses, one row per step while it is present.
    rows = fr[(fr["agent_id"] == "e2") & (fr["config"] == "normal")]
    assert rows["active"].all() and len(rows) == e2.loc["normal", "steps_active"]
    # Distances in the table agree with the time series.
    nor = fr[fr["config"] == "normal"].pivot_table(
        index="t_s", columns="agent_id", values=["x_m", "y_m"]
    )
    both = nor.dropna()
    d = np.hypot(
        both["x_m"]["e2"] - both["x_m"]["rider1"], both["y_m"]["e2"] - both["y_m"]["rider1"]
    )
    active = fr[(fr["config"] == "normal") & fr["active"]].groupby("t_s")["agent_id"].apply(set)
    steps = [t for t in d.index if {"e2", "rider1"} <= active.get(t, set())]
    assert d.loc[steps].min() == pytest.approx(e2.loc["normal", "min_rider_distance_m"], abs=1e-9)
    paths = write_casestudy(r, tmp_path, figures=False)
    csv = pd.read_csv(paths["riders_csv"])
    assert len(csv) == len(tab)
    doc = json.loads(paths["summary_json"].read_text())
    assert doc["sfm_riders"] == ["rider1", "e2"] and len(doc["riders"]) == len(tab)


def test_one_rider_case_study_has_no_rider_table() -> None:
    r = run_casestudy(crossing_scenario(), cases=["normal"])
    assert r.sfm_riders == () and r.riders is None


def test_closed_loop_backends_refuse_extra_sfm_riders() -> None:
    from vei.sim.backends.base import ClosedLoop

    with pytest.raises(ConfigError, match="only the primary rider"):
        ClosedLoop(_two_rider_scenario(), case_preset("normal"), sim=SimConfig(sfm_riders="all"))
    # one SFM rider (the primary) with the several-rider mode on: runs
    ClosedLoop(_two_rider_scenario(), case_preset("normal"), sim=SimConfig(sfm_riders=["rider1"]))


@pytest.fixture(scope="module")
def real_scenario(trafficmonitoring_root, tmp_path_factory):
    from vei.datasets.trafficmonitoring import import_scenario
    from vei.io.interaction import read_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    base = tmp_path_factory.mktemp("multi_rider_real")
    import_scenario(trafficmonitoring_root, REAL, base / "interaction", rate_hz=1.0)
    write_scenario(reconstruct(read_interaction(base / "interaction")), base / "scenario")
    return base / "scenario"


def test_real_recording_all_riders_social_force(real_scenario, tmp_path) -> None:
    """stadtmitte_12: the primary cyclist and the six other riders (four cyclists, two
    e-scooters) are all social-force driven at once."""
    out = tmp_path / "all"
    code, text = _cli(["casestudy", str(real_scenario), "--out", str(out), "--no-figures",
                       "--sfm-riders", "all"])  # fmt: skip
    assert code == 0, text
    doc = json.loads((out / "summary.json").read_text())
    assert len(doc["sfm_riders"]) == 7
    tab = pd.read_csv(out / "riders.csv")
    assert len(tab) == 7 * len(PAPER_CASES)
    others = tab[~tab["primary"]]
    rep = others[others["config"] == "replay"]
    assert rep["max_deviation_m"].max() < 1e-6
    sfm = others[others["config"] != "replay"]
    # Social-force driven: not their recordings (the calibrated rider, at its own recorded
    # speed, stays within centimetres to metres of it; the paper's rider runs ahead by tens).
    assert (sfm["max_deviation_m"] > 0.01).all()
    # Every rider rides (none stuck in the jitter of a recorded wait) and none touches the ego.
    assert (sfm["mean_speed_mps"] > 0.3).all()
    assert not sfm["ego_contact"].any()
    ts = pd.read_parquet(out / "timeseries.parquet")
    assert set(doc["sfm_riders"]) <= set(ts["agent_id"])
    # Two named riders only; an unknown id is a user error (exit 2, no traceback).
    code, text = _cli(["casestudy", str(real_scenario), "--out", str(tmp_path / "two"),
                       "--no-figures", "--sfm-riders", "escooter_78,escooter_81"])  # fmt: skip
    assert code == 0, text
    two = json.loads((tmp_path / "two" / "summary.json").read_text())
    assert two["sfm_riders"][1:] == ["escooter_78", "escooter_81"]
    code, text = _cli(["casestudy", str(real_scenario), "--out", str(tmp_path / "bad"),
                       "--no-figures", "--sfm-riders", "escooter_999"])  # fmt: skip
    assert code == 2 and "escooter_999" in text and "Traceback" not in text
