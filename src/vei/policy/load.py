"""Resolve a policy spec: a built-in name, ``package.module:Class`` or ``file.py:Class``.

    load_policy("aeb", {"ttc_full_s": 1.0})              # built-in, with parameters
    load_policy("mypkg.planners:Planner")                 # importable class
    load_policy("examples/my_policy.py:MyPolicy")          # class in a Python file

The class is instantiated with the parameters as keyword arguments; the instance must
implement :class:`vei.policy.base.Policy`. Every failure is a ConfigError naming the spec.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from vei.config import BUILTIN_POLICIES, KERNEL_POLICIES, validate_policy_spec
from vei.errors import ConfigError
from vei.policy.base import Policy, check_policy


def is_builtin(spec: str) -> bool:
    """True when ``spec`` names a built-in policy."""
    return spec in BUILTIN_POLICIES


validate_spec = validate_policy_spec


def _module_from_file(path: Path, spec: str) -> Any:
    if not path.is_file():
        raise ConfigError(f"policy {spec!r}: file {path} not found")
    digest = hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:12]
    name = f"vei_user_policy_{path.stem}_{digest}"
    if name in sys.modules:
        return sys.modules[name]
    mspec = importlib.util.spec_from_file_location(name, path)
    if mspec is None or mspec.loader is None:
        raise ConfigError(f"policy {spec!r}: cannot load {path} as a Python module")
    module = importlib.util.module_from_spec(mspec)
    sys.modules[name] = module  # pickling / dataclasses find the module
    try:
        mspec.loader.exec_module(module)
    except Exception as exc:  # noqa: BLE001 - a user's file: report, no traceback
        del sys.modules[name]
        raise ConfigError(
            f"policy {spec!r}: importing {path} failed: {type(exc).__name__}: {exc}"
        ) from None
    return module


def load_policy_class(spec: str) -> type:
    """The class a spec names (not instantiated)."""
    spec = validate_spec(spec)
    target, _, cls_name = BUILTIN_POLICIES.get(spec, spec).rpartition(":")
    if target.endswith(".py") or "/" in target or "\\" in target:
        module = _module_from_file(Path(target), spec)
    else:
        try:
            module = importlib.import_module(target)
        except Exception as exc:  # noqa: BLE001 - report any import failure with the spec
            raise ConfigError(
                f"policy {spec!r}: cannot import {target!r}: {type(exc).__name__}: {exc}"
            ) from None
    cls = getattr(module, cls_name, None)
    if cls is None:
        raise ConfigError(f"policy {spec!r}: {target} has no {cls_name!r}")
    if not isinstance(cls, type):
        raise ConfigError(f"policy {spec!r}: {cls_name!r} is not a class")
    return cls


def load_policy(spec: str, params: Mapping[str, Any] | None = None) -> Policy:
    """An instance of the policy ``spec`` built with ``params`` (keyword arguments).

    Args:
        spec: built-in name, 'package.module:Class' or 'file.py:Class'.
        params: constructor parameters (e.g. AEBConfig fields for 'aeb').
    Returns:
        The policy (checked against the interface).
    """
    cls = load_policy_class(spec)
    kwargs = dict(params or {})
    try:
        obj = cls(**kwargs)
    except ConfigError as exc:
        raise ConfigError(f"policy {spec!r}: {exc}") from None
    except TypeError as exc:
        raise ConfigError(f"policy {spec!r}: bad parameters {sorted(kwargs)}: {exc}") from None
    return check_policy(obj, spec)


__all__ = [
    "BUILTIN_POLICIES",
    "KERNEL_POLICIES",
    "is_builtin",
    "load_policy",
    "load_policy_class",
    "validate_spec",
]
