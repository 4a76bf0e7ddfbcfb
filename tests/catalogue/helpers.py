"""A small real catalogue (two TrafficMonitoring recordings, a 24-variant sweep), built once
per test session and shared by tests/catalogue and tests/report."""

from __future__ import annotations

import atexit
import functools
import shutil
import tempfile
from pathlib import Path

#: Recordings of the small catalogue: three encounters in all (stadtmitte_12: cyclist_60,
#: cyclist_12; audi_08_klinikum_rechtsabbiegen_02: cyclist_2).
SMALL_RECORDINGS = ("audi_08_klinikum_rechtsabbiegen_02", "stadtmitte_12_audi_geradeaus_03")

SMALL_SWEEP = {
    "design": "lhs",
    "n_samples": 24,
    "seed": 3,
    "base": "normal-cap",
    "time_shift_reference": "auto",
    "parameters": {
        "time_shift_s": {"min": -2.0, "max": 2.0},
        "ego.cruise_speed_mps": {"min": 3.0, "max": 9.0},
        "rider_model": {"choices": ["replay", "normal"]},
    },
}


#: A small per-encounter risk estimate (issue 23): the default variation, 2,000 simulations.
SMALL_RISK = {"budget": 2000, "target_rel_ci": 0.3, "method": "mc"}


def small_config(**kw):
    """The CatalogueConfig of the small catalogue (figures off unless given)."""
    from vei.catalogue import CatalogueConfig

    kw.setdefault("figures", False)
    kw.setdefault("risk", SMALL_RISK)
    kw.setdefault("sweep", SMALL_SWEEP)
    return CatalogueConfig(**kw)


@functools.lru_cache(maxsize=1)
def build_small_catalogue(dataset: str) -> Path:
    """Run the small catalogue once (cached) and return its folder."""
    from vei.catalogue import run_catalogue

    out = Path(tempfile.mkdtemp(prefix="vei-small-catalogue-"))
    atexit.register(shutil.rmtree, out, True)
    result = run_catalogue(
        dataset, out, small_config(), recordings=list(SMALL_RECORDINGS), progress=False
    )
    assert result.complete, result.failed_encounters
    return out


def score_rows(eid: str, collision, flagged, safety_index=0.5, **columns):
    """Hand-built catalogue rows of one encounter for vei.catalogue.store.encounter_scores:
    the first row the case study, the rest sweep variants; min_gap_m 0 where a row
    collides, else 2 m; more columns by name (e.g. collision_recorded)."""
    import pandas as pd

    n = len(collision)
    return pd.DataFrame(
        {
            "encounter_id": eid,
            "recording": eid.split("__")[0],
            "rider_id": "r",
            "kind": ["casestudy"] + ["sweep"] * (n - 1),
            "config": [f"c{i}" for i in range(n)],
            "collision": collision,
            "safety_index": safety_index,
            "min_gap_m": [0.0 if c else 2.0 for c in collision],
            "min_ttc_s": 1.0,
            "seen_too_late": flagged,
            **columns,
        }
    )
