"""Map benchmark: crop + OpenDRIVE conversion of a 500 m x 500 m region of the Helsinki extract.

Region: 500 m x 500 m centred on the extract's centre (60.171634 N, 24.944295 E, central
Helsinki). Times are the best of ``REPEATS`` runs (wall clock, in-process for the crop,
netconvert as a subprocess). Targets are vei's own (interactive use of ``vei reconstruct
--map auto``): crop under 2 s, conversion under 10 s.

Data: $VEI_DATA_DIR/osm/helsinki.osm.pbf (default ../shared/data).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

REPEATS = 3
CENTRE = (60.171634, 24.944295)
HALF_SIDE_M = 250.0
TARGET_CROP_S = 2.0
TARGET_BUILD_S = 10.0


def _data() -> Path | None:
    root = Path(
        os.environ.get(
            "VEI_DATA_DIR", Path(__file__).resolve().parents[1].parent / "shared" / "data"
        )
    )
    path = root / "osm" / "helsinki.osm.pbf"
    return path if path.is_file() else None


def main() -> None:
    from vei.geo import Bounds
    from vei.maps.build import build_opendrive
    from vei.maps.fetch import crop_osm
    from vei.maps.roads import load_roads
    from vei.maps.validate import validate_opendrive

    src = _data()
    if src is None:
        print("helsinki.osm.pbf not found (set VEI_DATA_DIR); skipped")
        return
    bounds = Bounds.around(CENTRE[0], CENTRE[1], margin_m=HALF_SIDE_M)
    crop_t, build_t, valid_t, load_t = [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        osm = Path(tmp) / "region.osm"
        for _ in range(REPEATS):
            t0 = time.perf_counter()
            counts = crop_osm(src, bounds, osm)
            crop_t.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            res = build_opendrive(osm, Path(tmp) / "region.xodr", origin=CENTRE)
            build_t.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            report = validate_opendrive(res.opendrive)
            valid_t.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            roads = load_roads(res.opendrive)
            load_t.append(time.perf_counter() - t0)
        size_kb = res.opendrive.stat().st_size / 1024
    rows = [
        ("crop (osmium, complete ways)", min(crop_t), f"< {TARGET_CROP_S:g} s"),
        ("conversion (netconvert -> .xodr)", min(build_t), f"< {TARGET_BUILD_S:g} s"),
        (
            "crop + conversion",
            min(crop_t) + min(build_t),
            f"< {TARGET_CROP_S + TARGET_BUILD_S:g} s",
        ),
        ("XSD validation", min(valid_t), "-"),
        ("load_roads (lane polygons)", min(load_t), "-"),
    ]
    print(f"region 500 m x 500 m at {CENTRE[0]}, {CENTRE[1]} (S,W,N,E = {bounds.as_sw_ne()})")
    print(f"crop: {counts['ways']} ways, {counts['nodes']} nodes, {counts['relations']} relations; "
          f"OpenDRIVE {report.version} {size_kb:.0f} KiB, valid={report.valid}, {len(roads.lanes)} lanes")  # fmt: skip
    print(f"{'step':36s} {'best of ' + str(REPEATS):>12s} {'target':>10s}")
    for name, secs, target in rows:
        print(f"{name:36s} {secs:10.2f} s {target:>10s}")
    ok = min(crop_t) < TARGET_CROP_S and min(build_t) < TARGET_BUILD_S
    print("targets met" if ok else "targets MISSED")


if __name__ == "__main__":
    main()
    sys.exit(0)
