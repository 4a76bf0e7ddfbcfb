"""The per-recording and per-encounter work of a catalogue (run in any worker).

:func:`process_recording`: import (TrafficMonitoring) or read (interaction folder) one
recording, reconstruct it (map from a local source where given), find its encounters.
:func:`process_encounter`: make the rider the primary threat, run the case study (the
paper's five configurations, automatic time shift) and the sweep, write the rows.
Both are plain functions of picklable arguments returning plain dicts, so a local
process pool and Ray run the very same code; both resume from what is on disk.
"""

from __future__ import annotations

import dataclasses
import functools
import re
import shutil
import traceback
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.catalogue.config import CatalogueConfig
from vei.catalogue.encounters import Encounter, find_encounters
from vei.catalogue.store import encounter_dir, is_done, mark_done, read_json, recording_dir
from vei.errors import NoRidersError, VeiError
from vei.io.atomic import write_json, write_parquet

#: Dataset kinds :func:`list_recordings` recognises.
KIND_TRAFFICMONITORING = "trafficmonitoring"
KIND_INTERACTIONS = "interactions"


def list_recordings(dataset: str | Path) -> tuple[str, list[str]]:
    """(kind, recording names) of a dataset folder.

    Kinds: 'trafficmonitoring' (a folder holding data/measurements: one recording per
    matching file) or 'interactions' (a folder of interaction-format folders, one per
    recording, or one such folder itself).

    Raises:
        InputError: neither layout.
    """
    from vei.datasets.trafficmonitoring import MEASUREMENTS_DIR, list_scenarios
    from vei.errors import InputError

    root = Path(dataset)
    if not root.is_dir():
        raise InputError("dataset folder not found", path=root)
    if (root / MEASUREMENTS_DIR).is_dir():
        return KIND_TRAFFICMONITORING, list_scenarios(root)
    if (root / "interaction.json").is_file():  # one interaction folder: one recording
        return KIND_INTERACTIONS, [root.name]
    subs = sorted(p.name for p in root.iterdir() if (p / "interaction.json").is_file())
    if not subs:
        raise InputError(
            "not a dataset: expected a TrafficMonitoring root (data/measurements) or a folder of "
            "interaction folders (each with interaction.json)",
            path=root,
        )
    return KIND_INTERACTIONS, subs


_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")


def _reason(exc: BaseException) -> str:
    """Why a job failed: a user error's own message; else 'internal error' with the
    exception's type, its message's first line and where it was raised."""
    if isinstance(exc, VeiError):
        return str(exc)
    last = traceback.extract_tb(exc.__traceback__)[-1:] if exc.__traceback__ else []
    where = f" at {Path(last[0].filename).name}:{last[0].lineno}" if last else ""
    text = _ANSI.sub("", str(exc)).strip().splitlines()
    return f"internal error {type(exc).__name__}: {text[0] if text else ''}{where}"


def process_recording(
    dataset: str, kind: str, recording: str, out: str, config: CatalogueConfig
) -> dict[str, Any]:
    """Import/read, reconstruct and find the encounters of one recording.

    Returns (and writes as recordings/<rec>/status.json) {'recording', 'status': 'ok' |
    'no-riders' | 'failed', 'reason', 'encounters': [Encounter.as_dict()], 'others': [...],
    'n_riders'}. Never raises for a bad recording: the failure is the returned status; a
    recording without any e-scooter or cyclist is 'no-riders' (nothing to do, not a failure).
    """
    rec_dir = recording_dir(Path(out), recording)
    status_path = rec_dir / "status.json"
    if status_path.is_file():
        old = read_json(status_path)
        if old.get("status") in ("ok", "no-riders"):
            return old
    try:
        doc = _recording(Path(dataset), kind, recording, rec_dir, config)
    except NoRidersError as exc:
        doc = {
            "recording": recording,
            "status": "no-riders",
            "reason": _reason(exc),
            "encounters": [],
            "others": [],
            "n_riders": 0,
        }
    except Exception as exc:  # a recording that fails never stops the others
        doc = {
            "recording": recording,
            "status": "failed",
            "reason": _reason(exc),
            "encounters": [],
            "others": [],
            "n_riders": 0,
        }
    write_json(status_path, doc)
    return doc


