"""The on-disk catalogue: layout, completion markers, assembly of the catalogue table.

Layout of a catalogue folder ``OUT``::

    catalogue.json                     manifest: format, dataset, settings (+ digest), status,
                                       recordings (status, reason, encounters), timings
    recordings/<rec>/interaction/      the imported interaction (vei.interaction/1)
    recordings/<rec>/scenario/         the reconstructed scenario (all riders)
    recordings/<rec>/status.json       {'status': 'ok'|'failed', 'reason', 'encounters', 'others'}
    encounters/<encounter_id>/scenario/    the recording with this rider as primary threat
    encounters/<encounter_id>/casestudy/   summary.json/csv, timeseries.parquet, figures
    encounters/<encounter_id>/ttc.parquet  the paper's TTC per configuration over time
    encounters/<encounter_id>/sweep/       the encounter's sweep (vei.sweep/1, resumable)
    encounters/<encounter_id>/rows.parquet the encounter's catalogue rows
    encounters/<encounter_id>/done.json    written last: the encounter is complete
    catalogue.parquet                  all rows, ranked (assembled when every job is done)
    encounters.csv                     one row per encounter, ranked
    report.html                        the HTML report (vei report)

Resume: every file is written atomically, and an encounter counts as done only when its
``done.json`` exists (written after its rows). A run killed at any instant loses only the
encounters in flight; a rerun skips done encounters (and recordings whose status.json
exists), and the catalogue is assembled from the done encounters' rows only, so nothing
appears twice.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.errors import InputError
from vei.io.atomic import write_json, write_parquet, write_text

CATALOGUE_FORMAT = "vei.catalogue/1"
MANIFEST = "catalogue.json"
TABLE = "catalogue.parquet"
ENCOUNTER_TABLE = "encounters.csv"


def recording_dir(out: Path, recording: str) -> Path:
    """Folder of one recording's import and reconstruction."""
    return Path(out) / "recordings" / recording


def encounter_dir(out: Path, encounter_id: str) -> Path:
    """Folder of one encounter's results."""
    return Path(out) / "encounters" / encounter_id


def read_json(path: Path) -> Any:
    """A JSON file written by the catalogue (InputError naming it if damaged)."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read catalogue file: {exc}", path=path) from None


def is_done(out: Path, encounter_id: str) -> bool:
    """Whether the encounter's rows are complete (its done.json exists)."""
    return (encounter_dir(out, encounter_id) / "done.json").is_file()


def mark_done(out: Path, encounter_id: str, info: dict[str, Any]) -> None:
    """Write the encounter's completion marker (after its rows)."""
    write_json(encounter_dir(out, encounter_id) / "done.json", info)


def done_encounters(out: Path) -> list[str]:
    """Ids of the complete encounters under ``out``, sorted."""
    base = Path(out) / "encounters"
    if not base.is_dir():
        return []
    return sorted(p.name for p in base.iterdir() if (p / "done.json").is_file())


def check_manifest(out: Path, digest: str, dataset: str) -> dict[str, Any] | None:
    """The existing manifest, or None; refuses a folder holding another catalogue.

    Raises:
        ConfigError: ``out`` holds a catalogue with other settings or of another dataset.
    """
    from vei.errors import ConfigError

    path = Path(out) / MANIFEST
    if not path.exists():
        return None
    old = read_json(path)
    if old.get("format") != CATALOGUE_FORMAT:
        raise ConfigError(f"{path} is not a vei catalogue manifest; choose another --out folder")
    if old.get("settings_digest") != digest:
        raise ConfigError(
            f"{out} holds a catalogue made with other settings (digest "
            f"{old.get('settings_digest')} != {digest}); choose another --out folder"
        )
    if old.get("dataset") != dataset:
        raise ConfigError(
            f"{out} holds a catalogue of another dataset ({old.get('dataset')}); choose another --out folder"
        )
    return old


def write_manifest(out: Path, doc: dict[str, Any]) -> Path:
    """Write catalogue.json atomically."""
    return write_json(Path(out) / MANIFEST, doc)


