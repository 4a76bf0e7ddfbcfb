"""Every command of the README's offline quick start, as written there, on every shared
TrafficMonitoring recording with a rider (not only the demo), and the examples/ files they
use: each exits 0 and writes what it promises (issue 28: the README's own sweep crashed on
a recording vei had not seen)."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from tests.helpers_data import REAL_WITH_RIDER
from vei.cli.main import main

# the slow tier (docs/testing.md): minutes of real data, players or browsers
pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
#: the recording the README names, replaced by each shared one
README_RECORDING = "stadtmitte_12_audi_geradeaus_03"
RECORDINGS = list(REAL_WITH_RIDER)
#: what each command must leave behind, by its --out name in the README
PROMISED = {
    "inter": ["interaction.json", "ego.csv", "annotations.csv"],
    "scen": ["scenario.json", "trajectories.parquet", "map.xodr"],
    "study": ["summary.json", "timeseries.parquet", "fig5_speed_profiles.png"],
    "run": ["metrics.json", "timeseries.parquet"],
    "xosc": [],  # named after the scenario: checked below
    "sweep": ["results.parquet", "critical.csv", "riskmap.png"],
    "policy-sweep": ["results.parquet", "policy_comparison.csv"],
    "mine": ["metrics.json"],
    "inter-all": ["interaction.json", "annotations.csv"],
    "scen-all": ["scenario.json", "map.xodr"],
    "v2x-real": ["metrics.json", "timeseries.parquet"],
    "occluded": ["scenario.json"],
    "v2x-run": ["metrics.json"],
    "v2x-sweep": ["results.parquet"],
    "v2x-risk": ["risk.json", "samples.parquet"],
}


def readme_commands() -> list[list[str]]:
    """The `vei ...` lines of the README's offline step-by-step block, split like a shell."""
    text = README.read_text(encoding="utf-8")
    start = text.index("On real data, step by step, offline")
    block = text[start:].split("```", 2)[1]
    lines = [ln.split("#", 1)[0].strip() for ln in block.splitlines()]
    return [shlex.split(ln)[1:] for ln in lines if ln.startswith("vei ")]


def test_the_readme_block_is_found_and_offline():
    cmds = readme_commands()
    assert len(cmds) >= 8
    assert not any("auto" == a for c in cmds for a in c if c[0] == "reconstruct")
    used = {a.split(":")[0] for c in cmds for a in c if a.startswith("examples/")}
    shipped = {f"examples/{p.name}" for p in (REPO / "examples").iterdir() if p.is_file()}
    # every example file is used by a README command (my_policy.py with its class), or is a
    # script a benchmark runs (examples/gym_cem.py: training belongs in a benchmark)
    # (my_compiled_policy.py, gym_trained_policy.py: bench_policies, bench_python_policy)
    benches = " ".join(p.read_text() for p in (REPO / "benchmarks").glob("bench_*.py"))
    scripts = {e for e in shipped - used if Path(e).name in benches}
    # ... or a data file one of those examples reads (gym_trained_policy.json: its weights)
    code = " ".join((REPO / e).read_text() for e in used | scripts if e.endswith(".py"))
    data = {e for e in shipped - used - scripts if Path(e).name in code}
    assert used | scripts | data == shipped, (used, scripts, data, shipped)
    assert used, "the README runs the examples"


@pytest.fixture(scope="module")
def shared(trafficmonitoring_root, data_dir) -> dict[str, str]:
    return {
        "data/tm": str(trafficmonitoring_root),
        "data/ingolstadt.net.xml.gz": str(
            data_dir / "maps" / "ingolstadt_research_intersection.net.xml.gz"
        ),
    }


@pytest.mark.parametrize("recording", RECORDINGS)
def test_every_readme_command_on_a_real_recording(recording, shared, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for args in readme_commands():
        argv = []
        for a in args:
            a = shared.get(a, a)
            a = a.replace(README_RECORDING, recording)
            if a.startswith("examples/"):
                a = str(REPO / a)
            argv.append(a)
        code = main(argv)
        out = capsys.readouterr()
        assert code == 0, (
            f"vei {' '.join(argv)} exited {code}:\n{out.out[-3000:]}\n{out.err[-3000:]}"
        )
        assert "Traceback" not in out.err
        if "--out" in argv and "--list" not in argv:
            folder = Path(argv[argv.index("--out") + 1])
            for name in PROMISED.get(folder.name, []):
                assert (folder / name).is_file(), f"{folder}/{name} missing after vei {argv[0]}"
    xosc = list((tmp_path / "xosc").glob("*.xosc"))
    assert xosc and all(re.search(r"_normal-cap\.xosc$", p.name) for p in xosc)
