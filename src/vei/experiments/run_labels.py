"""Labels that say what ran: the behaviour switches of each configuration and what V2X did.

A configuration's name ('normal', 'normal-cap') says which rider and controller ran, not
which of vei's behaviour models were switched on. :func:`switches` names them (the
rider's yield / go decisions, reacting traffic, V2X, the car's sensor model);
:func:`add_run_labels` writes them into a case study's summary (column ``switches``) with
what V2X did in each run (the fields of :mod:`vei.policy.v2x.report` and a ``v2x_note``
line that also says when V2X changed nothing).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from vei.config import CaseConfig

#: A configuration without any of the switches.
NO_SWITCHES = "none"


def switches(case: CaseConfig) -> tuple[str, ...]:
    """The behaviour switches that are on in ``case``, in words: 'decisions' (the
    social-force rider's yield / go decision), 'traffic (cars react, pedestrians social
    force)', 'V2X (<technology>, <penetration> equipped)', 'perception' (the car's sensor
    model; off: ideal perception)."""
    out: list[str] = []
    if case.decision.enabled:
        out.append("decisions" if case.rider == "sfm" else "decisions (no effect: replayed rider)")
    parts = [w for on, w in ((case.traffic.cars_react, "cars react"),
                             (case.traffic.pedestrians, "pedestrians social force")) if on]  # fmt: skip
    if parts:
        out.append(f"traffic ({', '.join(parts)})")
    if case.v2x.enabled:
        v = case.v2x
        out.append(f"V2X ({v.technology}, {v.penetration_rate:.0%} equipped)")
    if case.perception is not None and case.perception.enabled:
        out.append("perception")
    return tuple(out)


def switches_text(case: CaseConfig) -> str:
    """:func:`switches` as one comma-separated string ('none' without any)."""
    on = switches(case)
    return ", ".join(on) if on else NO_SWITCHES


def add_run_labels(
    summary: pd.DataFrame,
    cases: Sequence[CaseConfig],
    v2x: Mapping[str, Sequence[float]] | None,
    *,
    backend: str = "builtin",
) -> pd.DataFrame:
    """``summary`` (one row per case, same order) with the column ``switches`` and, where a
    case ran V2X, its report (vei.policy.v2x.report.REPORT_FIELDS) and ``v2x_note``.

    Args:
        summary: the case study's summary. cases: its configurations.
        v2x: {field: [B]} what V2X did in each run (SimResult.v2x), or None (no case
            ran V2X, or the backend does not report it).
        backend: the backend's name (for the note when it does not report V2X).
    """
    from vei.policy.v2x.report import REPORT_FIELDS, note

    out = summary.copy()
    out["switches"] = np.asarray([switches_text(c) for c in cases], dtype=object)
    with_v2x = np.array([bool(c.v2x.enabled) for c in cases])
    if not with_v2x.any():
        return out
    b = len(cases)
    for name in REPORT_FIELDS:
        vals = np.full(b, np.nan) if v2x is None else np.asarray(v2x[name], dtype=np.float64)
        out[name] = np.where(with_v2x, vals, np.nan)
    notes = []
    for i, case in enumerate(cases):
        if not case.v2x.enabled:
            notes.append("")
        elif v2x is None:
            notes.append(f"what V2X did is not reported by backend {backend!r}")
        else:
            rec: dict[str, Any] = {k: out[k].iloc[i] for k in REPORT_FIELDS}
            noise = case.perception.position_noise_std_m if case.perception is not None else 0.0
            notes.append(note(rec, noise if case.perception and case.perception.enabled else 0.0))
    out["v2x_note"] = np.asarray(notes, dtype=object)
    return out


__all__ = ["NO_SWITCHES", "add_run_labels", "switches", "switches_text"]
