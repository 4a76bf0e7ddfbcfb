"""A command that refuses its arguments writes nothing: every option is validated before
the output folder (or file) is touched, so the next, valid command into that folder is
not refused as "made with other settings" (issue 28: `vei catalogue --workers 0` wrote
catalogue.json first)."""

from __future__ import annotations

from pathlib import Path

import pytest

from vei.cli.main import main


@pytest.fixture(scope="module")
def scenario(tmp_path_factory) -> Path:
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


@pytest.fixture(scope="module")
def interaction(tmp_path_factory) -> Path:
    from vei.experiments.demo_data import demo_interaction
    from vei.io.interaction import write_interaction

    folder = tmp_path_factory.mktemp("demo") / "interaction"
    write_interaction(demo_interaction(), folder)
    return folder


def _spec(tmp: Path) -> Path:
    spec = tmp / "spec.yaml"
    spec.write_text("design: grid\nparameters: {time_shift_s: {min: 0, max: 1, num: 2}}\n")
    return spec


#: (name, argv with {scen}, {inter}, {spec}, {tm}, {out}) of a command that must be refused.
REFUSED = [
    ("catalogue workers 0", ["catalogue", "{tm}", "--out", "{out}", "--workers", "0"]),
    ("catalogue engine", ["catalogue", "{tm}", "--out", "{out}", "--engine", "spark"]),
    ("catalogue n-variants", ["catalogue", "{tm}", "--out", "{out}", "--n-variants", "0"]),
    ("catalogue recording", ["catalogue", "{tm}", "--out", "{out}", "--recording", "nope"]),
    ("sweep workers 0", ["sweep", "{scen}", "--spec", "{spec}", "--out", "{out}", "--workers", "0"]),
    ("sweep engine", ["sweep", "{scen}", "--spec", "{spec}", "--out", "{out}", "--engine", "x"]),
    ("sweep chunk", ["sweep", "{scen}", "--spec", "{spec}", "--out", "{out}", "--chunk-size", "0"]),
    ("sweep x only", ["sweep", "{scen}", "--spec", "{spec}", "--out", "{out}", "--x", "time_shift_s"]),
    ("casestudy shift", ["casestudy", "{scen}", "--out", "{out}", "--time-shift", "soon"]),
    ("casestudy backend", ["casestudy", "{scen}", "--out", "{out}", "--backend", "gazebo"]),
    ("casestudy threat", ["casestudy", "{scen}", "--out", "{out}", "--threat", "nobody"]),
    ("run config", ["run", "{scen}", "--config", "nothing", "--out", "{out}"]),
    ("run policy", ["run", "{scen}", "--config", "normal", "--policy", "x.py:Y", "--out", "{out}"]),
    ("demo shift", ["demo", "--out", "{out}", "--time-shift", "soon"]),
    ("reconstruct rate", ["reconstruct", "{inter}", "--out", "{out}", "--rate-hz", "0"]),
    ("reconstruct interp", ["reconstruct", "{inter}", "--out", "{out}", "--interp", "magic"]),
    ("export version", ["export", "openscenario", "{scen}", "--out", "{out}", "--osc-version", "9"]),
    ("export config", ["export", "openscenario", "{scen}", "--out", "{out}", "--config", "zz"]),
    ("import rate", ["import", "trafficmonitoring", "--root", "{tm}", "--scenario",
                     "stadtmitte_12_audi_geradeaus_03", "--out", "{out}", "--rate-hz", "0"]),
    ("import scenario", ["import", "trafficmonitoring", "--root", "{tm}", "--scenario", "nope",
                         "--out", "{out}"]),
    ("calibrate bootstrap", ["calibrate", "riders", "--root", "{tm}", "--out", "{out}",
                             "--bootstrap", "-1"]),
    ("calibrate category", ["calibrate", "riders", "--root", "{tm}", "--out", "{out}",
                            "--category", "tram"]),
    ("risk budget", ["risk", "{scen}", "--out", "{out}", "--budget", "0"]),
    ("risk method", ["risk", "{scen}", "--out", "{out}", "--method", "magic"]),
    ("risk target", ["risk", "{scen}", "--out", "{out}", "--target-rel-ci", "-1"]),
    ("risk spec", ["risk", "{scen}", "--out", "{out}", "--spec", "{spec}"]),
    ("map build converter", ["map", "build", "{spec}", "--out", "{out}/map.xodr",
                             "--converter", "magic"]),
]  # fmt: skip


@pytest.mark.parametrize(("name", "argv"), REFUSED, ids=[r[0] for r in REFUSED])
def test_a_refused_command_writes_nothing(
    name, argv, tmp_path, scenario, interaction, trafficmonitoring_root, capsys
):
    out = tmp_path / "out"
    values = {
        "scen": scenario,
        "inter": interaction,
        "spec": _spec(tmp_path),
        "tm": trafficmonitoring_root,
        "out": out,
    }
    args = [a.format(**{k: str(v) for k, v in values.items()}) for a in argv]
    code = main(args)
    err = capsys.readouterr().err
    assert code == 2, f"{name}: exit {code}\n{err}"
    assert not out.exists(), f"{name}: wrote {sorted(p.name for p in out.rglob('*'))}"
