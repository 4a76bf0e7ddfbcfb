"""vei catalogue: encounter rule (hand-computed), real catalogue, kill + resume, failures, CLI."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.catalogue.helpers import SMALL_RECORDINGS, SMALL_SWEEP, small_config
from vei.catalogue import EncounterRule, find_encounters, run_catalogue
from vei.catalogue.store import done_encounters, encounter_dir
from vei.errors import ConfigError
from vei.types import AgentInfo, Scenario

# the slow tier (docs/testing.md): minutes of real data, players or browsers
pytestmark = pytest.mark.slow


def _scenario() -> Scenario:
    """Ego along +x at 5 m/s (x = 5 t); rider A along +y at x = 20 m, y = 2 (t - 6):
    it crosses the ego path at t = 6 s, the ego is there at t = 4 s (PET 2 s, 90 deg);
    rider B parallel to the ego 30 m to the side (never an encounter)."""
    t = np.round(np.arange(0.0, 10.0 + 1e-9, 0.05), 6)
    rows = [
        pd.DataFrame(dict(t_s=t, agent_id="ego", source_track_id=None, category="ego",
                          x_m=5 * t, y_m=0 * t, yaw_rad=0 * t, speed_mps=5 + 0 * t)),
        pd.DataFrame(dict(t_s=t, agent_id="cyclist_a", source_track_id="a", category="cyclist",
                          x_m=20 + 0 * t, y_m=2 * (t - 6), yaw_rad=math.pi / 2 + 0 * t,
                          speed_mps=2 + 0 * t)),
        pd.DataFrame(dict(t_s=t, agent_id="escooter_b", source_track_id="b", category="escooter",
                          x_m=5 * t, y_m=30 + 0 * t, yaw_rad=0 * t, speed_mps=5 + 0 * t)),
    ]  # fmt: skip
    return Scenario(
        id="synthetic",
        projection="+proj=tmerc +lat_0=48 +lon_0=11",
        origin_lat_deg=48.0,
        origin_lon_deg=11.0,
        start_time_utc=datetime(2021, 2, 9, tzinfo=UTC),
        rate_hz=20.0,
        bounds={"south_deg": 47.9, "west_deg": 10.9, "north_deg": 48.1, "east_deg": 11.1},
        agents=(
            AgentInfo("ego", "ego", 4.7, 1.85),
            AgentInfo("cyclist_a", "cyclist", 1.8, 0.6, "a"),
            AgentInfo("escooter_b", "escooter", 1.2, 0.6, "b"),
        ),
        primary_threat="cyclist_a",
        trajectories=pd.concat(rows, ignore_index=True),
    )


def test_encounter_figures_hand_computed():
    found, others = find_encounters(_scenario())
    assert [e.rider_id for e in found] == ["cyclist_a"]
    assert [e.rider_id for e in others] == ["escooter_b"]
    a = found[0]
    assert a.path_distance_m == pytest.approx(0.0, abs=1e-9)
    assert a.pet_s == pytest.approx(2.0, abs=1e-6)  # rider at x=20 at t=6, ego at t=4
    assert a.crossing_angle_deg == pytest.approx(90.0)
    # same-time gap: |(20 - 5t, 2(t-6))| is smallest at t = (100 + 24) / 29 = 4.276 s
    t_star = 124 / 29
    gap = math.hypot(20 - 5 * t_star, 2 * (t_star - 6))
    assert a.min_gap_m == pytest.approx(gap, abs=0.02)
    assert a.t_closest_s == pytest.approx(t_star, abs=0.05)
    b = others[0]
    assert b.path_distance_m == pytest.approx(30.0) and b.min_gap_m == pytest.approx(30.0)
    # the rule: B passes within 30 m -> an encounter only with a 30 m gap bound
    found2, _ = find_encounters(_scenario(), EncounterRule(gap_max_m=30.0))
    assert {e.rider_id for e in found2} == {"cyclist_a", "escooter_b"}
    # a PET bound below 2 s drops A's route clause; its same-time gap (3.7 m) keeps it unless < 3.7
    found3, _ = find_encounters(_scenario(), EncounterRule(pet_max_s=1.0, gap_max_m=3.0))
    assert found3 == []


def test_rule_validation():
    with pytest.raises(ConfigError, match="pet_max_s"):
        EncounterRule(pet_max_s=-1.0)
    with pytest.raises(ConfigError, match="categories"):
        EncounterRule(categories=("pedestrian",))


def test_small_catalogue_table(small_catalogue):
    rows = pd.read_parquet(small_catalogue / "catalogue.parquet")
    enc = pd.read_csv(small_catalogue / "encounters.csv")
    n_enc = 3
    assert len(enc) == n_enc
    assert len(rows) == n_enc * (5 + SMALL_SWEEP["n_samples"])
    assert not rows.duplicated(["encounter_id", "kind", "config"]).any()
    assert list(rows["rank"]) == list(range(1, len(rows) + 1))
    assert list(enc["rank"]) == list(range(1, n_enc + 1))
    # rows are ranked: collisions first, then safety index ascending
    coll = rows["collision"].to_numpy(bool)
    assert not (np.diff(coll.astype(int)) > 0).any()
    si = rows.loc[coll, "safety_index"].to_numpy()
    assert (si == 0).all()
    # the encounter ranking follows the expected harm (issue 23: probability x injury
    # risk with a 95 % CI), then P(collision); a bound only (no collision seen) counts 0
    harm = enc["risk_expected_harm"].fillna(0.0).to_numpy()
    assert (np.diff(harm) <= 1e-12).all()
    assert (enc["risk_expected_harm_lo"] <= enc["risk_expected_harm"].fillna(0)).all()
    assert (enc["risk_p_collision_hi"] > 0).all()  # never 0: an upper bound at least
    share = rows.groupby("encounter_id")["collision"].mean()
    for r in enc.itertuples():
        assert r.collision_share == pytest.approx(share[r.encounter_id])
    # issue 31: the share colliding on the rider's recorded behaviour, from the rows
    ok = ~rows["seen_too_late"].astype(bool)
    on_rec = (rows["collision"].astype(bool) & rows["collision_recorded"].astype(bool))[ok]
    rec = on_rec.groupby(rows.loc[ok, "encounter_id"]).mean()
    for r in enc.itertuples():
        assert r.recorded_collision_share == pytest.approx(rec[r.encounter_id])
        assert r.recorded_collision_share_lo <= r.recorded_collision_share
        assert r.recorded_collision_share <= r.recorded_collision_share_hi
    # issue 31: P(collision on recorded behaviour) of the risk estimate, never above the total
    both = enc["risk_p_collision"].notna() & enc["risk_p_collision_recorded"].notna()
    assert (
        enc.loc[both, "risk_p_collision_recorded"] <= enc.loc[both, "risk_p_collision"] + 1e-12
    ).all()
    assert (enc["risk_p_collision_recorded_hi"] > 0).all()
    # the paper's encounter: stadtmitte_12 cyclist_60 collides without CAP, not with it
    cs = rows[
        (rows["encounter_id"] == "stadtmitte_12_audi_geradeaus_03__cyclist_60")
        & (rows["kind"] == "casestudy")
    ]
    outcome = dict(zip(cs["config"], cs["collision"], strict=True))
    # The default (calibrated) rider rides at cyclist_60's own ~3.1 m/s, later than the
    # replay-derived shift assumes, and misses the car by 3.6 m (normal) / 4.0 m
    # (aggressive): only the replay collides (the paper's rider collides: docs/riders.md).
    assert outcome == {"replay": True, "normal": False, "aggressive": False,
                       "normal-cap": False, "aggressive-cap": False}  # fmt: skip
    assert cs.loc[cs["config"] == "normal", "min_gap_m"].item() == pytest.approx(3.58, abs=0.05)


_CHILD = """
import sys
sys.path.insert(0, {root!r})
from tests.catalogue.helpers import small_config, SMALL_RECORDINGS
from vei.catalogue import run_catalogue
run_catalogue({dataset!r}, {out!r}, small_config(), recordings=list(SMALL_RECORDINGS), progress=False)
"""


def test_killed_run_resumes_without_loss_or_duplicates(
    tmp_path, trafficmonitoring_root, small_catalogue
):
    out = tmp_path / "cat"
    code = _CHILD.format(
        root=str(Path(__file__).parents[2]), dataset=str(trafficmonitoring_root), out=str(out)
    )
    proc = subprocess.Popen([sys.executable, "-c", code], env={**os.environ, "PYTHONHASHSEED": "0"})
    deadline = time.monotonic() + 240
    try:
        while not done_encounters(out):
            assert proc.poll() is None, "the run ended before it could be killed"
            assert time.monotonic() < deadline, "no encounter finished in time"
            time.sleep(0.05)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    before = done_encounters(out)
    assert 1 <= len(before) < 3, before
    stamps = {e: (encounter_dir(out, e) / "rows.parquet").stat().st_mtime_ns for e in before}
    assert not (out / "catalogue.parquet").exists()

    result = run_catalogue(
        trafficmonitoring_root,
        out,
        small_config(),
        recordings=list(SMALL_RECORDINGS),
        progress=False,
    )
    assert result.complete and result.n_done_before == len(before)
    for e, ns in stamps.items():  # done encounters were not run again
        assert (encounter_dir(out, e) / "rows.parquet").stat().st_mtime_ns == ns
    resumed = pd.read_parquet(out / "catalogue.parquet")
    reference = pd.read_parquet(small_catalogue / "catalogue.parquet")
    assert not resumed.duplicated(["encounter_id", "kind", "config"]).any()
    pd.testing.assert_frame_equal(resumed, reference)


def test_recordings_without_riders_are_reported_and_skipped(tmp_path, trafficmonitoring_root):
    result = run_catalogue(
        trafficmonitoring_root,
        tmp_path / "cat",
        small_config(sweep=None),
        recordings=["marktkauf_04_audi_rechtsabbiegen", "klinikum_01_marktkauf_geradeaus"],
        progress=False,
    )
    by = {d["recording"]: d for d in result.recordings}
    none = by["marktkauf_04_audi_rechtsabbiegen"]  # nothing to simulate: not a failure
    assert none["status"] == "no-riders" and "no e-scooter or cyclist" in none["reason"]
    ok = by["klinikum_01_marktkauf_geradeaus"]
    assert ok["status"] == "ok" and [e["rider_id"] for e in ok["encounters"]] == ["escooter_9"]
    assert result.complete and len(result.rows) == 5  # the case study only
    assert result.failed_recordings == []


def test_other_settings_refused(tmp_path, trafficmonitoring_root):
    out = tmp_path / "cat"
    run_catalogue(trafficmonitoring_root, out, small_config(sweep=None),
                  recordings=["klinikum_01_marktkauf_geradeaus"], progress=False)  # fmt: skip
    with pytest.raises(ConfigError, match="other settings"):
        run_catalogue(trafficmonitoring_root, out, small_config(), progress=False)


def test_cli_catalogue_and_report(tmp_path, trafficmonitoring_root):
    from vei.cli.main import main

    out = tmp_path / "cli"
    code = main(["catalogue", str(trafficmonitoring_root), "--out", str(out),
                 "--recording", "klinikum_01_marktkauf_geradeaus",
                 "--recording", "marktkauf_05_klinikum_geradeaus",
                 "--n-variants", "8", "--no-figures"])  # fmt: skip
    assert code == 0
    assert (out / "report.html").is_file()  # the index; plotly and the encounters beside it
    assert (out / "report_files" / "plotly.min.js").stat().st_size > 1_000_000
    assert len(list((out / "report_files" / "enc").glob("*.js"))) >= 1
    rows = pd.read_parquet(out / "catalogue.parquet")
    assert len(rows) == 5 + 8
    assert main(["catalogue", str(trafficmonitoring_root), "--out", str(tmp_path / "x"),
                 "--recording", "nope"]) == 2  # fmt: skip
    assert main(["report", str(tmp_path)]) == 2


def test_ray_and_local_give_the_same_catalogue(tmp_path, trafficmonitoring_root):
    """The same jobs as Ray tasks and in this process: identical rows."""
    pytest.importorskip("ray")
    recs = ["klinikum_01_marktkauf_geradeaus"]
    cfg = small_config(sweep={**SMALL_SWEEP, "n_samples": 8})
    local = run_catalogue(trafficmonitoring_root, tmp_path / "local", cfg, recordings=recs,
                          engine="local", workers=1, progress=False)  # fmt: skip
    ray = run_catalogue(trafficmonitoring_root, tmp_path / "ray", cfg, recordings=recs,
                        engine="ray", workers=2, progress=False)  # fmt: skip
    assert local.complete and ray.complete and len(local.rows) == 5 + 8
    pd.testing.assert_frame_equal(local.rows, ray.rows)


def test_folder_of_interaction_folders(tmp_path):
    """The interaction-format layout (any source): one recording per folder; a broken one is
    reported and skipped."""
    from tests.helpers_interaction import make_interaction

    data = tmp_path / "data"
    make_interaction(data, name="rec_a", id="rec_a")
    make_interaction(data, name="rec_b", id="rec_b")
    bad = make_interaction(data, name="rec_c", id="rec_c")
    (bad / "ego.csv").write_text("t_s,lat_deg,lon_deg\n0,1e999,x\n")
    result = run_catalogue(data, tmp_path / "cat", small_config(sweep=None), progress=False)
    by = {d["recording"]: d for d in result.recordings}
    assert by["rec_c"]["status"] == "failed" and "ego.csv" in by["rec_c"]["reason"]
    for rec in ("rec_a", "rec_b"):
        # the synthetic e-scooter crosses the ego's path (helpers_interaction): an encounter
        assert "escooter_1" in [e["rider_id"] for e in by[rec]["encounters"]]
    # a failed recording makes the catalogue partial (exit code 3 at the CLI)
    assert not result.complete and result.failed_recordings == ["rec_c"]
    manifest = json.loads((tmp_path / "cat" / "catalogue.json").read_text())
    assert manifest["status"] == "partial" and manifest["failed_recordings"] == ["rec_c"]
    assert set(result.rows["recording"]) == {"rec_a", "rec_b"}
    # a single interaction folder is a dataset of one recording
    one = run_catalogue(data / "rec_a", tmp_path / "one", small_config(sweep=None), progress=False)
    assert [d["recording"] for d in one.recordings] == ["rec_a"] and one.complete


def test_cli_exit_code_3_for_a_partial_catalogue(tmp_path, capsys):
    """Partial success (a recording failed, the others were catalogued) has its own exit
    code: 3, documented in the README; the failures are listed."""
    from tests.helpers_interaction import make_interaction
    from vei.cli.main import main

    data = tmp_path / "data"
    make_interaction(data, name="rec_a", id="rec_a")
    bad = make_interaction(data, name="rec_c", id="rec_c")
    (bad / "ego.csv").write_text("t_s,lat_deg,lon_deg\n0,1e999,x\n")
    code = main(["catalogue", str(data), "--out", str(tmp_path / "cat"), "--no-sweep",
                 "--no-figures", "--no-report"])  # fmt: skip
    out = " ".join(capsys.readouterr().out.split())
    assert code == 3, out
    assert "partial: 1 recording(s) and 0 encounter(s) failed" in out
    assert "rec_c" in out and "status partial" in out


def test_map_from_a_local_source(tmp_path, trafficmonitoring_root, data_dir):
    """--map: every recording gets its OpenDRIVE map (SUMO net of the area, netconvert);
    the ego drives on it, and the report draws its lanes."""
    from vei.catalogue.report_data import collect

    net = data_dir / "maps" / "ingolstadt_research_intersection.net.xml.gz"
    out = tmp_path / "cat"
    result = run_catalogue(trafficmonitoring_root, out, small_config(sweep=None, map_source=str(net)),
                           recordings=["klinikum_01_marktkauf_geradeaus"], progress=False)  # fmt: skip
    assert result.complete
    eid = "klinikum_01_marktkauf_geradeaus__escooter_9"
    scen = encounter_dir(out, eid) / "scenario"
    assert (scen / "map.xodr").is_file()
    import json

    share = json.loads((scen / "scenario.json").read_text())["map"]["ego_on_drivable_share"]
    assert share > 0.95  # measured 0.994
    roads = collect(out)["encounters"][0]["roads"]
    assert roads is not None and len(roads["x"]) > 100


def test_settings_file(tmp_path):
    from vei.catalogue import load_catalogue_config

    p = tmp_path / "s.yaml"
    p.write_text("rule: {gap_max_m: 3.5, categories: [escooter]}\nsweep: null\ncases: [replay]\n")
    cfg = load_catalogue_config(p)
    assert cfg.rule == EncounterRule(gap_max_m=3.5, categories=("escooter",))
    assert cfg.sweep is None and cfg.cases == ("replay",)
    assert cfg.digest() != load_catalogue_config(None).digest()
    p.write_text("rules: {}\n")
    with pytest.raises(ConfigError, match="unknown catalogue setting 'rules'"):
        load_catalogue_config(p)
    p.write_text("rule: {gap_max: 3}\n")
    with pytest.raises(ConfigError, match="unknown rule setting 'gap_max'"):
        load_catalogue_config(p)
    p.write_text(
        "sweep: {design: lhs, n_samples: 0, parameters: {time_shift_s: {min: 0, max: 1}}}\n"
    )
    with pytest.raises(ConfigError):
        load_catalogue_config(p)


def test_a_failing_encounter_is_reported_and_retried(tmp_path, trafficmonitoring_root, monkeypatch):
    import vei.experiments.casestudy as casestudy

    real = casestudy.run_casestudy

    def flaky(scenario, **kw):
        if scenario.primary_threat == "cyclist_12":
            raise RuntimeError("\x1b[1minjected\x1b[0m\nmore")
        return real(scenario, **kw)

    monkeypatch.setattr(casestudy, "run_casestudy", flaky)
    out = tmp_path / "cat"
    args = dict(recordings=["stadtmitte_12_audi_geradeaus_03"], progress=False)
    first = run_catalogue(trafficmonitoring_root, out, small_config(sweep=None), **args)
    assert not first.complete
    assert first.failed_encounters == [
        {
            "encounter_id": "stadtmitte_12_audi_geradeaus_03__cyclist_12",
            "reason": first.failed_encounters[0]["reason"],
        }
    ]
    assert first.failed_encounters[0]["reason"].startswith(
        "internal error RuntimeError: injected at "
    )
    assert set(first.rows["rider_id"]) == {"cyclist_60"}  # the other encounter is in
    monkeypatch.setattr(casestudy, "run_casestudy", real)
    second = run_catalogue(trafficmonitoring_root, out, small_config(sweep=None), **args)
    assert second.complete and second.n_done_before == 1
    assert set(second.rows["rider_id"]) == {"cyclist_60", "cyclist_12"}
    assert not (
        encounter_dir(out, "stadtmitte_12_audi_geradeaus_03__cyclist_12") / "failed.json"
    ).exists()


def test_encounters_belong_to_the_listed_folder_not_the_scenario_id(tmp_path):
    """Two interaction folders sharing one id, named otherwise: each encounter is named and
    read after its folder (before, the encounter read recordings/<id>/ and failed with
    'no scenario.json here', and both folders collided on encounters/<id>__...)."""
    from tests.helpers_interaction import make_interaction

    data = tmp_path / "data"
    make_interaction(data, name="renamed_folder", id="audi_08_klinikum_rechtsabbiegen")
    make_interaction(data, name="second_copy", id="audi_08_klinikum_rechtsabbiegen")
    cfg = small_config(sweep={**SMALL_SWEEP, "n_samples": 2})
    result = run_catalogue(data, tmp_path / "cat", cfg, progress=False)
    assert result.failed_encounters == [] and result.complete
    ids = sorted(set(result.rows["encounter_id"]))
    riders = ("cyclist_2", "escooter_1")  # both synthetic riders cross the ego's path
    assert ids == [f"{f}__{r}" for f in ("renamed_folder", "second_copy") for r in riders]
    assert set(result.rows["recording"]) == {"renamed_folder", "second_copy"}
    assert len(result.rows) == 4 * (5 + 2)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("recon: [1, 2]\n", "recon must be a mapping"),
        ("sweep: [1]\n", "sweep must be a mapping"),
        ("rule: [1]\n", "rule must be a mapping"),
        ("figures: 'no'\n", "figures must be true or false"),
        ("cases: [1]\n", "cases must be a list"),
        ("rule: {categories: 3}\n", "categories must be a list"),
        ("map_source: 3\n", "map_source must be"),
        ("road_users: some\n", "road_users must be riders or all"),
    ],
)
def test_settings_file_bad_values_are_config_errors(tmp_path, text, message):
    """Bad values in a settings file are ConfigErrors naming the file and the key (before:
    a raw TypeError for recon, silently accepted rule/figures)."""
    from vei.catalogue import load_catalogue_config

    p = tmp_path / "s.yaml"
    p.write_text(text)
    with pytest.raises(ConfigError, match=message) as info:
        load_catalogue_config(p)
    assert str(info.value).startswith(f"{p}: ")


def test_settings_file_lone_names_are_one_element_lists(tmp_path):
    """`cases: replay` / `categories: escooter` mean one name (before: its characters)."""
    from vei.catalogue import CatalogueConfig, load_catalogue_config

    p = tmp_path / "s.yaml"
    p.write_text("cases: replay\nrule: {categories: escooter}\nsweep: null\nfigures: false\n")
    cfg = load_catalogue_config(p)
    assert cfg.cases == ("replay",)
    assert cfg.rule == EncounterRule(categories=("escooter",))
    assert cfg.figures is False
    assert cfg.as_dict()["rule"]["categories"] == ["escooter"]
    # the dataclass itself: a rule mapping becomes an EncounterRule, lists become tuples
    direct = CatalogueConfig(rule={"gap_max_m": 2.0}, cases=["replay", "normal"], sweep=None)
    assert direct.rule == EncounterRule(gap_max_m=2.0)
    assert direct.cases == ("replay", "normal")
    with pytest.raises(ConfigError, match="unknown rule setting 'gap'"):
        CatalogueConfig(rule={"gap": 2.0}, sweep=None)


def _two_interactions(data: Path) -> None:
    """rec_a, rec_b: synthetic interaction folders, two encounters each (helpers_interaction)."""
    from tests.helpers_interaction import make_interaction

    make_interaction(data, name="rec_a", id="rec_a")
    make_interaction(data, name="rec_b", id="rec_b")


def test_limited_runs_go_on_with_the_next_encounters(tmp_path):
    """max_encounters counts encounters not done before: two runs with a limit of 1 finish two
    different encounters (before, the second run sliced the same first one and stopped)."""
    data = tmp_path / "data"
    _two_interactions(data)
    out = tmp_path / "cat"
    cfg = small_config(sweep=None)
    first = run_catalogue(data, out, cfg, recordings=["rec_a"], max_encounters=1, progress=False)
    once = done_encounters(out)
    assert len(once) == 1 and not first.complete
    second = run_catalogue(data, out, cfg, recordings=["rec_a"], max_encounters=1, progress=False)
    assert done_encounters(out) == ["rec_a__cyclist_2", "rec_a__escooter_1"]
    assert second.complete and second.n_done_before == 1
    assert sorted(set(second.rows["encounter_id"])) == done_encounters(out)
    import json

    assert json.loads((out / "catalogue.json").read_text())["status"] == "complete"
    with pytest.raises(ConfigError, match="max_encounters"):
        run_catalogue(data, out, cfg, recordings=["rec_a"], max_encounters=-1, progress=False)


def test_a_run_over_other_recordings_adds_to_the_catalogue(tmp_path):
    """A run with recordings=[rec_b] after one with [rec_a]: the table and the manifest hold
    both (before, they were rewritten with rec_b only)."""
    import json

    data = tmp_path / "data"
    _two_interactions(data)
    out = tmp_path / "cat"
    cfg = small_config(sweep=None)
    run_catalogue(data, out, cfg, recordings=["rec_a"], progress=False)
    second = run_catalogue(data, out, cfg, recordings=["rec_b"], progress=False)
    assert second.complete and [d["recording"] for d in second.recordings] == ["rec_b"]
    assert set(second.rows["recording"]) == {"rec_a", "rec_b"}
    assert len(second.rows) == 4 * 5  # 4 encounters x the 5 case-study configurations
    table = pd.read_parquet(out / "catalogue.parquet")
    assert set(table["encounter_id"]) == set(done_encounters(out))
    assert len(done_encounters(out)) == 4
    manifest = json.loads((out / "catalogue.json").read_text())
    assert sorted(manifest["recordings"]) == ["rec_a", "rec_b"]
    assert manifest["n_encounters"] == 4 and manifest["status"] == "complete"


def test_catalogue_imports_and_reconstructs_as_the_step_by_step_pipeline(
    tmp_path, trafficmonitoring_root
):
    """`vei catalogue --road-users all --interp smoothing` gives the encounter the scenario
    of `vei import trafficmonitoring --road-users all` + `vei reconstruct --interp
    smoothing` (the README's pipeline), and records both settings with the encounter."""
    from vei.cli.main import main
    from vei.io.scenario import read_scenario

    name = "audi_08_klinikum_rechtsabbiegen_02"
    settings = tmp_path / "s.yaml"
    settings.write_text("risk: null\ncases: [replay]\n")
    out = tmp_path / "cat"
    code = main(["catalogue", str(trafficmonitoring_root), "--out", str(out), "--recording",
                 name, "--settings", str(settings), "--no-sweep", "--no-figures", "--no-report",
                 "--road-users", "all", "--interp", "smoothing"])  # fmt: skip
    assert code == 0
    rows = pd.read_parquet(out / "catalogue.parquet")
    assert set(rows["import_road_users"]) == {"all"} and set(rows["recon_interp"]) == {"smoothing"}
    assert set(rows["risk_basis"]) == {"recorded behaviour"}  # the cyclist meets the car
    status = json.loads((out / "recordings" / name / "status.json").read_text())
    assert (status["road_users"], status["interp"]) == ("all", "smoothing")
    inter, scen = tmp_path / "inter", tmp_path / "scen"
    assert main(["import", "trafficmonitoring", "--root", str(trafficmonitoring_root),
                 "--scenario", name, "--out", str(inter), "--road-users", "all"]) == 0  # fmt: skip
    assert main(["reconstruct", str(inter), "--out", str(scen), "--no-figure",
                 "--interp", "smoothing"]) == 0  # fmt: skip
    mine = read_scenario(out / "recordings" / name / "scenario")
    ref = read_scenario(scen)
    assert [a.agent_id for a in mine.agents] == [a.agent_id for a in ref.agents]
    assert any(a.category not in ("ego", "cyclist", "escooter") for a in ref.agents)
    pd.testing.assert_frame_equal(mine.trajectories, ref.trajectories)
    assert main(["catalogue", str(trafficmonitoring_root), "--out", str(tmp_path / "bad"),
                 "--recording", name, "--interp", "spline"]) == 2  # fmt: skip
