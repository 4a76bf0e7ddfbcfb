"""Which varied quantity drives the risk most: Sobol indices (SALib) and, for rare
events, importance factors.

- **Sobol indices** (Sobol 2001; Saltelli 2002 / 2010 estimators, implemented by SALib,
  ``SALib.sample.sobol`` + ``SALib.analyze.sobol``): the first-order index S1 of a
  quantity is the share of the output's variance it explains alone, the total index ST
  the share it takes part in (with interactions). The sample is Saltelli's scheme of
  N (d + 2) points in standard normal space (each dimension N(0, 1), the same space the
  estimators use), simulated in one engine batch per planner. Two outputs: the collision
  indicator (whose variance is P (1 - P): noise when collisions are rare, said so) and
  the minimum gap [m] (continuous: which quantity brings rider and car close).
  Bootstrap 95 % intervals from SALib.
- **Importance factors** (cross-entropy runs only): the share of the squared distance of
  the final proposal's mean from the origin per dimension, alpha_j^2 = mu_j^2 / |mu|^2
  (the FORM importance factors, read at the cross-entropy design point): which
  quantities must move, and how far, for a collision to happen.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from vei.errors import DependencyError

#: Default base sample size N of the Saltelli scheme.
SOBOL_N = 256
#: Fewest collisions in the Sobol sample for the collision indices to mean something.
MIN_SOBOL_FAILURES = 20


def _salib() -> Any:
    try:
        from SALib.analyze import sobol as analyze
        from SALib.sample import sobol as sample
    except ImportError as exc:  # pragma: no cover - installed with the risk extra
        raise DependencyError("Sobol indices need SALib: pip install 'vei[risk]'") from exc
    return sample, analyze


def sobol_indices(problem: Any, policy: str, *, n: int = SOBOL_N, seed: int = 0) -> dict[str, Any]:
    """First-order and total Sobol indices of the collision indicator and the minimum gap.

    Args:
        problem: a RiskProblem (``evaluate``, ``space``). policy: the planner.
        n: Saltelli base sample size (a power of 2; N (d + 2) simulations).
        seed: SALib's scrambling seed.
    Returns:
        {'n_simulations', 'names', 'collision': {name: {S1, S1_conf, ST, ST_conf}},
        'min_gap_m': {...}, 'notes': [...]}.
    """
    sample, analyze = _salib()
    names = list(problem.space.names)
    d = len(names)
    spec = {
        "num_vars": d,
        "names": names,
        "bounds": [[0.0, 1.0]] * d,
        "dists": ["norm"] * d,
    }
    u = sample.sample(spec, n, calc_second_order=False, seed=seed)
    rows = problem.evaluate(u, policy, stage="sobol")
    notes: list[str] = []
    out: dict[str, Any] = {"n_simulations": len(u), "names": names, "notes": notes}
    fail = rows["failure"].to_numpy(np.float64)
    gap = rows["min_gap_m"].to_numpy(np.float64) if "min_gap_m" in rows else None
    for key, y in (("collision", fail), ("min_gap_m", gap)):
        if y is None:
            continue
        y = np.where(np.isfinite(y), y, np.nanmax(np.where(np.isfinite(y), y, 0.0)))
        if np.ptp(y) == 0:
            notes.append(f"{key}: constant over the Sobol sample, no indices")
            continue
        res = _analyze(analyze, spec, y, seed, key, notes)
        out[key] = {
            nm: {
                "S1": _c(res["S1"][j]),
                "S1_conf": _c(res["S1_conf"][j]),
                "ST": _c(res["ST"][j]),
                "ST_conf": _c(res["ST_conf"][j]),
            }
            for j, nm in enumerate(names)
        }
    k = int(fail.sum())
    if k < MIN_SOBOL_FAILURES:
        notes.append(
            f"only {k} collisions in the {len(u):,} Sobol samples: the collision indices are "
            "noise; read the minimum gap's (and the importance factors)"
        )
    return out


def _analyze(
    analyze: Any, spec: dict[str, Any], y: np.ndarray, seed: int, key: str, notes: list[str]
) -> Any:
    """SALib's analysis with its warnings caught and said in vei's words (a note)."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = analyze.analyze(spec, y, calc_second_order=False, seed=seed)
    said = set()
    for w in caught:
        text = str(w.message)
        if "Constant values" in text:
            msg = (
                f"{key}: some Saltelli blocks hold one value only (too few samples reach a "
                "change of the outcome): their indices are unreliable"
            )
        else:
            msg = f"{key}: SALib warned: {text.splitlines()[0] if text else type(w).__name__}"
        if msg not in said:
            said.add(msg)
            notes.append(msg)
    return res


def few_failures_note(sobol: dict[str, Any]) -> str | None:
    """The note that the collision indices rest on too few collisions, or None."""
    for n in sobol.get("notes", []):
        if "collision indices are noise" in n:
            return n
    return None


def _c(v: float) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def importance_factors(names: Sequence[str], mean: Sequence[float]) -> dict[str, float]:
    """alpha_j^2 = mu_j^2 / |mu|^2 of a cross-entropy proposal mean (module docstring)."""
    mu = np.asarray(mean, dtype=np.float64)
    tot = float(np.sum(mu * mu))
    if tot <= 0:
        return {}
    return {n: float(m * m / tot) for n, m in zip(names, mu, strict=True)}


def driver(sobol: dict[str, Any]) -> str | None:
    """The quantity with the largest total index (collision if meaningful, else gap)."""
    for key in ("collision", "min_gap_m"):
        table = sobol.get(key)
        if key == "collision" and any("collision indices are noise" in n for n in sobol["notes"]):
            continue
        if table:
            return max(table, key=lambda n: table[n]["ST"] or 0.0)
    return None
