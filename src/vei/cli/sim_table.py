"""The terminal table of ``vei run`` / ``vei casestudy`` / ``vei demo``: one row per
configuration with the collision, timing and conflict metrics and what a collision costs
(impact speed, the rider's injury risk, the verdict against no avoidance)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any


def _console():
    from rich.console import Console

    return Console(soft_wrap=True) if sys.stdout.isatty() else Console(width=200)


def _fmt(value: Any, fmt: str = ".2f") -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if value != value:  # NaN
            return "-"
        if value in (float("inf"), float("-inf")):
            return "inf"
        return format(value, fmt)
    return str(value)


def _cell(rec: dict[str, Any], key: str, fmt: str | None) -> str:
    """One table cell of a summary record: a missing or empty value is '-'; the verdict
    names the configuration it is judged against ('avoided vs normal'), or says that the
    row is that reference itself (a no-avoidance configuration)."""
    value = rec.get(key)
    if key == "verdict":
        ref = rec.get("reference") or ""
        if not value or not ref:
            return "-"
        return "reference" if ref == rec.get("name") else f"{value} vs {ref}"
    if value == "":
        return "-"
    return _fmt(value, fmt) if fmt else _fmt(value)


def print_summary(result, out: Path | None = None, console=None) -> None:
    """Print the case-study table (one row per configuration: collision, timing and
    conflict metrics, and what a collision costs: impact speed, the rider's injury risk and
    the verdict against the no-avoidance configuration) and where it was written."""
    from rich.table import Table

    from vei.metrics import summary_records

    console = console or _console()
    ts = result.time_shift_s
    table = Table(
        title=f"case study: {result.scenario.id} (time shift {ts:+.2f} s, {result.time_shift.get('mode')}; backend {result.backend})"
    )
    cols = [
        ("config", "name", None),
        ("collision", "collision", None),
        ("t collision [s]", "collision_time_s", ".2f"),
        ("safety index", "safety_index", ".3f"),
        ("min gap [m]", "min_gap_m", ".2f"),
        ("min TTC [s]", "min_ttc_s", ".2f"),
        ("min TTC rel [s]", "min_ttc_rel_s", ".2f"),
        ("PET [s]", "pet_s", ".2f"),
        ("max DRAC [m/s2]", "max_drac_mps2", ".2f"),
        ("peak decel [m/s2]", "peak_decel_mps2", ".2f"),
        ("speed std [m/s]", "ego_speed_std_mps", ".3f"),
        # What a collision costs (vei.metrics.severity, docs/metrics.md)
        ("impact speed [m/s]", "impact_speed_mps", ".2f"),
        ("injury risk", "injury_risk", ".3g"),
        ("verdict", "verdict", None),
    ]
    # could the car have known (issue 22): beside the collision; the relative-TTC safety
    # index (issue 28.7): beside the paper's
    cols.insert(2, ("seen too late", "seen_too_late", None))
    cols.insert(
        cols.index(("safety index", "safety_index", ".3f")) + 1,
        ("SI rel", "safety_index_rel", ".3f"),
    )
    from rich.markup import escape

    for head, _, _ in cols:
        table.add_column(
            escape(head),
            justify="left" if head in ("config", "verdict") else "right",
            no_wrap=head in ("config", "verdict"),
        )
    for rec in summary_records(result.summary):
        table.add_row(*[escape(_cell(rec, key, fmt)) for _, key, fmt in cols])
    console.print(table)
    flagged = [r["name"] for r in summary_records(result.summary) if r.get("seen_too_late")]
    if flagged:
        console.print(
            escape(
                f"seen too late (no planner could have reacted: first seen within the "
                f"reaction time of contact or closer than the stopping distance): "
                f"{', '.join(flagged)}"
            )
        )
    crit = getattr(result, "criticality", None) or {}
    for key in ("perturbation_message", "message"):
        if crit.get(key):
            console.print(escape(crit[key]))
    outcome = result.paper_outcome()
    if outcome["reproduced"] is not None:
        verdict = "reproduced" if outcome["reproduced"] else "NOT reproduced"
        bad = [n for n, v in outcome["per_config"].items() if not v["ok"]]
        console.print(
            f"paper outcome (replay/normal/aggressive collide, the CAP runs keep safety index 1): {verdict}"
            + (f" (differs: {', '.join(bad)})" if bad else "")
        )
    if any(c.rider == "sfm" and c.sfm.speed_from_recording for c in getattr(result, "cases", ())):
        console.print(
            escape(
                f"SFM rider: speeds from {result.other_id}'s own recording (the calibrated "
                "rider, the default; docs/riders.md); the paper's rider (v0 5 m/s): "
                "--config paper-normal etc., or 'sfm: paper' in a configuration file"
            )
        )
    if out is not None:
        console.print(f"output folder: {out.resolve()}")
