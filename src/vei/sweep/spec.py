"""Sweep specification: which variant parameters to vary, how, and the table of variants.

A sweep spec is a YAML (or JSON) mapping loaded into frozen dataclasses at the edge::

    design: lhs            # grid | random | lhs
    n_samples: 1000        # random / lhs only (an error for grid: its size is the product)
    seed: 7                # design seed (random / lhs); also mixed into the per-variant seed
    base: normal-cap       # the configuration (vei.config.CASE_PRESETS) that parameters the
                           # spec does not name keep
    time_shift_reference: auto   # auto: time_shift_s is an offset to the scenario's automatic
                                 # shift (computed once per scenario under the base config);
                                 # zero: time_shift_s is the absolute shift
    parameters:
      time_shift_s: {min: -2.0, max: 2.0, num: 21}   # a range (num: grid points, grid only)
      rider_model: {choices: [normal, aggressive]}   # a finite set
      ego.cruise_speed_mps: {min: 3.0, max: 9.0, num: 13}
      ego.policy: paper-cap                          # a fixed value
      sfm:                                           # nested groups are the dotted names
        k_des_nspm: {min: 50.0, max: 200.0, num: 3}
    reconstruction: {samples: 200}   # optional: every design point runs on each of 200
                                     # posterior samples of the primary rider's trajectory
                                     # (vei.recon.samples, drawn with `seed`; column
                                     # reconstruction_sample = 0..199)
    rider: {profile: calibrated, sample: 50}   # optional: every design point runs with each
                                     # of 50 riders sampled from a rider profile's population
                                     # (vei calibrate riders; keys profile, sample, category,
                                     # seed (default: the spec's); columns rider_sample and
                                     # rider.<parameter>)
    perception: {enabled: true, fov_deg: 60.0, detection_probability: 0.7}
                                     # optional: the ego's sensor model for every variant
                                     # (the run config's case.perception keys)
    v2x: {enabled: true}             # optional: V2X for every variant (case.v2x keys)
    variation: {cap.t_safe_s: {dist: normal, mean: 2.0, std: 0.3, min: 0.5}}
                                     # optional (random / lhs): drawn as u -> F^-1(u)

A parameter's name is the path of its field in the run configuration (``cap.t_safe_s``,
``sfm.k_des_nspm``, ``ego.policy_params.ttc_full_s``; :mod:`vei.sweep.params`);
a name of an earlier version (``cap.T_safe_s``, ``sfm.k_des``, ...) is an error naming
the new one. Unknown keys are errors that name the key and the file; ``0`` never means
"default".
Parameters that a spec does not name keep the values of the ``base`` configuration (one of
``vei.config.CASE_PRESETS``, default ``normal-cap``: the calibrated rider; ``paper-normal-cap``
for the paper's). ``rider_model`` normal / aggressive picks the (calibrated) SFM_PRESETS of
those names.

:func:`variants_table` turns a spec into a pandas DataFrame, one row per variant, with a
stable ``variant_id`` (hash of the scenario id and the parameter values) and a per-variant
``seed`` derived from that id and the spec seed.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd

from vei.calibrate.population import (
    POPULATION_SET,
    RIDER_PARAM_COLUMNS,
    parse_population,
    with_population,
)
from vei.config import CASE_PRESETS, RiderPopulationConfig
from vei.config.distributions import Distribution
from vei.config.perception import PerceptionConfig
from vei.config.v2x import V2XConfig  # noqa: F401 - SweepSpec.v2x's type
from vei.errors import ConfigError, InputError
from vei.sweep.ids import (  # noqa: F401 - variant_id/_seed part of this API
    name_variants,
    variant_id,
    variant_ids,
    variant_seed,
    variant_seeds,
)
from vei.sweep.params import (  # noqa: F401 - part of this module's API
    CONFIG_FIELDS,
    PARAMETERS,
    POLICY_PARAM,
    POLICY_PARAMS,
    POLICY_PARAMS_PREFIX,
    RENAMED,
    REPLACED,
    RIDER_MODELS,
    ParamDef,
    SpecLike,
    check_aeb_rows,
    check_name,
    check_v2x_spec,
    parse_perception,
    parse_reconstruction,
    parse_v2x,
    parse_variation_section,
    resolve_policy,
    variant_config,
)

Design = Literal["grid", "random", "lhs"]
DESIGNS: tuple[str, ...] = ("grid", "random", "lhs")
TIME_SHIFT_REFERENCES: tuple[str, ...] = ("auto", "zero")


@dataclass(frozen=True)
class ParamSpec:
    """How one parameter is varied: a fixed value, a numeric range, or a finite set.

    Attributes:
        name: dotted parameter name (a key of :data:`PARAMETERS`).
        value: the fixed value (when neither a range nor choices).
        min, max: numeric range (floats only), min <= max.
        num: grid points over [min, max] (grid design only; >= 2, or 1 when min == max).
        choices: finite set of values (any kind); sampled uniformly by random / lhs.
    """

    name: str
    value: Any = None
    min: float | None = None
    max: float | None = None
    num: int | None = None
    choices: tuple[Any, ...] | None = None

    @property
    def is_fixed(self) -> bool:
        """True when the parameter takes one value."""
        return self.min is None and self.choices is None

    @property
    def is_range(self) -> bool:
        """True for a continuous range [min, max]."""
        return self.min is not None

    def grid_values(self) -> list[Any]:
        """The values this parameter takes in a grid design."""
        if self.is_fixed:
            return [self.value]
        if self.choices is not None:
            return list(self.choices)
        assert self.min is not None and self.max is not None and self.num is not None
        if self.num == 1:
            return [float(self.min)]
        return [float(v) for v in np.linspace(self.min, self.max, self.num)]


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep specification (see the module docstring for the YAML form).

    Attributes:
        design: 'grid', 'random' or 'lhs'.
        parameters: the varied / fixed parameters, in :data:`PARAMETERS` order.
        n_samples: number of variants (random / lhs); None for grid.
        seed: design seed (random / lhs sampling) and per-variant seed salt.
        time_shift_reference: 'auto' (time_shift_s offsets the scenario's automatic shift)
            or 'zero' (time_shift_s is absolute).
        base: configuration preset (``vei.config.CASE_PRESETS``) for what is not swept.
        reconstruction_samples: N posterior samples of the primary rider's trajectory that
            every design point runs on (None: the reconstruction's mean trajectory only).
        rider: a rider population: every design point runs with each of its N sampled
            riders (their SFM parameters in columns RIDER_PARAM_COLUMNS); None: the base
            configuration's rider. Cannot be combined with sweeping sfm.k_des_nspm /
            a_veh_n / b_veh_per_m / v0_mps / mass_kg (the population sets them).
        perception: the ego's sensor model for every variant (the run config's
            ``case.perception``); None: the base configuration's.
        v2x: V2X for every variant (the run config's ``case.v2x``); None: the base
            configuration's (off). Swept ``v2x.*`` parameters need it enabled.
        variation: (parameter, Distribution): random / lhs designs draw it as F^-1(u) of
            its design coordinate u in [0, 1) (vei.config.distributions; issue 23).
        source: file it was loaded from, if any (for messages).
    """

    design: Design
    parameters: tuple[ParamSpec, ...]
    n_samples: int | None = None
    seed: int = 0
    time_shift_reference: str = "auto"
    base: str = "normal-cap"
    reconstruction_samples: int | None = None
    rider: RiderPopulationConfig | None = None
    perception: PerceptionConfig | None = None
    v2x: V2XConfig | None = None
    source: str | None = field(default=None, compare=False)
    variation: tuple[tuple[str, Distribution], ...] = ()

    def _check_policy_params(self, where: str) -> None:
        """A swept ``ego.policy_params.<f>`` needs its policy among the ``ego.policy`` values
        (the base presets run none / paper-cap, which take no policy_params): else it would
        change nothing."""
        by_name = {p.name: p for p in self.parameters}
        pol = by_name.get(POLICY_PARAM)
        run = set() if pol is None else set(map(str, pol.choices or (pol.value,)))
        for name, (owner, _) in POLICY_PARAMS.items():
            if name in by_name and owner not in run:
                raise ConfigError(
                    f"{where}: parameters.{name} belongs to policy '{owner}', which no variant "
                    f"runs (ego.policy: {', '.join(sorted(run)) or 'not swept'}): add "
                    f"'{owner}' to ego.policy or remove the parameter"
                )

    def __post_init__(self) -> None:
        where = self.source or "sweep spec"
        if self.design not in DESIGNS:
            raise ConfigError(
                f"{where}: design must be one of {', '.join(DESIGNS)}, got {self.design!r}"
            )
        if self.time_shift_reference not in TIME_SHIFT_REFERENCES:
            raise ConfigError(
                f"{where}: time_shift_reference must be auto or zero, got {self.time_shift_reference!r}"
            )
        if self.base not in CASE_PRESETS:
            raise ConfigError(
                f"{where}: base must be one of {', '.join(CASE_PRESETS)}, got {self.base!r}"
            )
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError(f"{where}: seed must be an integer >= 0, got {self.seed!r}")
        self._check_policy_params(where)
        n_rec = self.reconstruction_samples
        if n_rec is not None and (
            isinstance(n_rec, bool) or not isinstance(n_rec, int) or n_rec < 1
        ):
            raise ConfigError(
                f"{where}: reconstruction.samples must be an integer >= 1, got {n_rec!r}"
            )
        if self.design == "grid":
            if self.n_samples is not None:
                raise ConfigError(
                    f"{where}: n_samples is not used by design 'grid' (its size is the product "
                    "of the parameters' num / choices): remove it"
                )
            for p in self.parameters:
                if p.is_range and p.num is None:
                    raise ConfigError(f"{where}: parameters.{p.name}: design 'grid' needs 'num'")
        else:
            if (
                isinstance(self.n_samples, bool)
                or not isinstance(self.n_samples, int)
                or self.n_samples < 1
            ):
                raise ConfigError(
                    f"{where}: design '{self.design}' needs n_samples, an integer >= 1, got {self.n_samples!r}"
                )
            for p in self.parameters:
                if p.num is not None:
                    raise ConfigError(
                        f"{where}: parameters.{p.name}: 'num' is only used by design 'grid'"
                    )
        names = [p.name for p in self.parameters]
        if len(set(names)) != len(names):
            raise ConfigError(f"{where}: a parameter is given twice: {names}")
        both = sorted(set(names) & {n for n, _ in self.variation})
        if self.variation and (self.design == "grid" or both):
            why = f"{', '.join(both)} in parameters too" if both else "needs random or lhs"
            raise ConfigError(f"{where}: variation (distributions): {why}")
        if self.perception is not None and not isinstance(self.perception, PerceptionConfig):
            raise ConfigError(f"{where}: perception must be a PerceptionConfig or None")
        check_v2x_spec(names, self.v2x, where)
        if self.rider is not None:
            if not isinstance(self.rider, RiderPopulationConfig):
                raise ConfigError(f"{where}: rider must be a mapping {{profile, sample}}")
            clash = sorted(set(names) & set(POPULATION_SET))
            if clash:
                raise ConfigError(
                    f"{where}: rider (a population) sets the rider's parameters; do not also "
                    f"sweep {', '.join(clash)}"
                )

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names, in table column order (the variation's after the others)."""
        return tuple(p.name for p in self.parameters) + tuple(n for n, _ in self.variation)

    def param(self, name: str) -> ParamSpec:
        """The ParamSpec of ``name`` (KeyError if the spec does not name it)."""
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        """The spec as a plain mapping (the YAML form, dotted names)."""
        params: dict[str, Any] = {}
        for p in self.parameters:
            if p.is_fixed:
                params[p.name] = p.value
            elif p.choices is not None:
                params[p.name] = {"choices": list(p.choices)}
            else:
                d: dict[str, Any] = {"min": p.min, "max": p.max}
                if p.num is not None:
                    d["num"] = p.num
                params[p.name] = d
        out: dict[str, Any] = {"design": self.design}
        if self.n_samples is not None:
            out["n_samples"] = self.n_samples
        out["seed"] = self.seed
        out["time_shift_reference"] = self.time_shift_reference
        out["base"] = self.base
        out["parameters"] = params
        if self.reconstruction_samples is not None:
            out["reconstruction"] = {"samples": self.reconstruction_samples}
        if self.rider is not None:
            out["rider"] = {
                "profile": self.rider.profile,
                "sample": self.rider.sample,
                "category": self.rider.category,
                "seed": self.rider.seed,
            }
        if self.perception is not None:
            out["perception"] = dataclasses.asdict(self.perception)
        if self.v2x is not None:
            out["v2x"] = dataclasses.asdict(self.v2x)
        if self.variation:
            out["variation"] = {n: d.to_dict() for n, d in self.variation}
        return out

    def digest(self) -> str:
        """A stable hash of the spec's content (sweep resume refuses a different spec)."""
        text = json.dumps(self.to_dict(), sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def n_variants(self) -> int:
        """Number of design points per scenario (before removing duplicates)."""
        per_sample = (self.reconstruction_samples or 1) * (self.rider.sample if self.rider else 1)
        if self.design == "grid":
            grid = int(np.prod([len(p.grid_values()) for p in self.parameters], dtype=np.int64))
            return grid * per_sample
        assert self.n_samples is not None
        return self.n_samples * per_sample


_SPEC_KEYS = {
    "design",
    "n_samples",
    "seed",
    "time_shift_reference",
    "base",
    "parameters",
    "reconstruction",
    "rider",
    "perception",
    "v2x",
    "variation",
}
#: Variants-table column of the reconstruction sample a variant runs on.
SAMPLE_COLUMN = "reconstruction_sample"
_PARAM_KEYS = {"min", "max", "num", "choices"}


def _flatten_params(raw: Any, where: str) -> dict[str, Any]:
    """``parameters`` -> {dotted name: value}: groups (``sfm: {k_des_nspm: ..}``,
    ``ego: {policy_params: {ttc_full_s: ..}}``) become dotted names; a mapping under a
    known parameter's name is its range / choices."""
    if not isinstance(raw, Mapping) or not raw:
        raise ConfigError(f"{where}: 'parameters' must be a non-empty mapping of parameter names")
    flat: dict[str, Any] = {}

    def walk(prefix: str, node: Mapping[Any, Any]) -> None:
        for key, val in node.items():
            name = f"{prefix}{key}"
            is_group = any(p.startswith(f"{name}.") for p in PARAMETERS) or any(
                p.startswith(f"{name}.") for p in (*RENAMED, *REPLACED)
            )
            if name not in PARAMETERS and is_group and isinstance(val, Mapping):
                if set(map(str, val)) & _PARAM_KEYS:  # a range given to a group: say so
                    raise ConfigError(
                        f"{where}: parameters.{name} is a group of parameters, not one"
                    )
                walk(f"{name}.", val)
            else:
                flat[name] = val

    walk("", raw)
    return flat


def _parse_param(name: str, raw: Any, where: str, base_dir: Path | None = None) -> ParamSpec:
    check_name(name, where)
    if name not in PARAMETERS:
        raise ConfigError(f"{where}: unknown parameter '{name}'; known: {', '.join(PARAMETERS)}")
    pdef = PARAMETERS[name]
    if name == POLICY_PARAM:  # a user policy's file: relative to the spec's folder
        if isinstance(raw, Mapping) and isinstance(raw.get("choices"), list):
            raw = {**raw, "choices": [resolve_policy(c, where, base_dir) for c in raw["choices"]]}
        elif not isinstance(raw, Mapping):
            raw = resolve_policy(raw, where, base_dir)
    loc = f"{where}: parameters.{name}"
    if not isinstance(raw, Mapping):
        return ParamSpec(name=name, value=pdef.check(raw, where))
    unknown = set(map(str, raw)) - _PARAM_KEYS
    if unknown:
        raise ConfigError(
            f"{loc}: unknown key(s) {', '.join(sorted(unknown))}; expected min/max[/num] or choices"
        )
    if "choices" in raw:
        if set(raw) != {"choices"}:
            raise ConfigError(f"{loc}: 'choices' cannot be combined with min/max/num")
        ch = raw["choices"]
        if not isinstance(ch, Sequence) or isinstance(ch, str) or len(ch) == 0:
            raise ConfigError(f"{loc}: 'choices' must be a non-empty list")
        vals = tuple(pdef.check(c, where) for c in ch)
        if len(set(vals)) != len(vals):
            raise ConfigError(f"{loc}: 'choices' has duplicates: {list(ch)}")
        return ParamSpec(name=name, choices=vals)
    if pdef.kind != "float":
        raise ConfigError(f"{loc}: a {pdef.kind} parameter takes a value or 'choices', not a range")
    if "min" not in raw or "max" not in raw:
        raise ConfigError(f"{loc}: a range needs both 'min' and 'max'")
    lo, hi = pdef.check(raw["min"], where), pdef.check(raw["max"], where)
    if lo > hi:
        raise ConfigError(f"{loc}: min ({lo:g}) > max ({hi:g})")
    num = raw.get("num")
    if num is not None:
        if isinstance(num, bool) or not isinstance(num, int) or num < 1:
            raise ConfigError(f"{loc}: 'num' must be an integer >= 1, got {num!r}")
        if num == 1 and lo != hi:
            raise ConfigError(f"{loc}: 'num' = 1 needs min == max (use a fixed value)")
        if num >= 2 and lo == hi:
            raise ConfigError(f"{loc}: min == max needs num = 1 (or a fixed value)")
    return ParamSpec(name=name, min=lo, max=hi, num=num)


def spec_from_dict(raw: Any, *, source: str | None = None) -> SweepSpec:
    """Build a validated :class:`SweepSpec` from a mapping (YAML/JSON content).

    Raises:
        ConfigError: unknown key (named, with the file), bad value or inconsistent design.
    """
    where = source or "sweep spec"
    if not isinstance(raw, Mapping):
        raise ConfigError(f"{where}: expected a mapping at the top level, got {type(raw).__name__}")
    unknown = set(map(str, raw)) - _SPEC_KEYS
    if unknown:
        raise ConfigError(
            f"{where}: unknown key(s) {', '.join(sorted(unknown))}; expected "
            f"{', '.join(sorted(_SPEC_KEYS))}"
        )
    for req in ("design", "parameters"):
        if req not in raw:
            raise ConfigError(f"{where}: missing required key '{req}'")
    flat = _flatten_params(raw["parameters"], where)
    base_dir = Path(source).parent if source and Path(source).is_file() else None
    parsed = {name: _parse_param(name, val, where, base_dir) for name, val in flat.items()}
    ordered = tuple(parsed[n] for n in PARAMETERS if n in parsed)
    return SweepSpec(
        design=raw["design"],
        parameters=ordered,
        n_samples=raw.get("n_samples"),
        seed=raw.get("seed", 0),
        time_shift_reference=raw.get("time_shift_reference", "auto"),
        base=raw.get("base", "normal-cap"),
        reconstruction_samples=parse_reconstruction(raw.get("reconstruction"), where),
        rider=parse_population(raw.get("rider"), where, raw.get("seed", 0)),
        perception=parse_perception(raw.get("perception"), where),
        v2x=parse_v2x(raw.get("v2x"), where),
        source=source,
        variation=parse_variation_section(raw.get("variation"), where),
    )


def load_spec(path: str | Path) -> SweepSpec:
    """Load a sweep spec from a YAML or JSON file.

    Raises:
        InputError: the file is missing or not valid YAML.
        ConfigError: its content is invalid (message names the file and the key).
    """
    import yaml

    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot read the sweep spec: {exc.strerror}", path=path) from exc
    try:
        raw = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise InputError(f"not valid YAML: {exc}", path=path) from exc
    return spec_from_dict(raw, source=str(path))


# --------------------------------------------------------------------------- variants


# variant_id / variant_seed (and their whole-table forms) live in sweep_ids (H2, issue 15:
# one implementation, vectorised for 10^6-variant sweeps); importable from here too.


def design_points(spec: SweepSpec) -> pd.DataFrame:
    """The design of ``spec``: one row per design point, one column per parameter.

    grid: the Cartesian product (last parameter varies fastest). random: independent
    uniform draws (ranges) / uniform choice (sets), ``numpy.random.default_rng(seed)``.
    lhs: ``scipy.stats.qmc.LatinHypercube(d, rng=seed)`` over the varied parameters; a set
    of k choices takes the stratum ``floor(u * k)``. Fixed parameters are constant columns.
    """
    names = list(spec.names)
    if spec.design == "grid":
        rows = list(itertools.product(*[p.grid_values() for p in spec.parameters]))
        return pd.DataFrame(rows, columns=names)
    n = int(spec.n_samples or 0)
    varied = [p for p in spec.parameters if not p.is_fixed]
    n_dims = len(varied) + len(spec.variation)
    if spec.design == "random":
        rng = np.random.default_rng(spec.seed)
        u = rng.random((n, n_dims))
    else:
        from scipy.stats import qmc

        u = qmc.LatinHypercube(d=n_dims, rng=spec.seed).random(n) if n_dims else np.zeros((n, 0))
    cols: dict[str, Any] = {}
    j = 0
    for p in spec.parameters:
        if p.is_fixed:
            cols[p.name] = [p.value] * n
            continue
        col = u[:, j]
        j += 1
        if p.choices is not None:
            idx = np.minimum((col * len(p.choices)).astype(np.int64), len(p.choices) - 1)
            cols[p.name] = [p.choices[i] for i in idx]
        else:
            assert p.min is not None and p.max is not None
            cols[p.name] = (p.min + col * (p.max - p.min)).astype(np.float64)
    for name, dist in spec.variation:  # issue 23: the design's u through the distribution
        cols[name] = dist.ppf(np.clip(u[:, j], 1e-12, 1.0 - 1e-12))
        j += 1
    return pd.DataFrame(cols, columns=names)


#: Leading columns of a variants table (then one column per parameter, PARAMETERS order).
VARIANT_COLUMNS: tuple[str, ...] = ("variant_id", "scenario_id", "variant_index", "seed")


def variants_table(spec: SweepSpec, scenario_id: str, *, named: bool = True) -> pd.DataFrame:
    """The variants of one scenario: one row per distinct design point.

    Columns: variant_id (str, :func:`variant_id`), scenario_id (str), variant_index (int,
    position in the design, the row order), seed (int, :func:`variant_seed`), then one
    column per spec parameter (float / bool / str). Design points whose parameters repeat
    an earlier row (possible when only sets are varied) are identical simulations with the
    same id and are kept once. With ``reconstruction_samples`` N, every design point is
    repeated for samples 0..N-1 (column SAMPLE_COLUMN, int, part of the variant id). With
    a rider population of N riders, every point is repeated for riders 0..N-1 (column
    RIDER_COLUMN, int, and the rider's parameters in RIDER_PARAM_COLUMNS, float; part of
    the variant id); the same N riders for every scenario (seeded).

    With ``named=False`` the rows are not named (no variant_id and seed columns) when no
    two design points are equal: a sweep's workers name their own chunks
    (:func:`vei.sweep.ids.name_variants`, the same ids and seeds; ~1 us per
    row saved up front). Points that repeat one another are named here and de-duplicated
    by id, so the result has variant_id exactly when ``named`` or such points exist.
    """
    pts = design_points(spec)
    if spec.reconstruction_samples is not None:
        n_rec = spec.reconstruction_samples
        pts = pts.loc[pts.index.repeat(n_rec)].reset_index(drop=True)
        pts[SAMPLE_COLUMN] = np.tile(np.arange(n_rec, dtype=np.int64), len(pts) // n_rec)
    if spec.rider is not None:
        pts = with_population(pts, spec.rider)
    df = pd.DataFrame(
        {"scenario_id": scenario_id, "variant_index": np.arange(len(pts), dtype=np.int64)}
    )
    df = pd.concat([df, pts.reset_index(drop=True)], axis=1)
    for p in (*spec.parameters, *(ParamSpec(n) for n, _ in spec.variation)):
        kind = PARAMETERS[p.name].kind
        if kind == "float":
            df[p.name] = df[p.name].astype(np.float64)
        elif kind == "bool":
            df[p.name] = df[p.name].astype(bool)
        else:
            df[p.name] = df[p.name].astype(str)
    # Equal values (pandas: -0.0 == 0.0, NaN == NaN) include every pair of equal ids
    # (ids encode the repr of each value), so without them every id is distinct.
    if named or len(pts.columns) == 0 or df.duplicated(list(pts.columns)).any():
        df = name_variants(df, spec.seed)  # = variant_id of each row (sweep_ids)
        df = df.drop_duplicates("variant_id", keep="first").reset_index(drop=True)
    check_aeb_rows(df, spec.base)  # what vei run refuses, a sweep refuses before it runs
    return df


def row_params(row: Mapping[str, Any], spec: SweepSpec) -> dict[str, Any]:
    """The parameter values of one variants-table row, as a {dotted name: value} dict
    (with the population rider's ``rider.*`` parameters where the spec has a population)."""
    out = {n: row[n] for n in spec.names}
    if spec.rider is not None:
        out.update({c: row[c] for c in RIDER_PARAM_COLUMNS if c in row})
    return out
