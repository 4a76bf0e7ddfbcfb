"""One declaration per engine setting (vei.config.settings.SETTINGS): the run configuration,
the engine's per-variant parameters, the compiled kernel's rows, the sweep parameters and
the docs' table all agree with it.

The consistency checks are functions of (declarations, the other side), so that a test
feeds them a deliberately broken declaration list and sees each kind of mismatch caught.
"""

from __future__ import annotations

import ast
import dataclasses
import math
import typing
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from tests.helpers_config import case_field
from vei.config import MAX_RUN_UP_M, case_preset
from vei.config.settings import BY_FIELD, NUMERIC_CONVERTS, SETTINGS, Setting, check_section
from vei.errors import ConfigError
from vei.policy.aeb import AEB_PARAM_FIELDS, AEBConfig
from vei.policy.idm import IDM_PARAM_FIELDS, IDMConfig
from vei.sim.kernel import layout as kernel_layout
from vei.sim.params import VariantParams
from vei.sim.tables import TimeTable
from vei.sweep import params as sweep_params
from vei.sweep.params import PARAMETERS, SWEEP_FIELDS, parameter_table

ROOT = Path(__file__).resolve().parents[2]
POLICY_CONFIGS: dict[str, type] = {"aeb": AEBConfig, "idm": IDMConfig}
#: Unit suffixes of DESIGN.md's naming rule -> the unit they stand for.
SUFFIX_UNITS = {
    "_s": "s", "_m": "m", "_mps": "m/s", "_mps2": "m/s^2", "_n": "N", "_nspm": "N s/m",
    "_per_m": "1/m", "_kg": "kg",
}  # fmt: skip


def suffix_of(name: str) -> str:
    """The unit suffix a field name ends with ('' for none); a trailing '_ego' (the engine's
    name of an ego field whose plain name is the rider's) is not part of it."""
    name = name.removesuffix("_ego")
    found = [s for s in SUFFIX_UNITS if name.endswith(s)]
    return max(found, key=len) if found else ""


def resolve(setting: Setting) -> tuple[type, typing.Any]:
    """(class, type hint) of the run-configuration field at ``setting.path``."""
    assert setting.path is not None
    if setting.convert == "policy_param":
        cls: type = POLICY_CONFIGS[str(setting.policy)]
        return cls, typing.get_type_hints(cls)[str(setting.config_field)]
    return case_field(setting.path)


def declaration_problems(
    settings: tuple[Setting, ...], vp_fields: list[str], param_fields: tuple[str, ...]
) -> list[str]:
    """Every mismatch between the declarations and the other sides, as readable lines.

    Args:
        settings: the declarations. vp_fields: VariantParams' fields in order.
        param_fields: the kernel's rows (kernel_layout.PARAM_FIELDS).
    """
    bad: list[str] = []
    if [s.field for s in settings] != vp_fields:
        bad.append(f"VariantParams fields {vp_fields} != declared {[s.field for s in settings]}")
    kernel = tuple(s.field for s in settings if s.kernel)
    if kernel != param_fields:
        bad.append(f"kernel rows {param_fields} != declared kernel settings {kernel}")
    for s in settings:
        if s.path is None:
            continue
        try:
            cls, hint = resolve(s)
        except AssertionError as exc:
            bad.append(str(exc))
            continue
        args = set(typing.get_args(hint)) or {hint}
        if s.kind == "float" and s.convert in (*NUMERIC_CONVERTS, "policy_param"):
            if float not in args:
                bad.append(f"{s.path}: {cls.__name__}.{s.config_field} is {hint}, not a number")
            if suffix_of(str(s.config_field)) != suffix_of(s.field):
                bad.append(f"{s.path}: unit suffix differs from the engine's {s.field}")
            sfx = suffix_of(s.field)
            if sfx and SUFFIX_UNITS[sfx] != s.unit:
                bad.append(f"{s.path}: declared unit {s.unit!r}, the name says {sfx!r}")
        elif s.convert == "equals" and s.equals not in set().union(
            *(typing.get_args(a) or {a} for a in args)
        ):
            bad.append(f"{s.path}: {s.equals!r} is not a value of {hint}")
        elif s.kind == "bool" and s.convert == "identity" and hint is not bool:
            bad.append(f"{s.path}: {cls.__name__}.{s.config_field} is {hint}, not bool")
    return bad