def _recording(
    dataset: Path, kind: str, recording: str, rec_dir: Path, config: CatalogueConfig
) -> dict[str, Any]:
    from vei.io.interaction import read_interaction
    from vei.io.scenario import read_scenario, write_scenario
    from vei.recon.pipeline import reconstruct

    rec_dir.mkdir(parents=True, exist_ok=True)
    scen_dir = rec_dir / "scenario"
    if (scen_dir / "scenario.json").is_file():
        scenario = read_scenario(scen_dir)
    else:
        if kind == KIND_TRAFFICMONITORING:
            from vei.datasets.trafficmonitoring import import_scenario

            inter_dir = rec_dir / "interaction"
            if not (inter_dir / "interaction.json").is_file():
                import_scenario(
                    dataset, recording, inter_dir, rate_hz=config.annotation_rate_hz,
                    road_users=config.road_users,
                )  # fmt: skip
        else:
            inter_dir = dataset if (dataset / "interaction.json").is_file() else dataset / recording
        scenario = reconstruct(read_interaction(inter_dir), config.recon_config())
        writers: dict[str, Any] = {}
        if config.map_source is not None:
            import tempfile

            from vei.maps.scenario_map import add_map

            with tempfile.TemporaryDirectory(prefix=".vei-map-", dir=rec_dir) as work:
                scenario, files, _ = add_map(scenario, Path(work), source=config.map_source)
                for name, path in files.items():
                    writers[name] = functools.partial(shutil.copyfile, path)
                write_scenario(scenario, scen_dir, extra_files=writers)
        else:
            write_scenario(scenario, scen_dir)
        scenario = read_scenario(scen_dir)
    found, others = find_encounters(scenario, config.rule)
    # Encounters belong to the recording as listed (its folder under recordings/), not to the
    # scenario id: two folders may share an id, and a folder may be named otherwise.
    found, others = (
        [
            dataclasses.replace(e, recording=recording, encounter_id=f"{recording}__{e.rider_id}")
            for e in group
        ]
        for group in (found, others)
    )
    if config.max_encounters_per_recording is not None:
        others = found[config.max_encounters_per_recording :] + others
        found = found[: config.max_encounters_per_recording]
    n_riders = sum(a.category in config.rule.categories for a in scenario.agents)
    return {
        "recording": recording,
        "scenario_id": scenario.id,
        "status": "ok",
        "reason": "" if found else f"no encounter among {n_riders} rider(s) under the rule",
        "encounters": [e.as_dict() for e in found],
        "others": [e.as_dict() for e in others],
        "n_riders": n_riders,
        "road_users": config.road_users if kind == KIND_TRAFFICMONITORING else "as given",
        "interp": config.recon_config().interp,
        "duration_s": float(
            scenario.trajectories["t_s"].max() - scenario.trajectories["t_s"].min()
        ),
    }


def _clean_object_columns(frame: pd.DataFrame) -> pd.DataFrame:
    """Object columns -> nullable booleans (all values bool) or strings, for Parquet."""
    for col in frame.columns:
        if frame[col].dtype != object:
            continue
        vals = frame[col].dropna()
        if len(vals) and all(isinstance(v, bool | np.bool_) for v in vals):
            frame[col] = frame[col].astype("boolean")
        else:
            frame[col] = frame[col].map(
                lambda v: (
                    None
                    if v is None or v is pd.NA or (isinstance(v, float) and np.isnan(v))
                    else str(v)
                )
            )
    return frame


def _float(v: Any) -> float:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else float("nan")


def process_encounter(
    out: str, encounter: dict[str, Any], config: CatalogueConfig
) -> dict[str, Any]:
    """Case study + sweep of one encounter; writes its rows and its done.json.

    Returns {'encounter_id', 'status': 'ok' | 'failed' | 'done-before', 'reason',
    'n_rows', 'seconds'}. Never raises for a bad encounter.
    """
    import time

    enc = Encounter.from_dict(encounter)
    outp = Path(out)
    if is_done(outp, enc.encounter_id):
        return {
            "encounter_id": enc.encounter_id,
            "status": "done-before",
            "reason": "",
            "n_rows": 0,
        }
    t0 = time.perf_counter()
    try:
        n = _encounter(outp, enc, config)
    except Exception as exc:
        doc = {
            "encounter_id": enc.encounter_id,
            "status": "failed",
            "reason": _reason(exc),
            "n_rows": 0,
        }
        write_json(encounter_dir(outp, enc.encounter_id) / "failed.json", doc)
        return doc
    seconds = time.perf_counter() - t0
    mark_done(
        outp, enc.encounter_id, {"encounter_id": enc.encounter_id, "n_rows": n, "seconds": seconds}
    )
    failed = encounter_dir(outp, enc.encounter_id) / "failed.json"
    failed.unlink(missing_ok=True)
    return {
        "encounter_id": enc.encounter_id,
        "status": "ok",
        "reason": "",
        "n_rows": n,
        "seconds": seconds,
    }


