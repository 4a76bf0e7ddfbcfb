"""Settings of a catalogue run (frozen, validated; ConfigError on a bad value)."""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from vei.catalogue.encounters import EncounterRule
from vei.errors import ConfigError

#: The default per-encounter sweep: 240 Latin-hypercube variants around the automatic time
#: shift (+-2 s), over the ego's cruise speed, the rider model and the CAP (on/off, t_safe_s).
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
        "ego.policy": {"choices": ["paper-cap", "none"]},
        "cap.t_safe_s": {"min": 1.0, "max": 3.0},
    },
}

#: The default per-encounter risk estimate (issue 23, ``vei risk``): the default variation
#: (vei.risk.defaults), the base configuration's planner, P(collision) to +-20 % within
#: 20,000 simulations (Monte Carlo, or cross-entropy importance sampling when rare). Keys:
#: a risk spec's (base, time_shift_reference, seed, variation, fixed, perception,
#: injury_relevant_speed_mps; docs/risk.md) and budget, target_rel_ci, method, policies.
DEFAULT_RISK: dict[str, Any] = {"budget": 20_000, "target_rel_ci": 0.2, "method": "auto"}
RISK_RUN_KEYS: tuple[str, ...] = ("budget", "target_rel_ci", "method", "policies")

#: What a TrafficMonitoring import keeps (vei import trafficmonitoring --road-users).
ROAD_USERS: tuple[str, ...] = ("riders", "all")

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
        risk: the per-encounter risk estimate (``vei risk``: a risk spec's keys and
            budget, target_rel_ci, method, policies), None = none; encounters are then
            ranked by collision share instead of expected harm.
        road_users: which road users a TrafficMonitoring recording's import keeps:
            'riders' (e-scooters and cyclists) or 'all' (also vehicles and pedestrians),
            as ``vei import trafficmonitoring --road-users``; the reconstruction's
            interpolation is ``recon: {interp: ...}`` (``vei reconstruct --interp``).
            Both are recorded with every encounter (columns import_road_users,
            recon_interp).
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
    risk: dict[str, Any] | None = field(default_factory=lambda: dict(DEFAULT_RISK))
    road_users: str = "riders"

    def __post_init__(self) -> None:
        if self.road_users not in ROAD_USERS:
            raise ConfigError(f"road_users must be riders or all, got {self.road_users!r}")
        rule = self.rule
        if isinstance(rule, Mapping):
            object.__setattr__(self, "rule", rule_from_mapping(rule))
        elif not isinstance(rule, EncounterRule):
            raise ConfigError(f"rule must be a mapping of rule settings, got {rule!r}")
        if self.sweep is not None and not isinstance(self.sweep, Mapping):
            raise ConfigError(f"sweep must be a mapping (a sweep spec) or null, got {self.sweep!r}")
        if self.sweep is not None:
            object.__setattr__(self, "sweep", dict(self.sweep))
        if not isinstance(self.recon, Mapping):
            raise ConfigError(
                f"recon must be a mapping of reconstruction settings, got {self.recon!r}"
            )
        object.__setattr__(self, "recon", dict(self.recon))
        if not isinstance(self.figures, bool):
            raise ConfigError(f"figures must be true or false, got {self.figures!r}")
        cases = self.cases
        if isinstance(cases, str):  # a lone name is a one-element tuple, not its characters
            cases = (cases,)
        if not isinstance(cases, list | tuple) or not all(isinstance(c, str) for c in cases):
            raise ConfigError(f"cases must be a list of configuration names, got {cases!r}")
        object.__setattr__(self, "cases", tuple(cases))
        ms = self.map_source
        if ms is not None and not isinstance(ms, str | Path):
            raise ConfigError(f"map_source must be a file path or null, got {ms!r}")
        if isinstance(ms, Path):
            object.__setattr__(self, "map_source", str(ms))
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
        if self.risk is not None and not isinstance(self.risk, Mapping):
            raise ConfigError(f"risk must be a mapping (a risk spec) or null, got {self.risk!r}")
        if self.risk is not None:
            object.__setattr__(self, "risk", dict(self.risk))
        self.risk_settings()
        from vei.experiments.casestudy import resolve_cases

        resolve_cases(list(self.cases))

    def sweep_spec(self):
        """The sweep as a vei.sweep.spec.SweepSpec (None without a sweep)."""
        if self.sweep is None:
            return None
        from vei.sweep.spec import spec_from_dict

        return spec_from_dict(self.sweep, source="catalogue sweep")

    def risk_settings(self) -> tuple[Any, dict[str, Any]] | None:
        """(VariationModel, {budget, target_rel_ci, method, policies}) of the risk
        estimate, or None without one. Raises ConfigError on a bad value."""
        if self.risk is None:
            return None
        from vei.risk.assess import METHODS, check_budget
        from vei.risk.variation import parse_variation

        raw = dict(self.risk)
        run = {k: raw.pop(k) for k in RISK_RUN_KEYS if k in raw}
        model = parse_variation(raw, "catalogue risk")
        opts = {
            "budget": run.get("budget", DEFAULT_RISK["budget"]),
            "target_rel_ci": run.get("target_rel_ci", DEFAULT_RISK["target_rel_ci"]),
            "method": run.get("method", DEFAULT_RISK["method"]),
            "policies": run.get("policies") or [],
        }
        try:
            check_budget(opts["budget"], opts["target_rel_ci"])
        except ConfigError as exc:
            raise ConfigError(f"catalogue risk: {exc}".replace("--", "")) from None
        if opts["method"] not in METHODS:
            raise ConfigError(
                f"catalogue risk: method must be one of {', '.join(METHODS)}, got {opts['method']!r}"
            )
        pols = opts["policies"]
        if isinstance(pols, str):
            pols = [pols]
        if not isinstance(pols, list | tuple) or not all(isinstance(p, str) for p in pols):
            raise ConfigError(f"catalogue risk: policies must be a list of names, got {pols!r}")
        opts["policies"] = list(pols)
        return model, opts

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
    recon, map_source, max_encounters_per_recording, figures, risk, road_users; unknown keys are
    errors), with
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
        "risk",
        "road_users",
    }
    unknown = sorted(set(raw) - known)
    if unknown:
        raise ConfigError(
            f"{path}: unknown catalogue setting {unknown[0]!r}; known: {', '.join(sorted(known))}"
        )
    raw.update({k: v for k, v in overrides.items() if v is not None})
    try:
        return CatalogueConfig(**raw)
    except ConfigError as exc:
        if path is None:
            raise
        raise ConfigError(f"{path}: {exc}") from None


def rule_from_mapping(raw: Mapping[str, Any]) -> EncounterRule:
    """An EncounterRule from its settings mapping (keys: path_distance_max_m, pet_max_s,
    gap_max_m, categories; a lone category name is a one-element list; unknown keys and bad
    values are ConfigErrors)."""
    names = {"path_distance_max_m", "pet_max_s", "gap_max_m", "categories"}
    bad = sorted(set(raw) - names)
    if bad:
        raise ConfigError(f"unknown rule setting {bad[0]!r}; known: {', '.join(sorted(names))}")
    return EncounterRule(**dict(raw))
