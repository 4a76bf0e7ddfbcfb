"""Run every ``benchmarks/bench_*.py`` module in its own process (so peak memory is its own).

Each module has a ``main()`` that prints its table. ``python -m benchmarks NAME ...`` runs
only the named ones (e.g. ``reconstruct``); arguments starting with ``--`` are passed on to
each module (``python -m benchmarks gym --features``).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv: list[str]) -> int:
    mods = sorted(p.stem for p in HERE.glob("bench_*.py"))
    flags = [a for a in argv if a.startswith("--")]
    argv = [a for a in argv if not a.startswith("--")]
    if argv:
        wanted = {a if a.startswith("bench_") else f"bench_{a}" for a in argv}
        unknown = wanted - set(mods)
        if unknown:
            print(f"unknown benchmark(s): {', '.join(sorted(unknown))}; have: {', '.join(mods)}")
            return 2
        mods = [m for m in mods if m in wanted]
    failed = []
    for mod in mods:
        print(f"\n=== {mod} ===", flush=True)
        rc = subprocess.call([sys.executable, "-m", f"benchmarks.{mod}", *flags], cwd=HERE.parent)
        if rc != 0:
            failed.append(mod)
    if failed:
        print(f"\nfailed: {', '.join(failed)}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
