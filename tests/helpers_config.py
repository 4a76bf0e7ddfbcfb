"""Walk the run configuration's dataclasses by a dotted path (shared by the tests of the
settings' declarations and of the sweep's parameter names)."""

from __future__ import annotations

import dataclasses
import typing

from vei.config import CaseConfig


def case_field(path: str) -> tuple[type, typing.Any]:
    """(dataclass, type hint) of the field at ``path`` (e.g. 'cap.t_safe_s') under
    CaseConfig; AssertionError naming the missing part or a part that is no section."""
    cls: typing.Any = CaseConfig
    parts = path.split(".")
    for i, part in enumerate(parts):
        names = {f.name for f in dataclasses.fields(cls)}
        assert part in names, f"{path}: {cls.__name__} has no field {part!r}"
        hint = typing.get_type_hints(cls)[part]
        if i == len(parts) - 1:
            return cls, hint
        cls = hint
        assert dataclasses.is_dataclass(cls), f"{path}: {part} is not a section"
    raise AssertionError(path)
