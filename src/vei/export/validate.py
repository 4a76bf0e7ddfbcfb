"""Validate an OpenSCENARIO file against the official XSD of its declared version.

The schemas ship in ``vei/export/schemas/openscenario/<major.minor>/OpenSCENARIO.xsd``
(origin and license in that folder's README.md). Validation uses ``xmlschema`` on a
document parsed with defusedxml (no entity expansion, no network access).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from vei.errors import DependencyError, InputError

SCHEMA_DIR = Path(__file__).resolve().parent / "schemas" / "openscenario"


def schema_path(osc_version: str) -> Path:
    """Path of the shipped XSD for '1.0' | '1.1' | '1.2' | '1.3'."""
    path = SCHEMA_DIR / osc_version / "OpenSCENARIO.xsd"
    if not path.is_file():
        known = sorted(p.name for p in SCHEMA_DIR.iterdir() if p.is_dir())
        raise InputError(
            f"no OpenSCENARIO schema for version {osc_version!r}; shipped: {', '.join(known)}"
        )
    return path


@lru_cache(maxsize=8)
def _schema(osc_version: str):
    try:
        import xmlschema
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise DependencyError("XSD validation needs xmlschema: pip install 'vei[export]'") from exc
    return xmlschema.XMLSchema(str(schema_path(osc_version)))


def declared_version(path: str | Path) -> str:
    """'major.minor' from the file's FileHeader revMajor/revMinor."""
    from defusedxml import ElementTree as SafeET

    path = Path(path)
    try:
        root = SafeET.parse(path).getroot()
    except Exception as exc:
        raise InputError(f"not a readable XML file: {exc}", path=path) from exc
    header = root.find("FileHeader")
    if header is None or header.get("revMajor") is None or header.get("revMinor") is None:
        raise InputError("no FileHeader with revMajor/revMinor", path=path, field="FileHeader")
    return f"{int(header.get('revMajor'))}.{int(header.get('revMinor'))}"


def validate_openscenario(path: str | Path, osc_version: str | None = None) -> list[str]:
    """Schema errors of an OpenSCENARIO file ([] when valid).

    Args:
        path: the .xosc file.
        osc_version: the schema to use; None: the version the file declares.

    Returns:
        One message per violation (the xmlschema reason and the element's path).
    """
    from defusedxml import ElementTree as SafeET

    path = Path(path)
    version = osc_version or declared_version(path)
    tree = SafeET.parse(path)
    errors = []
    for err in _schema(version).iter_errors(tree):
        errors.append(f"{err.path}: {err.reason}")
    return errors