def test_the_declarations_match_variant_params_the_config_and_the_kernel():
    vp = [f.name for f in dataclasses.fields(VariantParams)]
    assert declaration_problems(SETTINGS, vp, kernel_layout.PARAM_FIELDS) == []


def test_the_checks_catch_each_kind_of_mismatch():
    vp = [f.name for f in dataclasses.fields(VariantParams)]
    t = BY_FIELD["t_safe_s"]
    cases = {
        # a setting declared but missing in VariantParams (and a field not declared)
        "VariantParams fields": (SETTINGS, [f for f in vp if f != "t_safe_s"]),
        # its kernel flag off: the rows no longer cover it
        "kernel rows": (
            tuple(dataclasses.replace(s, kernel=False) if s is t else s for s in SETTINGS),
            vp,
        ),
        # a path that is no field, a wrong unit, a mislabelled suffix, a bad 'equals'
        "has no field 't_safe'": (
            tuple(dataclasses.replace(s, path="cap.t_safe") if s is t else s for s in SETTINGS),
            vp,
        ),
        "declared unit 'm'": (
            tuple(dataclasses.replace(s, unit="m") if s is t else s for s in SETTINGS),
            vp,
        ),
        "unit suffix differs": (
            tuple(dataclasses.replace(s, path="cap.d_buf_m") if s is t else s for s in SETTINGS),
            vp,
        ),
        "is not a value of": (
            tuple(
                dataclasses.replace(s, equals="papr") if s.field == "paper_vdes" else s
                for s in SETTINGS
            ),
            vp,
        ),
    }
    for expected, (settings, fields) in cases.items():
        problems = declaration_problems(settings, fields, kernel_layout.PARAM_FIELDS)
        assert any(expected in p for p in problems), (expected, problems)


def test_the_kernel_rows_are_the_declared_ones_and_numba_sees_ints():
    rows = {n: v for n, v in vars(kernel_layout).items() if n.startswith("P_")}
    assert all(type(v) is int for v in rows.values())
    assert sorted(rows.values()) == list(range(kernel_layout.N_PARAMS))  # one name per row
    assert {kernel_layout.PARAM_FIELDS[v] for v in rows.values()} == {
        s.field for s in SETTINGS if s.kernel
    }
    assert kernel_layout.P_TSAFE == kernel_layout.PARAM_FIELDS.index("t_safe_s")
    # every P_* name the compiled modules import exists in the layout
    used: set[str] = set()
    for path in (ROOT / "src/vei/sim/kernel").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module == "vei.sim.kernel.layout":
                used |= {a.name for a in node.names if a.name.startswith("P_")}
    assert used and used <= set(rows), used - set(rows)


def _scene() -> SimpleNamespace:
    """What VariantParams.from_case reads of a scenario: a rider recorded at 3 m/s."""
    track = TimeTable(0.0, 0.1, np.full((50, 1), 3.0), ("speed_mps",))
    return SimpleNamespace(
        scenario_id="x", ego_speed0_mps=4.0, ego_median_moving_speed_mps=5.6,
        conflict_s_m=40.0, rider_track=track,
    )  # fmt: skip


@pytest.fixture(scope="module")
def base_params() -> VariantParams:
    return VariantParams.from_case(case_preset("paper-normal-cap"), _scene(), 1)


def _probes(s: Setting) -> list[float]:
    """Values at and just beyond each declared bound (and inside); for the int ego_mode
    one step beyond and its lower bound (its upper, 3, needs a policy object)."""
    if s.kind == "int":
        return [float(s.lower) - 1, float(s.lower), float(s.upper) + 1]  # type: ignore[arg-type]
    out: list[float] = []
    for bound in (s.lower, s.upper):
        if bound is not None:
            out += [bound, bound - 1e-9, bound + 1e-9]
    return out


def _config_accepts(s: Setting, value: float) -> bool:
    """Does the run configuration accept ``value`` in the setting's field? (For an AEB
    threshold only a refusal of the value itself counts, not of the thresholds' order.)"""
    try:
        if s.convert == "policy_param":
            POLICY_CONFIGS[str(s.policy)](**{str(s.config_field): value})
        else:
            section = getattr(case_preset("paper-normal-cap"), str(s.section))
            dataclasses.replace(section, **{str(s.config_field): value})
    except ConfigError as exc:
        msg = str(exc)
        return not (f"{s.config_field} must be" in msg and s.bounds_text() in msg)
    return True


