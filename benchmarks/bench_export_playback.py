"""Export + esmini playback of a ~60 s real recording (stadtmitte_12_audi_geradeaus_03).

The recording is imported and reconstructed with its map (the Ingolstadt SUMO network,
converted to OpenDRIVE by netconvert), exported for the recorded trajectories and the
``normal-cap`` run (OpenSCENARIO 1.2), and each file is played headless in esmini
(``--fixed_timestep 0.05 --collision``, as ``vei export check`` does). Times are the best
of ``REPEATS`` runs (wall clock; esmini as a subprocess). Also measured: esmini with the
same file stopped after 0.1 s (loading the scenario and its map, the fixed cost of a
play), the log size and the warnings / errors from the file (0 expected), and how far
the played paths are from the file's vertices.

Data: $VEI_DATA_DIR (default ../shared/data); esmini: $VEI_ESMINI (default
../shared/tools/esmini).
"""

from __future__ import annotations

import os
import re
import resource
import sys
import tempfile
import time
from pathlib import Path

REPEATS = 3
SCENARIO = "stadtmitte_12_audi_geradeaus_03"
ROOT = Path(__file__).resolve().parents[1]


def _data_root() -> Path:
    return Path(os.environ.get("VEI_DATA_DIR", ROOT.parent / "shared" / "data"))


def _short_copy(xosc: Path) -> Path:
    """The same file with its stop trigger at 0.1 s (load + two steps)."""
    text = xosc.read_text(encoding="utf-8")
    i = text.index('name="vei_stop"')
    j = text.index('value="', text.index("SimulationTimeCondition", i)) + len('value="')
    k = text.index('"', j)
    out = xosc.with_name(xosc.stem + "_load_only.xosc")
    out.write_text(text[:j] + "0.1" + text[k:], encoding="utf-8")
    return out


def _child_cpu_s() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def main() -> None:
    from vei.cli.main import main as cli
    from vei.errors import DependencyError
    from vei.esmini import find_esmini
    from vei.experiments.casestudy import run_casestudy
    from vei.export.openscenario import export_openscenario, timeseries_to_trajectories
    from vei.export.playback import play_xosc
    from vei.io.scenario import read_scenario

    data = _data_root()
    tm = data / "trafficmonitoring"
    net = data / "maps" / "ingolstadt_research_intersection.net.xml.gz"
    if not tm.is_dir() or not net.is_file():
        print(f"trafficmonitoring data or the Ingolstadt network not under {data}; skipped")
        return
    try:
        esmini = find_esmini()
        esmini.require_player()
    except DependencyError as exc:
        print(f"esmini not found ({exc}); skipped")
        return
    with tempfile.TemporaryDirectory(prefix="vei-bench-") as tmp:
        tmp = Path(tmp)
        t0 = time.perf_counter()
        code = cli(["import", "trafficmonitoring", "--root", str(tm), "--scenario", SCENARIO,
                    "--out", str(tmp / "inter")])  # fmt: skip
        code = code or cli(["reconstruct", str(tmp / "inter"), "--out", str(tmp / "scen"),
                            "--no-figure", "--map", str(net)])  # fmt: skip
        if code:
            print(f"import / reconstruct failed (exit {code})")
            sys.exit(1)
        t_build = time.perf_counter() - t0
        sc = read_scenario(tmp / "scen")
        xodr = tmp / "scen" / sc.maps["opendrive"]
        frame = run_casestudy(sc, cases=["normal-cap"], time_shift="auto").frame
        runs = {
            "recorded": sc.trajectories,
            "normal-cap": timeseries_to_trajectories(frame, config="normal-cap"),
        }
        n_roads = len(re.findall(rb"<road ", xodr.read_bytes()))
        print(f"{SCENARIO}: {sc.trajectories['t_s'].max():.1f} s, "
              f"{sc.trajectories['agent_id'].nunique()} road users; map {xodr.stat().st_size / 1e6:.2f} MB, "
              f"{n_roads} roads; import + reconstruct with the map {t_build:.1f} s")  # fmt: skip
        head = (f"{'run':<11} {'export s':>8} {'play s':>7} {'cpu s':>6} {'load s':>7} {'frames':>6} "
                f"{'log kB':>6} {'warn':>4} {'err':>3} {'inst':>4} {'med dev m':>9} "
                f"{'max dev m':>9} {'collisions':<14}")  # fmt: skip
        print(head)
        print("-" * len(head))
        for name, traj in runs.items():
            ex, pl, ld, cpu = [], [], [], []
            for _ in range(REPEATS):
                t0 = time.perf_counter()
                path = export_openscenario(
                    traj, list(sc.agents), tmp / "out" / name, xodr=xodr, name=name
                )
                ex.append(time.perf_counter() - t0)
                c0 = _child_cpu_s()
                rep = play_xosc(path, esmini=esmini, work_dir=tmp / "play" / name)
                cpu.append(_child_cpu_s() - c0)
                pl.append(rep.wall_s)
                ld.append(play_xosc(_short_copy(path), esmini=esmini).wall_s)
            tab = rep.table()
            pairs = sorted("-".join(sorted(p)) for p in rep.collision_pairs())
            print(f"{name:<11} {min(ex):>8.2f} {min(pl):>7.2f} {min(cpu):>6.2f} {min(ld):>7.2f} "
                  f"{rep.frames['time'].nunique():>6} {rep.log_bytes / 1e3:>6.1f} "
                  f"{len(rep.log.warnings):>4} {len(rep.log.errors):>3} "
                  f"{len(rep.log.install_warnings):>4} {tab['median_dev_m'].max():>9.4f} "
                  f"{tab['max_dev_m'].max():>9.4f} {', '.join(pairs) or 'none':<14}")  # fmt: skip
        print(
            "play s: esmini wall time for the whole run (cpu s: CPU time of esmini + dat2csv, "
            "less sensitive to a busy machine); load s: the same file stopped at "
            "0.1 s (scenario + map loading); warn / err: log lines caused by the file "
            "(0 expected); inst: messages about the installation's missing resources "
            "(3D models, traffic-sign table); dev: worst entity's median / max distance "
            "from the file's vertices"
        )


if __name__ == "__main__":
    main()
