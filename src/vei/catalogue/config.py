"""Settings of a catalogue run (frozen, validated; ConfigError on a bad value)."""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from vei.catalogue.encounters import EncounterRule
from vei.errors import ConfigError

#: The default per-encounter sweep: 240 Latin-hypercube variants around the automatic time
#: shift (+-2 s), over the ego's cruise speed, the rider model and the CAP (on/off, T_safe).
#: Small on purpose: the whole TrafficMonitoring catalogue runs in a few minutes on 2 cores.
DEFAULT_SWEEP: dict[str, Any] = {
    "design": "lhs",
    "n_samples": 240,
    "seed": 14,
    "base": "normal-cap",
    "time_shift_reference": "auto",
    "parameters": {
        "time_shift_s": {"min": -2.0, "max": 2.0},
        "ego.cruise_speed_mps": {"min": 3.0, "max": 9.0},
        "rider_model": {"choices": ["replay", "normal", "aggressive"]},
        "cap": {"enabled": {"choices": [True, False]}, "T_safe_s": {"min": 1.0, "max": 3.0}},
    },
}

#: The case study's configurations (the paper's five).
DEFAULT_CASES: tuple[str, ...] = ("replay", "normal", "aggressive", "normal-cap", "aggressive-cap")


@dataclass(frozen=True)
class CatalogueConfig:
    """What a catalogue computes per recording and per encounter.

    Attributes:
        rule: when a rider is an encounter (vei.catalogue.encounters.EncounterRule).
        sweep: the per-encounter sweep spec as a mapping (the YAML form of docs/sweeps.md);
            None = no sweep (case study only).
        cases: case-study configuration names.
        annotation_rate_hz: importer annotation rate [Hz] (the paper's 1 FPS).
        recon: reconstruction settings as a mapping (vei.recon.pipeline.ReconstructionConfig).
        map_source: None (no map) or a local OSM / SUMO net / xodr file given to
            ``vei.maps.attach.attach_map`` for every recording.
        max_encounters_per_recording: keep at most this many encounters per recording
            (the most critical by PET first); None = all.
        figures: write the case-study PNG/PDF figures per encounter.
    """

    rule: EncounterRule = field(default_factory=EncounterRule)
    sweep: dict[str, Any] | None = field(
        default_factory=lambda: json.loads(json.dumps(DEFAULT_SWEEP))
    )
    cases: tuple[str, ...] = DEFAULT_CASES
    annotation_rate_hz: float = 1.0
    recon: dict[str, Any] = field(default_factory=dict)
    map_source: str | None = None
    max_encounters_per_recording: int | None = None
    figures: bool = True

    def __post_init__(self) -> None:
        r = self.annotation_rate_hz
        if isinstance(r, bool) or not isinstance(r, int | float) or not math.isfinite(r) or r <= 0:
            raise ConfigError(f"annotation_rate_hz must be a number > 0, got {r!r}")
        m = self.max_encounters_per_recording
        if m is not None and (isinstance(m, bool) or not isinstance(m, int) or m < 1):
            raise ConfigError(f"max_encounters_per_recording must be an integer >= 1, got {m!r}")
        if not self.cases:
            raise ConfigError("cases: at least one configuration is needed")
        if self.map_source is not None and not Path(self.map_source).is_file():
            raise ConfigError(f"map source {self.map_source!r} is not a file")
        # Validate the nested settings now, so a typo fails before any work starts.
        self.sweep_spec()
        self.recon_config()
        from vei.experiments.casestudy import resolve_cases

        resolve_cases(list(self.cases))

    def sweep_spec(self):
        """The sweep as a vei.experiments.sweep_spec.SweepSpec (None without a sweep)."""
        if self.sweep is None:
            return None
        from vei.experiments.sweep_spec import spec_from_dict

        return spec_from_dict(self.sweep, source="catalogue sweep")

    def recon_config(self):
        """The reconstruction settings as a ReconstructionConfig."""
        from vei.recon.pipeline import ReconstructionConfig

        return ReconstructionConfig.from_dict(dict(self.recon))

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-ready mapping (what catalogue.json records)."""
        from dataclasses import asdict

        d = asdict(self)
        d["rule"]["categories"] = list(self.rule.categories)
        d["cases"] = list(self.cases)
        return d

    def digest(self) -> str:
        """16 hex digits identifying the settings (a resume with other settings is refused)."""
        text = json.dumps(self.as_dict(), sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def load_catalogue_config(path: str | Path | None, **overrides: Any) -> CatalogueConfig:
    """A CatalogueConfig from a YAML/JSON file (keys: rule, sweep, cases, annotation_rate_hz,
    recon, map_source, max_encounters_per_recording, figures; unknown keys are errors), with
    ``overrides`` (not None) applied on top. ``path`` None: the defaults."""
    raw: dict[str, Any] = {}
    if path is not None:
        import yaml

        from vei.errors import InputError

        p = Path(path)
        try:
            raw = yaml.safe_load(p.read_text(encoding="utf-8")) or {}
        except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
            raise InputError(f"cannot read the catalogue settings: {exc}", path=p) from None
        if not isinstance(raw, dict):
            raise InputError("expected a mapping at the top level", path=p)
    known = {
        "rule",
        "sweep",
        "cases",
        "annotation_rate_hz",
        "recon",
        "map_source",
        "max_encounters_per_recording",
        "figures",
    }
    unknown = sorted(set(raw) - known)
    if unknown:
        raise ConfigError(
            f"{path}: unknown catalogue setting {unknown[0]!r}; known: {', '.join(sorted(known))}"
        )
    raw.update({k: v for k, v in overrides.items() if v is not None})
    if "rule" in raw and isinstance(raw["rule"], dict):
        rule_raw = dict(raw["rule"])
        names = {"path_distance_max_m", "pet_max_s", "gap_max_m", "categories"}
        bad = sorted(set(rule_raw) - names)
        if bad:
            raise ConfigError(
                f"{path}: unknown rule setting {bad[0]!r}; known: {', '.join(sorted(names))}"
            )
        if "categories" in rule_raw:
            rule_raw["categories"] = tuple(rule_raw["categories"])
        raw["rule"] = EncounterRule(**rule_raw)
    if "cases" in raw:
        raw["cases"] = tuple(raw["cases"])
    if raw.get("map_source") is not None:
        raw["map_source"] = str(raw["map_source"])
    return CatalogueConfig(**raw)