@pytest.mark.parametrize(
    "field",
    [s.field for s in SETTINGS if s.bounds_text() and s.kind in ("float", "int")],
)
def test_one_set_of_bounds_for_the_config_the_engine_and_the_sweep(field, base_params):
    s = BY_FIELD[field]
    name = s.path if s.path in PARAMETERS else None
    if name is not None:  # the sweep's bounds are the declaration's
        p = PARAMETERS[name]
        assert (p.lower, p.upper, p.lower_open, p.upper_open, p.unit) == (
            s.lower, s.upper, s.lower_open, s.upper_open, s.unit,
        )  # fmt: skip
    for v in _probes(s):
        ok = not s.outside(v)
        try:  # the engine's parameters
            base_params.with_values(**{field: v})
            engine_ok = True
        except ConfigError as exc:
            engine_ok = False
            assert f"VariantParams.{field} ({s.path}) must be {s.bounds_text()}" in str(exc)
        assert engine_ok == ok, (field, v)
        if name is not None:  # the sweep spec
            try:
                PARAMETERS[name].check(v, "spec")
                assert ok, (name, v)
            except ConfigError as exc:
                assert not ok and f"spec: {name} must be" in str(exc), (name, v)
        if s.convert in (*NUMERIC_CONVERTS, "policy_param") and s.section in ("sfm", "ego", "cap"):
            assert _config_accepts(s, v) == ok, (s.path, v)


def test_inf_only_where_none_means_no_limit(base_params):
    for s in SETTINGS:
        if s.kind != "float":
            continue
        try:
            base_params.with_values(**{s.field: math.inf})
            assert s.allows_inf, s.field
        except ConfigError:
            assert not s.allows_inf, s.field
    assert {s.field for s in SETTINGS if s.allows_inf} == {
        "max_speed_mps", "max_accel_mps2", "integral_window_s",
    }  # fmt: skip


def _changed(value: typing.Any, upper: float | None = None) -> typing.Any:
    """Another valid value of a configuration field (x 1.25, or x 0.8 where that passes the
    upper bound; 0 -> 0.25; None -> 4.0)."""
    if value is None:
        return 4.0
    if value and upper is not None and value * 1.25 > upper:
        return value * 0.8
    return value * 1.25 if value else 0.25


def test_from_case_reads_every_setting_from_its_path_with_its_conversion():
    # Each setting read straight from the configuration is changed at its path, one at a
    # time; the engine's value follows through the declared conversion.
    base = case_preset("paper-normal-cap")
    checked = 0
    for s in SETTINGS:
        if s.convert in ("derived", "policy_param", "median_moving") or s.section is None:
            continue
        section = getattr(base, str(s.section))
        old = getattr(section, str(s.config_field))
        if s.convert == "equals":
            new = s.equals
            want: typing.Any = True
        elif s.kind == "bool":
            new = want = not old
        else:
            new = _changed(old, s.upper)
            want = new * base.sfm.k_des_factor if s.convert == "times_k_des_factor" else new
        case = dataclasses.replace(
            base, **{str(s.section): dataclasses.replace(section, **{str(s.config_field): new})}
        )
        p = VariantParams.from_case(case, _scene(), 2)
        assert getattr(p, s.field).tolist() == [want, want], s.path
        before = getattr(VariantParams.from_case(base, _scene(), 1), s.field)[0]
        assert before != want, s.path  # the change is visible
        checked += 1
    assert checked >= 30
    # None = no limit
    p = VariantParams.from_case(base, _scene(), 1)
    assert p.max_speed_mps[0] == math.inf and p.integral_window_s[0] == 0.5
    # the engine's gain is the configuration's x k_des_factor (aggressive preset: x 2)
    agg = case_preset("paper-aggressive-cap")
    assert VariantParams.from_case(agg, _scene(), 1).k_des_nspm[0] == 200.0
    # derived from the scenario: the median moving speed; the run-up in [-250, 0]
    assert p.cruise_speed_mps[0] == 5.6 and -MAX_RUN_UP_M <= p.ego_start_s_m[0] <= 0.0


