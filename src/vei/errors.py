"""Exceptions raised by vei. Every user-facing error names where and what was expected.

The CLI turns any :class:`VeiError` into a one-paragraph message and exit code 2, without
a traceback; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

from pathlib import Path


class VeiError(Exception):
    """Base class of every error that is the user's input or environment, not a bug."""


class InputError(VeiError):
    """Bad input data: names the file, row and field, and what was expected.

    Args:
        message: what is wrong and what was expected.
        path: the offending file (or folder), if any.
        row: 1-based data row (header excluded) or record index, if any.
        field: column / key name, if any.
    """

    def __init__(
        self,
        message: str,
        *,
        path: str | Path | None = None,
        row: int | None = None,
        field: str | None = None,
    ) -> None:
        self.path = None if path is None else Path(path)
        self.row = row
        self.field = field
        self.detail = message
        where = []
        if self.path is not None:
            where.append(str(self.path))
        if row is not None:
            where.append(f"row {row}")
        if field is not None:
            where.append(f"field '{field}'")
        prefix = ", ".join(where)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class NoRidersError(InputError):
    """A recording holds no e-scooter or cyclist: nothing to simulate. An importer refuses
    it; a catalogue lists it as 'no-riders', not as a failed recording."""


class ConfigError(VeiError):
    """An invalid configuration value or an unknown key in a configuration file."""


class DependencyError(VeiError):
    """An optional dependency (extra) or external tool is missing."""


class BackendError(VeiError):
    """A simulation backend could not be reached or failed (e.g. no CARLA server)."""


class PolicyError(VeiError):
    """A user's ego policy raised an exception while the engine called it (its bind,
    init_state or act): names the policy, the step and time, the exception and the last
    frames of the policy's own file."""
