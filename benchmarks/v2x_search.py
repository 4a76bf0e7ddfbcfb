"""Search the shared recordings for an occluded crossing where V2X could decide the outcome.

For every TrafficMonitoring scenario with riders (imported with every road user, so that
stopped and parked vehicles are there to hide riders), every rider as the primary threat
(reconstructed on the shared SUMO map), the rider's time shift is scanned over its whole
span (0.2 s steps) with the paper's CAP on a replayed rider (the rider does not react):

- ``none``: no avoidance (where the paths meet at all);
- ``ideal``: the CAP with ideal perception;
- ``perception``: the CAP with vei's sensor model (range 50 m, field of view 90 deg,
  occlusion by every road user's box).

A recording "allows" the V2X case study when some shift makes perception alone collide
while ideal perception does not (the occlusion decides); V2X can only close that gap. The
same scan runs after ``--make-critical timing+path`` (the rider's path moved to meet the
car's). Prints one line per rider and writes ``search.csv`` into the work folder.

    python -m benchmarks.v2x_search --root ../shared/data/trafficmonitoring \\
        --map ../shared/data/maps/ingolstadt_research_intersection.net.xml.gz --work /tmp/v2x-search

Takes about ten minutes on two cores (the timing+path search is the slow part).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

RIDERS = ("escooter", "cyclist")


def vei(*args: str) -> None:
    """Run the vei CLI of this interpreter's environment."""
    exe = Path(sys.executable).with_name("vei")
    subprocess.run([str(exe), *args], check=True, capture_output=True, text=True)


def scan(scenario, shifts: np.ndarray) -> dict[str, np.ndarray]:
    """Collision per shift of none / ideal / perception (paper-cap, replayed rider)."""
    from vei.config import PerceptionConfig, SimConfig, case_preset
    from vei.sim.engine import simulate
    from vei.sim.state import VariantParams, prepare_scenario

    arrays = prepare_scenario(scenario, SimConfig())
    base = case_preset("replay")
    cap = replace(base, ego=replace(base.ego, policy="paper-cap"))
    cases = {
        "none": base,
        "ideal": cap,
        "perception": replace(cap, perception=PerceptionConfig(enabled=True)),
    }
    labels = np.array([f"shift{x:+.3f}" for x in shifts], dtype=object)
    out = {}
    for name, case in cases.items():
        p = VariantParams.from_case(case, arrays, len(shifts), time_shift_s=shifts)
        res = simulate(arrays, p.with_values(labels=labels), record="none", kernel="auto")
        out[name] = np.asarray(res.collision, dtype=bool)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", required=True, type=Path, help="trafficmonitoring dataset root")
    ap.add_argument("--map", required=True, type=Path, help="SUMO .net.xml(.gz) of the area")
    ap.add_argument("--work", required=True, type=Path, help="work folder")
    args = ap.parse_args(argv)

    from vei.datasets.trafficmonitoring import list_scenarios
    from vei.experiments.critical_path import make_critical
    from vei.io.scenario import read_scenario

    args.work.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in list_scenarios(args.root):
        it = args.work / f"it_{name}"
        try:
            vei("import", "trafficmonitoring", "--root", str(args.root), "--scenario", name,
                "--out", str(it), "--road-users", "all")  # fmt: skip
        except subprocess.CalledProcessError as exc:
            print(f"{name}: not imported ({exc.stderr.strip().splitlines()[-1]})")
            continue
        ann = pd.read_csv(it / "annotations.csv")
        for tid in sorted(ann.loc[ann["category"].isin(RIDERS), "track_id"].astype(str).unique()):
            sc_dir = args.work / f"sc_{name}__{tid}"
            try:
                vei("reconstruct", str(it), "--out", str(sc_dir), "--map", str(args.map),
                    "--threat", tid, "--no-figure")  # fmt: skip
            except subprocess.CalledProcessError:
                print(f"{name} rider {tid}: not reconstructed (too few keyframes)")
                continue
            sc = read_scenario(sc_dir)
            traj = sc.trajectories
            r = traj[traj["agent_id"] == sc.primary_threat]["t_s"]
            t_end = float(traj["t_s"].max())
            shifts = np.round(np.arange(-float(r.max()), t_end - float(r.min()), 0.2), 3)
            res = scan(sc, shifts)
            decided = res["perception"] & ~res["ideal"]
            row = {"scenario": name, "rider": tid, "mode": "timing", "shifts": len(shifts),
                   **{k: int(v.sum()) for k, v in res.items()},
                   "occlusion_decides": int(decided.sum())}  # fmt: skip
            rows.append(row)
            print(row, flush=True)
            try:
                moved, shift, _, _ = make_critical(sc, mode="timing+path")
            except Exception as exc:  # noqa: BLE001 - report and go on
                print(f"  timing+path: {exc}")
                continue
            near = np.round(shift + np.arange(-2.0, 2.0 + 1e-9, 0.1), 3)
            res = scan(moved, near)
            decided = res["perception"] & ~res["ideal"]
            row = {"scenario": name, "rider": tid, "mode": "timing+path", "shifts": len(near),
                   **{k: int(v.sum()) for k, v in res.items()},
                   "occlusion_decides": int(decided.sum())}  # fmt: skip
            rows.append(row)
            print(row, flush=True)
    table = pd.DataFrame(rows)
    table.to_csv(args.work / "search.csv", index=False)
    n = int((table["occlusion_decides"] > 0).sum()) if len(table) else 0
    print(f"riders x modes where the occlusion decides the outcome: {n} of {len(table)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
