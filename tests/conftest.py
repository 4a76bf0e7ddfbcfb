"""Shared fixtures: where the real public data lives (VEI_DATA_DIR), temp folders."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]


def _data_dir() -> Path | None:
    env = os.environ.get("VEI_DATA_DIR")
    if env:
        return Path(env)
    default = REPO_ROOT.parent / "shared" / "data"
    return default if default.exists() else None


def require_data(*parts: str) -> Path:
    """Path to a file/folder under the data dir; skip (or fail under VEI_REQUIRE_DATA=1) if absent."""
    base = _data_dir()
    path = None if base is None else base.joinpath(*parts)
    if path is None or not path.exists():
        msg = f"real data not found: {path or 'VEI_DATA_DIR unset and ../shared/data absent'}"
        if os.environ.get("VEI_REQUIRE_DATA") == "1":
            pytest.fail(msg)
        pytest.skip(msg)
    return path


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """Root of the shared real data (../shared/data or $VEI_DATA_DIR)."""
    return require_data()


@pytest.fixture(scope="session")
def trafficmonitoring_root() -> Path:
    """The trafficmonitoring dataset root (the folder holding data/measurements)."""
    return require_data("trafficmonitoring")


def _esmini_dir() -> Path:
    env = os.environ.get("VEI_ESMINI")
    return Path(env) if env else REPO_ROOT.parent / "shared" / "tools" / "esmini"


def require_esmini():
    """The esmini installation ($VEI_ESMINI, default ../shared/tools/esmini) as a
    :class:`vei.esmini.Esmini`; skip without it (fail under VEI_REQUIRE_ESMINI=1)."""
    from vei.errors import DependencyError
    from vei.esmini import find_esmini

    try:
        found = find_esmini(_esmini_dir())
        found.require_player()
        found.require_dat2csv()
        found.require_library()
    except DependencyError as exc:
        msg = f"esmini not found: {exc}"
        if os.environ.get("VEI_REQUIRE_ESMINI") == "1":
            pytest.fail(msg)
        pytest.skip(msg)
    return found


@pytest.fixture(scope="session")
def esmini():
    """The esmini installation used by the tests (see :func:`require_esmini`)."""
    return require_esmini()