#: Ranking of rows: collisions first, then the lowest safety index, the smallest gap, TTC;
#: rows flagged seen_too_late (no planner could have reacted, vei.metrics.seen) after
#: every unflagged one.
ROW_ORDER: tuple[tuple[str, bool], ...] = (
    ("seen_too_late", True),
    ("collision", False),
    ("safety_index", True),
    ("min_gap_m", True),
    ("min_ttc_s", True),
)


def encounter_scores(rows: pd.DataFrame) -> pd.DataFrame:
    """One row per encounter with its criticality and rank (1 = most critical).

    Criticality of an encounter: with a risk estimate (issue 23; ``risk_*`` columns of
    its rows), the expected harm (probability x injury risk) and then P(collision), the
    encounters with only an upper bound after those with an estimate; then (and without
    one) ``collision_share`` = share of its simulated configurations (case study + sweep)
    that collide, the lowest mean safety index, the smallest minimum gap over them.
    Configurations flagged ``seen_too_late`` (the rider was first seen too late for any
    planner, vei.metrics.seen) are counted apart (``n_flagged``, ``flagged_collisions``)
    and left out of every score (the risk estimate leaves them out of its probabilities
    too), so they never decide a rank; an encounter whose configurations are all flagged
    ranks last. Returns columns encounter_id, recording, rider_id, category, the recorded
    geometry, n_configs, n_flagged, flagged_collisions, collision_share,
    mean_safety_index, worst_min_gap_m, worst_min_ttc_s, casestudy_collisions, the
    ``risk_*`` columns where estimated, secondary_share / rear_end_share (issue 24: share
    of its unflagged configurations with a secondary / a rear-end collision, where the
    rows report them), the recorded-behaviour columns of :func:`_recorded_shares` where
    the rows report ``collision_recorded`` (issue 31), rank.
    """
    from vei.metrics.seen import flagged_mask

    flag = flagged_mask(rows)
    all_rows, rows = rows, rows[~flag]
    geo_cols = [
        c
        for c in (
            "recording",
            "rider_id",
            "category",
            "rec_path_distance_m",
            "rec_pet_s",
            "rec_min_gap_m",
            "rec_crossing_angle_deg",
            "rec_ego_speed_mps",
            "rec_rider_speed_mps",
            "time_shift_auto_s",
        )
        if c in rows
    ]
    ga = all_rows.groupby("encounter_id", sort=True)
    out = ga[geo_cols].first()
    out["n_configs"] = ga.size()
    fl = all_rows.assign(_f=flag, _fc=flag & all_rows["collision"].fillna(False).astype(bool))
    out["n_flagged"] = fl.groupby("encounter_id")["_f"].sum().astype(int)
    out["flagged_collisions"] = fl.groupby("encounter_id")["_fc"].sum().astype(int)
    g = rows.groupby("encounter_id", sort=True)
    out["collision_share"] = g["collision"].mean().astype(float).reindex(out.index)
    out["mean_safety_index"] = g["safety_index"].mean().reindex(out.index)
    out["worst_min_gap_m"] = g["min_gap_m"].min().reindex(out.index)
    out["worst_min_ttc_s"] = (
        g["min_ttc_s"].min().reindex(out.index) if "min_ttc_s" in rows else np.nan
    )
    cs = rows[rows["kind"] == "casestudy"]
    out["casestudy_collisions"] = (
        cs.groupby("encounter_id")["collision"].sum().reindex(out.index).fillna(0).astype(int)
    )
    # secondary collisions (issue 24): the share of configurations with one, a rear-end
    for col, name in (
        ("secondary_collision", "secondary_share"),
        ("rear_end_collision", "rear_end_share"),
    ):
        if col in rows:
            out[name] = g[col].apply(lambda c: c.fillna(False).astype(bool).mean()).astype(float)
    if "collision_recorded" in rows:  # issue 31: the collisions the data itself supports
        _recorded_shares(out, rows)
    risk_cols = [c for c in all_rows.columns if c.startswith("risk_")]
    for c in risk_cols:  # issue 23: one estimate per encounter, constant over its rows
        out[c] = ga[c].first()
    keys = ["collision_share", "mean_safety_index", "worst_min_gap_m", "encounter_id"]
    asc = [False, True, True, True]
    if "risk_expected_harm" in out:  # ranked by expected harm, then P(collision)
        out["_harm"] = out["risk_expected_harm"].fillna(0.0)  # a bound only: after estimates
        out["_p"] = out["risk_p_collision"].fillna(0.0)
        keys, asc = ["_harm", "_p", *keys], [False, False, *asc]
    out = out.reset_index().sort_values(keys, ascending=asc, kind="stable", na_position="last")
    out = out.drop(columns=[c for c in ("_harm", "_p") if c in out])
    out["rank"] = np.arange(1, len(out) + 1)
    return out.reset_index(drop=True)


