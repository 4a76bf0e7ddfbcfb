"""Benchmark: the engine kernel's compile time per feature set, cold and warm (issue 33).

The compiled kernel is specialised per feature set (:class:`vei.sim.kernel.Features`: other
road users, extra riders, decisions, reacting cars, fused metrics); a run compiles only
the parts it uses. For each feature set below, a fresh process with an empty numba cache
(``NUMBA_CACHE_DIR`` a new folder: nothing compiled before, as on a fresh clone) runs one
variant of :func:`vei.sim.warmup.warmup_scene` (cold: numba compiles), then a second fresh
process with the same cache runs it again (warm: numba loads the machine code). Times are
of the kernel call alone (imports and the scene's preparation excluded), wall and CPU of
the process.

The demo's own run (``vei demo``: ego and one rider, no metrics in the kernel) uses
``base``; a sweep or ``vei risk`` of a recording with other road users
``others+metrics``; the catalogue's defaults add nothing else. ``all`` is the upper bound
(and what the previous, unspecialised kernel compiled for every run: 106 s cold on this
machine before issue 33, of which ~70 s were numba's parallel passes over the inlined
step; see :mod:`vei.sim.kernel.loop`).

``python -m benchmarks compile`` prints the table (``--sets base,metrics`` a subset).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile

#: Feature sets measured: name -> Features field values.
SETS: dict[str, dict[str, bool]] = {
    "base": {},
    "metrics": {"metrics": True},
    "others": {"others": True},
    "others+metrics": {"others": True, "metrics": True},
    "others+riders+metrics": {"others": True, "riders": True, "metrics": True},
    "others+decisions+metrics": {"others": True, "decisions": True, "metrics": True},
    "others+traffic+metrics": {"others": True, "traffic": True, "metrics": True},
    "others+metrics+policy": {"others": True, "metrics": True, "policy": True},  # issue 34
    "all": {
        f: True for f in ("others", "riders", "decisions", "traffic", "metrics", "policy", "user")
    },
}

_CHILD = """
import json, sys, time
from vei.metrics.config import MetricsConfig
from vei.metrics.fused_layout import config_vector
from vei.sim import kernel
from vei.sim.batch import batch_flags
from vei.sim.step import initial_state
from vei.sim.warmup import warmup_scene
f = kernel.Features(**json.loads(sys.argv[1]))
arrays, params, scored = warmup_scene(f)
fl = batch_flags(params, arrays.dt_s)
state = initial_state(arrays, params, fl)
cfg = config_vector(MetricsConfig()) if scored else None
used = kernel.features_of(arrays, params, scored)
assert used == f, (used, f)
t0, c0 = time.perf_counter(), time.process_time()
kernel.run(arrays, params, state, fl.hist_len, False, cfg)
print(json.dumps({"name": used.name, "wall_s": time.perf_counter() - t0,
                  "cpu_s": time.process_time() - c0}))
"""


def _once(fields: dict[str, bool], cache_dir: str) -> dict:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache_dir}
    out = subprocess.run(
        [sys.executable, "-c", _CHILD, json.dumps(fields)],
        env=env, capture_output=True, text=True, check=True,
    )  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def measure(name: str) -> dict:
    """Cold and warm times [s] of feature set ``name`` (each in a fresh process)."""
    with tempfile.TemporaryDirectory(prefix="vei-nb-") as cache_dir:
        cold = _once(SETS[name], cache_dir)
        warm = _once(SETS[name], cache_dir)
    return {"set": cold["name"], "cold": cold, "warm": warm}


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    names = list(SETS)
    if args and args[0].startswith("--sets"):
        names = (args[1] if args[0] == "--sets" else args[0].split("=", 1)[1]).split(",")
    print(f"{'feature set':<36} {'cold wall':>10} {'cold CPU':>10} {'warm wall':>10}")
    for name in names:
        r = measure(name)
        c, w = r["cold"], r["warm"]
        print(
            f"{r['set']:<36} {c['wall_s']:>9.1f}s {c['cpu_s']:>9.1f}s {w['wall_s']:>9.2f}s",
            flush=True,
        )


if __name__ == "__main__":
    main()
