"""Fixtures of the catalogue tests."""

from __future__ import annotations

import pytest

from tests.catalogue.helpers import build_small_catalogue


@pytest.fixture(scope="session")
def small_catalogue(trafficmonitoring_root):
    """Folder of the small real catalogue (tests.catalogue.helpers)."""
    return build_small_catalogue(str(trafficmonitoring_root))