def assemble(out: Path, ids: list[str] | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Assemble (rows, encounters) from the done encounters (all, or ``ids``), rank them and
    write catalogue.parquet and encounters.csv atomically.

    rows: one per encounter x configuration, with ``encounter_rank`` (the encounter's
    rank) and ``rank`` (the row's rank over the whole catalogue by ROW_ORDER).
    """
    out = Path(out)
    ids = done_encounters(out) if ids is None else [i for i in ids if is_done(out, i)]
    parts = [pd.read_parquet(encounter_dir(out, i) / "rows.parquet") for i in ids]
    if not parts:
        rows = pd.DataFrame()
        enc = pd.DataFrame()
    else:
        rows = pd.concat(parts, ignore_index=True)
        dup = rows.duplicated(["encounter_id", "kind", "config"])
        if dup.any():  # every encounter's rows come from one file: this is a bug guard
            raise RuntimeError(f"duplicate catalogue rows: {rows[dup].head()}")
        enc = encounter_scores(rows)
        rows = rows.merge(
            enc[["encounter_id", "rank"]].rename(columns={"rank": "encounter_rank"}),
            on="encounter_id",
        )
        if "seen_too_late" not in rows:  # rows made before the flag existed: unflagged
            rows = rows.assign(seen_too_late=False)
        keys = [k for k, _ in ROW_ORDER if k in rows] + ["encounter_id", "kind", "config"]
        asc = [a for k, a in ROW_ORDER if k in rows] + [True, True, True]
        rows = rows.sort_values(keys, ascending=asc, kind="stable", na_position="last").reset_index(
            drop=True
        )
        rows.insert(0, "rank", np.arange(1, len(rows) + 1))
    write_parquet(out / TABLE, rows)
    write_text(out / ENCOUNTER_TABLE, enc.to_csv(index=False))
    return rows, enc


def _recorded_shares(out: pd.DataFrame, rows: pd.DataFrame) -> None:
    """Add, per encounter (``out``'s index) from its unflagged ``rows``:
    ``recorded_collision_share`` = share of its configurations that collide with the primary
    rider on the rider's recorded behaviour, with its 95 % Wilson interval
    (``recorded_collision_share_lo`` / ``_hi``), and ``collisions_on_recorded`` = the share
    of its collisions that happen on recorded behaviour (NaN without a collision); the
    rest happen on the synthetic run-in or run-out (vei.continuation)."""
    from vei.sweep.riskmap import wilson_intervals

    coll = rows["collision"].fillna(False).astype(bool)
    on_rec = rows["collision_recorded"].fillna(False).astype(bool) & coll
    frame = pd.DataFrame({"e": rows["encounter_id"], "c": coll, "r": on_rec})
    g = frame.groupby("e", sort=True)
    n, k, n_coll = g.size(), g["r"].sum().astype(int), g["c"].sum().astype(int)
    share_runs = (k / n).astype(float)
    lo, hi = wilson_intervals(share_runs.to_numpy(), n.to_numpy())
    out["recorded_collision_share"] = share_runs.reindex(out.index)
    out["recorded_collision_share_lo"] = pd.Series(lo, index=n.index).reindex(out.index)
    out["recorded_collision_share_hi"] = pd.Series(hi, index=n.index).reindex(out.index)
    share = (k / n_coll.where(n_coll > 0)).astype(float)
    out["collisions_on_recorded"] = share.reindex(out.index)
