"""Critical-boundary search of a scenario: where, in a plane of two sweep parameters,
collisions begin.

The algorithm (adaptive quadtree refinement on a lattice, marching squares) is
:func:`vei.sweep.lattice.adaptive_boundary`; :func:`search_boundary` runs it against the
simulation (the two axes are sweep parameters, everything else fixed by a sweep spec) and
writes what it found.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from vei.errors import ConfigError
from vei.sweep.lattice import (
    BoundaryResult,
    Oracle,
    adaptive_boundary,
    binned_risk,
    boundary_neighbours,
    lattice_heatmap,
    lattice_segments,
    share_boundary,
)

if TYPE_CHECKING:
    from vei.sweep.spec import SweepSpec

__all__ = [
    "BoundaryResult", "Oracle", "adaptive_boundary", "binned_risk", "boundary_neighbours",
    "lattice_heatmap", "lattice_segments", "search_boundary", "share_boundary",
]  # fmt: skip


def search_boundary(
    scenario_dir: str | Path,
    spec: SweepSpec,
    x: str,
    y: str,
    out_dir: str | Path,
    *,
    x_range: tuple[float, float] | None = None,
    y_range: tuple[float, float] | None = None,
    coarse: tuple[int, int] = (9, 9),
    levels: int = 4,
    k_critical: int = 20,
    evaluator: Any = None,
    progress: bool | None = None,
) -> BoundaryResult:
    """Critical-boundary search of one scenario in the plane of parameters ``x`` and ``y``.

    The two axes are sweep parameters (float); their box is ``x_range`` / ``y_range`` or
    their ``min``/``max`` in ``spec``. Every other spec parameter must be fixed (it sets the
    plane); parameters the spec does not name keep the base configuration's values. Each
    refinement level is one engine batch.

    Writes into ``out_dir``: samples.parquet (every evaluated variant: variant columns, i, j,
    level, metrics), boundary.json (axes, box, counts, segments, crossings), boundary.csv
    (crossing points), riskmap.png (safety-index heatmap, samples, boundary), critical.csv /
    critical.json (the ``k_critical`` boundary-adjacent variants, most critical first) and
    configs/<variant_id>.yaml, each runnable with ``vei run SCENARIO --config FILE``.

    Returns:
        the :class:`BoundaryResult` (samples carry the variant columns and every metric).

    Raises:
        ConfigError: an axis is not a float parameter, has no range, or another parameter
            varies.
    """

    from vei.io.atomic import write_json, write_parquet, write_text
    from vei.report.riskmap import write_risk_map
    from vei.sweep.evaluator import EngineEvaluator
    from vei.sweep.io import json_records, most_critical, write_variant_configs
    from vei.sweep.spec import PARAMETERS, check_name, variant_id, variant_seed

    for axis in (x, y):
        check_name(axis, "boundary axis")  # an old spelling: say the new one
        if axis not in PARAMETERS or PARAMETERS[axis].kind != "float":
            floats = [n for n, p in PARAMETERS.items() if p.kind == "float"]
            raise ConfigError(
                f"boundary axis {axis!r} must be a float parameter: {', '.join(floats)}"
            )
    if x == y:
        raise ConfigError(f"boundary axes must differ, got {x!r} twice")

    def box(axis: str, given: tuple[float, float] | None) -> tuple[float, float]:
        if given is not None:
            lo, hi = (PARAMETERS[axis].check(v, "boundary range") for v in given)
            return float(lo), float(hi)
        if axis in spec.names and spec.param(axis).is_range:
            p = spec.param(axis)
            return float(p.min), float(p.max)  # type: ignore[arg-type]
        raise ConfigError(
            f"boundary axis {axis!r} needs a range: give it min/max in the spec or a range option"
        )

    xr, yr = box(x, x_range), box(y, y_range)
    varying = [p.name for p in spec.parameters if p.name not in (x, y) and not p.is_fixed]
    if varying:
        raise ConfigError(
            f"boundary search holds every other parameter fixed; these vary in the spec: {', '.join(varying)}"
        )
    fixed = {p.name: p.value for p in spec.parameters if p.name not in (x, y)}
    if evaluator is None:
        from vei.sweep.params import CRUISE_PARAM, reach_sim, reach_speed_of

        # continuations reach beyond the car at the largest cruise speed searched
        speed = reach_speed_of(spec)
        for axis, rng in ((x, xr), (y, yr)):
            if axis == CRUISE_PARAM:
                speed = float(max(rng))
        evaluator = EngineEvaluator(
            time_shift_reference=spec.time_shift_reference,
            base=spec.base,
            perception=spec.perception,
            v2x=spec.v2x,
            sim=reach_sim(speed),
        )
    prepared = evaluator.prepare(Path(scenario_dir))
    sid = evaluator.scenario_id(prepared)
    counter = [0]

    def oracle(points: np.ndarray) -> dict[str, Any]:
        recs = [{**fixed, x: float(px), y: float(py)} for px, py in points]
        ids = [variant_id(sid, r) for r in recs]
        table = pd.DataFrame(
            {
                "variant_id": ids,
                "scenario_id": sid,
                "variant_index": np.arange(counter[0], counter[0] + len(recs), dtype=np.int64),
                "seed": np.array([variant_seed(v, spec.seed) for v in ids], dtype=np.int64),
            }
        )
        counter[0] += len(recs)
        params = pd.DataFrame(recs)
        order = [n for n in PARAMETERS if n in params.columns]
        table = pd.concat([table, params[order]], axis=1)
        metrics = evaluator.evaluate(prepared, table)
        out = {c: metrics[c].to_numpy() for c in metrics.columns}
        out["collision"] = metrics["collision"].to_numpy(bool)
        for c in table.columns:
            if c not in out:
                out[c] = table[c].to_numpy()
        return out

    cb = None
    if progress is not False:  # None: a line per level, on a terminal or in a log
        from vei.io.progress import note

        def cb(level: int, n: int) -> None:
            note(f"boundary search: level {level}/{levels}, {n} variants evaluated")

    res = adaptive_boundary(
        oracle, xr, yr, coarse=coarse, levels=levels, x_name=x, y_name=y, progress=cb
    )
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    lead = ["variant_id", "scenario_id", "variant_index", "seed"]
    params = [n for n in PARAMETERS if n in res.samples.columns]
    rest = [c for c in res.samples.columns if c not in (*lead, *params, "x", "y")]
    table = res.samples[lead + params + rest]
    write_parquet(out / "samples.parquet", table)
    write_json(
        out / "boundary.json",
        {
            "scenario_id": sid,
            "x": x,
            "y": y,
            "x_range": list(xr),
            "y_range": list(yr),
            "coarse": list(coarse),
            "levels": levels,
            "fixed": fixed,
            "n_evaluations": res.n_evaluations,
            "grid_evaluations": res.grid_evaluations,
            "n_collisions": int(res.samples["collision"].sum()),
            "segments": res.segments.tolist(),
            "crossings": res.crossings.tolist(),
        },
    )
    write_text(
        out / "boundary.csv",
        pd.DataFrame(res.crossings, columns=[x, y]).to_csv(index=False),
    )
    heat = lattice_heatmap(res, "safety_index") if "safety_index" in res.samples else None
    if heat is not None:
        write_risk_map(
            out / "riskmap.png",
            x_centres=heat["x_centres"],
            y_centres=heat["y_centres"],
            value=heat["value"],
            segments=res.segments,
            sample_x=res.samples["x"].to_numpy(),
            sample_y=res.samples["y"].to_numpy(),
            sample_collided=res.samples["collision"].to_numpy(),
            x_label=x,
            y_label=y,
            title=f"{sid}: safety index and collision boundary\n({res.n_evaluations} variants "
            f"evaluated; a grid of the same resolution: {res.grid_evaluations})",
        )
    crit = most_critical(boundary_neighbours(res)[table.columns], k_critical)
    write_text(out / "critical.csv", crit.to_csv(index=False))
    write_json(out / "critical.json", json_records(crit))
    write_variant_configs(
        out / "configs",
        crit,
        spec,
        evaluator.auto_shift_s(prepared),
        evaluator.sim.continuation.ego_speed_mps,
    )
    return res
