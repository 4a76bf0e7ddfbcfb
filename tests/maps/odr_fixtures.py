"""Hand-written OpenDRIVE snippets for the tests (analytic geometry)."""

from __future__ import annotations

from pathlib import Path

HEADER = (
    '<?xml version="1.0" encoding="UTF-8"?>\n<OpenDRIVE>\n'
    '<header revMajor="1" revMinor="{minor}" name="t" version="1.00">'
    "<geoReference><![CDATA[+proj=tmerc +lat_0=48.0000000000 +lon_0=11.0000000000 +k=1 +x_0=0 +y_0=0 "
    "+ellps=WGS84 +units=m +no_defs]]></geoReference></header>\n"
)


def lane(lid: int, ltype: str, a: float, b: float = 0.0) -> str:
    return (
        f'<lane id="{lid}" type="{ltype}" level="false"><link/>'
        f'<width sOffset="0" a="{a}" b="{b}" c="0" d="0"/></lane>'
    )


def road(rid: str, length: float, geometry: str, *, left: str = "", right: str = "", offset: str = "",
         x: float = 10.0, y: float = 20.0, hdg: float = 0.0) -> str:  # fmt: skip
    left_el = f"<left>{left}</left>" if left else ""
    right_el = f"<right>{right}</right>" if right else ""
    return (
        f'<road name="r{rid}" length="{length}" id="{rid}" junction="-1"><link/>'
        f'<planView><geometry s="0" x="{x}" y="{y}" hdg="{hdg}" length="{length}">{geometry}</geometry></planView>'
        f"<lanes>{offset}"
        f'<laneSection s="0">{left_el}<center><lane id="0" type="none" level="false"><link/></lane></center>'
        f"{right_el}</laneSection></lanes></road>\n"
    )


def write_odr(path: Path, *roads: str, minor: int = 4) -> Path:
    path.write_text(HEADER.format(minor=minor) + "".join(roads) + "</OpenDRIVE>\n")
    return path


def straight_road() -> str:
    """100 m east from (10, 20): left driving 3.0 m; right driving 3.5 m, then sidewalk 2.0 m."""
    return road(
        "1", 100.0, "<line/>",
        left=lane(1, "driving", 3.0),
        right=lane(-1, "driving", 3.5) + lane(-2, "sidewalk", 2.0),
    )  # fmt: skip