def _encounter(out: Path, enc: Encounter, config: CatalogueConfig) -> int:
    from vei.experiments.casestudy import run_casestudy, write_casestudy
    from vei.io.scenario import read_scenario, write_scenario
    from vei.sweep.run import run_sweep

    edir = encounter_dir(out, enc.encounter_id)
    edir.mkdir(parents=True, exist_ok=True)
    scen_dir = edir / "scenario"
    if not (scen_dir / "scenario.json").is_file():
        rec = read_scenario(recording_dir(out, enc.recording) / "scenario")
        copies = {
            name: functools.partial(shutil.copyfile, Path(rec.root) / name)
            for name in rec.maps.values()
            if rec.root is not None and (Path(rec.root) / name).is_file()
        }
        extra = dict(rec.extra)
        extra["catalogue_encounter"] = enc.as_dict()
        scenario = dataclasses.replace(rec, primary_threat=enc.rider_id, extra=extra, root=None)
        write_scenario(scenario, scen_dir, extra_files=copies)
    scenario = read_scenario(scen_dir)

    cs = run_casestudy(scenario, cases=list(config.cases), time_shift="auto")
    write_casestudy(cs, edir / "casestudy", figures=config.figures)
    t = np.asarray(cs.t_s, dtype=np.float64)
    ttc = np.asarray(cs.ttc_s, dtype=np.float64)
    write_parquet(
        edir / "ttc.parquet",
        pd.DataFrame(
            {
                "config": np.repeat([c.name for c in cs.cases], t.size),
                "t_s": np.tile(t, len(cs.cases)),
                "ttc_s": ttc.reshape(-1),
            }
        ),
    )
    ident = {
        "encounter_id": enc.encounter_id,
        "recording": enc.recording,
        "rider_id": enc.rider_id,
        "category": enc.category,
        "rec_path_distance_m": enc.path_distance_m,
        "rec_pet_s": enc.pet_s,
        "rec_min_gap_m": enc.min_gap_m,
        "rec_crossing_angle_deg": enc.crossing_angle_deg,
        "rec_ego_speed_mps": enc.ego_speed_mps,
        "rec_rider_speed_mps": enc.rider_speed_mps,
        "time_shift_auto_s": float(cs.time_shift_s),
        "miss_distance_m": _float(cs.time_shift.get("miss_distance_m")),
        # how the encounter was imported and reconstructed (one answer per setting)
        "import_road_users": config.road_users,
        "recon_interp": config.recon_config().interp,
        # 'recorded behaviour' where the recorded paths meet, else 'continuations' (the
        # risk is continuation-driven: vei.risk.window)
        "risk_basis": str(cs.time_shift.get("risk_basis", "")),
    }
    summary = cs.summary.rename(columns={"name": "config"}).copy()
    summary.insert(0, "kind", "casestudy")
    summary["time_shift_applied_s"] = float(cs.time_shift_s)
    case_by_name = {c.name: c for c in cs.cases}
    summary["p.rider_model"] = [
        str(getattr(case_by_name[n], "rider", "")) for n in summary["config"]
    ]
    summary["p.ego_mode"] = [
        str(getattr(case_by_name[n], "ego_mode", "")) for n in summary["config"]
    ]
    parts = [summary]
    spec = config.sweep_spec()
    if spec is not None:
        res = run_sweep(scen_dir, spec, edir / "sweep", engine="local", workers=1, progress=False)
        sweep = pd.read_parquet(res.results)
        sweep = sweep.drop(columns=["scenario_id", "seed"], errors="ignore")
        sweep = sweep.rename(columns={n: f"p.{n}" for n in spec.names})
        sweep = sweep.rename(columns={"variant_id": "config"})
        sweep.insert(0, "kind", "sweep")
        parts.append(sweep)
    rows = pd.concat(parts, ignore_index=True)
    ident.update(_encounter_risk(scen_dir, edir, config))  # issue 23: per-encounter risk
    clash = sorted(set(ident) & set(rows.columns))
    if clash:
        raise RuntimeError(f"identifier columns clash with metric columns: {clash}")
    for k, v in reversed(list(ident.items())):
        rows.insert(0, k, v)
    rows = _clean_object_columns(rows)
    write_parquet(edir / "rows.parquet", rows)
    return len(rows)


def _encounter_risk(scen_dir: Path, edir: Path, config: CatalogueConfig) -> dict[str, Any]:
    """The encounter's risk estimate (``vei risk`` into ``edir/risk``) as identifier
    columns of its rows (vei.risk.output.encounter_columns); {} without one."""
    settings = config.risk_settings()
    if settings is None:
        return {}
    from vei.risk.output import encounter_columns
    from vei.risk.run import assess_risk

    model, opts = settings
    result = assess_risk(
        scen_dir, model, policies=tuple(opts["policies"]), method=opts["method"],
        budget=opts["budget"], target_rel_ci=opts["target_rel_ci"], sobol_n=0,
        out_dir=edir / "risk", configs="failures",
    )  # fmt: skip
    return encounter_columns(result)
