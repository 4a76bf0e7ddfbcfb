"""The old names of the modules moved in round 3 still import, for one release, with a
DeprecationWarning, and give the new modules' objects."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

from vei._moved import MOVED


@pytest.mark.parametrize("old", sorted(MOVED))
def test_old_name_warns_and_gives_the_new_objects(old):
    code = (
        "import importlib, warnings\n"
        "warnings.simplefilter('error', DeprecationWarning)\n"
        "import vei\n"
        f"try:\n    importlib.import_module({old!r})\n"
        "except DeprecationWarning as w:\n    print('warned:', w)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert f"warned: {old} has moved to {MOVED[old]}" in out.stdout, out.stdout + out.stderr
    with pytest.warns(DeprecationWarning):
        sys.modules.pop(old, None)
        alias = importlib.import_module(old)
    new = importlib.import_module(MOVED[old])
    public = [n for n in vars(new) if not n.startswith("__")]
    assert public and all(getattr(alias, n) is getattr(new, n) for n in public)


def test_from_import_of_an_old_name_works():
    with pytest.warns(DeprecationWarning):
        sys.modules.pop("vei.experiments.sweep", None)
        from vei.experiments.sweep import run_sweep
    from vei.sweep.run import run_sweep as new

    assert run_sweep is new


def test_an_unknown_old_looking_name_is_still_an_import_error():
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("vei.experiments.sweep_nothing")