def test_policy_params_come_from_the_policy_they_belong_to():
    for pol, mapping in (("aeb", AEB_PARAM_FIELDS), ("idm", IDM_PARAM_FIELDS)):
        declared = {s.config_field: s.field for s in SETTINGS if s.policy == pol}
        assert declared == mapping
    values = {"ttc_warning_s": 3.0, "ttc_partial_s": 2.0, "ttc_full_s": 1.0,
              "partial_decel_mps2": 4.5, "full_decel_mps2": 9.0}  # fmt: skip
    base = case_preset("paper-normal-cap")
    case = dataclasses.replace(
        base,
        ego_mode="pid",
        ego=dataclasses.replace(base.ego, policy="aeb", policy_params=values),
    )
    p = VariantParams.from_case(case, _scene(), 1)
    for f, v in values.items():
        assert getattr(p, f"aeb_{f}")[0] == v
    idm = IDMConfig()  # not this variant's policy: its defaults
    assert p.idm_time_headway_s[0] == idm.time_headway_s and p.idm_delta[0] == idm.delta
    from vei.sim.params import POLICY_PARAM_DEFAULTS

    assert POLICY_PARAM_DEFAULTS["aeb_ttc_full_s"] == AEBConfig().ttc_full_s


def test_sweep_names_are_the_declared_paths():
    declared = [str(s.path) for s in SETTINGS if s.sweep]
    assert list(PARAMETERS) == ["time_shift_s", "rider_model", *declared]
    assert SWEEP_FIELDS == {str(s.path): s.field for s in SETTINGS if s.sweep and s.kind == "float"}
    assert sweep_params.RENAMED["cap.T_safe_s"] == "cap.t_safe_s"
    assert set(sweep_params.RENAMED.values()) <= set(declared)
    # a swept value goes through its setting's conversion (k_des x k_des_factor); the
    # sweep knows no other conversion of a number
    assert {s.convert for s in SETTINGS if s.sweep and s.kind == "float"} <= {
        "identity", "times_k_des_factor", "median_moving", "policy_param", "none_is_default",
    }  # fmt: skip
    from vei.sweep.evaluator import _K_DES_COLUMNS, _PARAM_FIELDS

    assert {s.path for s in SETTINGS if s.sweep and s.convert == "times_k_des_factor"} <= set(
        _K_DES_COLUMNS
    )
    assert {p: f for p, f in _PARAM_FIELDS.items() if p in PARAMETERS} == SWEEP_FIELDS


def test_config_checks_come_from_the_declarations():
    # check_section refuses what the declaration refuses, naming the field and value
    cap = case_preset("normal-cap").cap
    with pytest.raises(ConfigError, match=r"^t_safe_s must be >= 0, got -0\.5$"):
        dataclasses.replace(cap, t_safe_s=-0.5)
    with pytest.raises(ConfigError, match="a_min_mps2 must be < 0, got 0.0"):
        dataclasses.replace(cap, a_min_mps2=0.0)
    with pytest.raises(ConfigError, match="d_buf_m must be a number"):
        dataclasses.replace(cap, d_buf_m="3")
    with pytest.raises(ConfigError, match="use_vehicle_force must be true or false"):
        dataclasses.replace(case_preset("normal").sfm, use_vehicle_force=1)
    check_section(cap, "cap")  # the defaults pass


def test_the_docs_parameter_table_is_generated_from_the_declarations():
    text = (ROOT / "docs/sweeps.md").read_text()
    begin, end = sweep_params.TABLE_BEGIN, sweep_params.TABLE_END
    assert text.count(begin) == 1 and text.count(end) == 1
    table = text.split(begin, 1)[1].split(end, 1)[0].strip("\n") + "\n"
    assert table == parameter_table(), "docs/sweeps.md: regenerate the parameter table"
    assert "| `cap.t_safe_s` | s | >= 0 | `t_safe_s` | CAP time headway T_safe |" in table


def test_a_setting_declaration_is_validated():
    with pytest.raises(ConfigError, match="equals"):
        Setting("x", "cap.x", "bool", "doc", kind="bool", convert="equals")
    with pytest.raises(ConfigError, match="only a derived setting has no path"):
        Setting("x", None, "s", "doc")
    with pytest.raises(ConfigError, match="lower > upper"):
        Setting("x", "cap.x", "s", "doc", lower=1.0, upper=0.0)
    assert Setting("x", "cap.x", "m", "d", lower=-250.0, upper=0.0).bounds_text() == (
        "in [-250, 0]"
    )
    assert np.array_equal(
        BY_FIELD["a_min_mps2"].outside(np.array([-1.0, 0.0, np.nan])), [False, True, True]
    )
