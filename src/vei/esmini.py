"""Where esmini is: the reference open-source OpenSCENARIO player (github.com/esmini/esmini).

vei uses esmini in two ways: as a player of exported ``.xosc`` files (``bin/esmini`` and
``bin/dat2csv``, run headless) and as a co-simulation host (``libesminiLib.so`` through
ctypes, the ``esmini`` backend). esmini is not on PyPI; users install a release from
github.com/esmini/esmini/releases (the ``bin/`` + ``lib/`` layout of the release packages)
and point vei at its folder.

Lookup order for the folder: the ``root`` argument, ``$VEI_ESMINI``, then
``../shared/tools/esmini`` relative to the current directory (the project's test
default). The library is looked for in ``lib/`` then ``bin/`` (release packages put it
in ``bin/``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from vei.errors import DependencyError

#: Environment variable naming the esmini folder.
ENV_VAR = "VEI_ESMINI"
#: Default folder (relative to the current directory): the project's shared tools.
DEFAULT_ROOT = Path("../shared/tools/esmini")
_LIB_NAMES = ("libesminiLib.so", "libesminiLib.dylib", "esminiLib.dll")
_HELP = (
    "install esmini from https://github.com/esmini/esmini/releases and set "
    f"{ENV_VAR}=<its folder> (the one holding bin/esmini)"
)


@dataclass(frozen=True)
class Esmini:
    """Paths of one esmini installation.

    Attributes:
        root: the installation folder.
        player: ``bin/esmini`` (None if absent).
        dat2csv: ``bin/dat2csv`` (None if absent).
        library: the C library ``libesminiLib.so`` (None if absent).
    """

    root: Path
    player: Path | None
    dat2csv: Path | None
    library: Path | None

    def require_player(self) -> Path:
        """The player binary; DependencyError if this installation has none."""
        if self.player is None:
            raise DependencyError(f"no esmini player at {self.root / 'bin' / 'esmini'}: {_HELP}")
        return self.player

    def require_dat2csv(self) -> Path:
        """The dat2csv binary; DependencyError if this installation has none."""
        if self.dat2csv is None:
            raise DependencyError(f"no dat2csv at {self.root / 'bin' / 'dat2csv'}: {_HELP}")
        return self.dat2csv

    def require_library(self) -> Path:
        """The C library; DependencyError if this installation has none."""
        if self.library is None:
            raise DependencyError(
                f"no esmini library ({' / '.join(_LIB_NAMES)}) under {self.root}/lib or "
                f"{self.root}/bin: {_HELP}"
            )
        return self.library


def _exe(path: Path) -> Path | None:
    return path if path.is_file() and os.access(path, os.X_OK) else None


def find_esmini(root: str | Path | None = None) -> Esmini:
    """The esmini installation at ``root``, ``$VEI_ESMINI`` or the default folder.

    Args:
        root: the esmini folder (holding ``bin/``), or None for the lookup order above.

    Returns:
        The paths found (a missing binary is None; use the ``require_*`` methods).

    Raises:
        DependencyError: no such folder, naming where vei looked and how to install.
    """
    if root is not None:
        candidates = [Path(root)]
    elif os.environ.get(ENV_VAR):
        candidates = [Path(os.environ[ENV_VAR])]
    else:
        candidates = [DEFAULT_ROOT]
    folder = candidates[0].expanduser()
    if not folder.is_dir():
        raise DependencyError(f"esmini not found: {folder} is not a folder; {_HELP}")
    folder = folder.resolve()
    library = None
    for sub in ("lib", "bin"):
        for name in _LIB_NAMES:
            if (folder / sub / name).is_file():
                library = folder / sub / name
                break
        if library is not None:
            break
    return Esmini(
        root=folder,
        player=_exe(folder / "bin" / "esmini"),
        dat2csv=_exe(folder / "bin" / "dat2csv"),
        library=library,
    )


def esmini_available(root: str | Path | None = None) -> bool:
    """True where :func:`find_esmini` finds a folder with the player and the library."""
    try:
        found = find_esmini(root)
    except DependencyError:
        return False
    return found.player is not None and found.library is not None
