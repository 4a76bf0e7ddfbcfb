"""The terminal table of ``vei run`` / ``vei casestudy`` / ``vei demo``: one row per
configuration with the collision, timing and conflict metrics and what a collision costs
(impact speed, the rider's injury risk, the verdict against no avoidance)."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def _console():
    from vei.cli.output import console

    return console()


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
    names the configuration it is judged against ('avoided vs normal'), says that there
    was nothing to avoid (the reference did not collide either), or that the row is that
    reference itself (a no-avoidance configuration)."""
    value = rec.get(key)
    if key == "verdict":
        ref = rec.get("reference") or ""
        if not value or not ref:
            return "-"
        if ref == rec.get("name"):
            return "reference"
        if value == "nothing-to-avoid":
            return f"nothing to avoid ({ref} did not collide)"
        return f"{value} vs {ref}"
    if value == "":
        return "-"
    return _fmt(value, fmt) if fmt else _fmt(value)


def summary_table(title: str, heads: list[str], rows: list[list[str]], width: int):
    """The case-study table: one row per configuration when it fits ``width`` characters,
    else transposed (one row per metric, one column per configuration), so that no value is
    ever cut off; a value that still does not fit is folded, never truncated."""
    from rich.table import Table

    # one row per configuration fits when every column holds its widest value unwrapped
    # (headers may wrap at their spaces): value or longest header word, + 3 for the borders
    widths = [
        max([len(r[j]) for r in rows] + [len(w) for w in head.split()])
        for j, head in enumerate(heads)
    ]
    if 1 + sum(3 + w for w in widths) <= width:
        wide = Table(title=title)
        for j, head in enumerate(heads):
            left = j == 0 or head == "verdict"
            wide.add_column(
                head, justify="left" if left else "right", overflow="fold", width=widths[j]
            )
        for row in rows:
            wide.add_row(*row)
        return wide
    tall = Table(title=title)
    tall.add_column(heads[0], justify="left", overflow="fold")
    for row in rows:
        tall.add_column(row[0], justify="right", overflow="fold")
    for j, head in enumerate(heads[1:], start=1):
        tall.add_row(head, *[row[j] for row in rows])
    return tall


def print_summary(result, out: Path | None = None, console=None) -> None:
    """Print the case-study table (one row per configuration: collision, timing and
    conflict metrics, and what a collision costs: impact speed, the rider's injury risk and
    the verdict against the no-avoidance configuration) and where it was written."""

    from vei.metrics import summary_records

    console = console or _console()
    ts = result.time_shift_s
    title = (
        f"case study: {result.scenario.id} (time shift {ts:+.2f} s, "
        f"{result.time_shift.get('mode')}; backend {result.backend})"
    )
    cols = [
        ("config", "name", None),
        # which behaviour models ran (issue 32.4): decisions, traffic, V2X, perception
        ("switches", "switches", None),
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
    records = summary_records(result.summary)
    cells = [[_cell(rec, key, fmt) for _, key, fmt in cols] for rec in records]
    console.print(summary_table(title, [head for head, _, _ in cols], cells, console.width))
    flagged = [r["name"] for r in records if r.get("seen_too_late")]
    if flagged:
        console.print(
            "seen too late (no planner could have reacted: first seen within the "
            "reaction time of contact or closer than the stopping distance): "
            f"{', '.join(flagged)}"
        )
    for rec in records:
        if rec.get("v2x_note"):
            console.print(f"{rec['name']}: V2X: {rec['v2x_note']}", highlight=False)
    crit = getattr(result, "criticality", None) or {}
    for key in ("perturbation_message", "message"):
        if crit.get(key):
            console.print(crit[key], highlight=False)
    hit = [r["name"] for r in records if r.get("collision")]
    if crit.get("message") and crit.get("paths_meet") is False and hit:
        console.print(
            "the line above is about the recorded paths; in the simulation "
            f"{', '.join(hit)} collided (the table)",
            highlight=False,
        )
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
            f"SFM rider: speeds from {result.other_id}'s own recording (the calibrated "
            "rider, the default; docs/riders.md); the paper's rider (v0 5 m/s): "
            "--config paper-normal etc., or 'sfm: paper' in a configuration file"
        )
    if out is not None:
        console.print(f"output folder: {out.resolve()}")
