"""Secondary figures of a weighted (importance) sample, never ``nan``, and the share of
the risk that rests on recorded behaviour.

An importance sample concentrated on the collisions may hold no sample of a secondary
event (no injury-relevant collision, no run seen too late). Its weighted mean is then 0
with a zero standard error: no interval. The honest answers:

- an event that is part of the failure event (an injury-relevant collision, a collision
  on recorded behaviour): P(event) = P(failure) P(event | failure), and none of the
  n_eff effective failure samples (ESS of the failures' weights, Kong 1992) holding it
  bounds P(event | failure) by the Clopper-Pearson bound 1 - 0.025^(1 / n_eff); the
  upper bound is P(failure)'s upper limit times that (approximate: on the effective
  sample size);
- an event outside the failure event (seen too late): the Monte Carlo figure of a sample
  of the variation itself (the pilot) where there is one, else the Clopper-Pearson bound
  on the effective size of the whole sample (approximate).

The recorded share: the share of P(collision) whose contact with the primary rider
happened on its recorded behaviour (``collision_recorded``, vei.metrics.where); the rest
happened on vei's synthetic run-in or run-out of the rider (issue 22's continuations).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.risk import estimators as est
from vei.risk.estimators import Estimate

FloatArray = npt.NDArray[np.float64]


def _ess(w: FloatArray) -> float:
    s2 = float(np.sum(w * w))
    return float(np.sum(w)) ** 2 / s2 if s2 > 0 else 0.0


def weighted_figure(
    h: npt.ArrayLike,
    w: npt.ArrayLike,
    failures: npt.ArrayLike,
    p_failure: Estimate,
    *,
    part_of_failure: bool,
    pilot: Estimate | None = None,
) -> Estimate:
    """E_f[h] of an importance sample (h [n] in [0, 1], weights w [n], failure indicator
    [n]) with an honest upper bound when no sample holds the event (module docstring).

    Args:
        p_failure: P(failure) from the same sample. part_of_failure: h is 0 wherever the
            sample is no failure. pilot: the event's Monte Carlo figure of a sample of
            the variation itself (used for events outside the failure event).
    """
    h = np.asarray(h, dtype=np.float64)
    w = np.asarray(w, dtype=np.float64)
    f = np.asarray(failures, dtype=bool)
    e = est.importance_sampling(h, w, f)
    if not e.bound:
        return e
    if part_of_failure and not p_failure.bound and f.any():
        n_eff = _ess(w[f])
        cp = 1.0 - (1.0 - est.CONFIDENCE) / 2.0
        share_hi = 1.0 - (1.0 - cp) ** (1.0 / max(n_eff, 1.0))
        return Estimate(
            math.nan, 0.0, min(1.0, p_failure.hi * share_hi), len(h), "importance-sampling-bound",
            0, bound=True, reliable=p_failure.reliable, diagnostics={"ess_failures": n_eff},
            notes=(f"none of the {int(f.sum()):,} failures ({n_eff:,.0f} effective) holds it: "
                   "P(collision)'s upper limit x the Clopper-Pearson bound of its share "
                   "(approximate: on the effective sample size)",),
        )  # fmt: skip
    if pilot is not None:
        return pilot.with_note("from the Monte Carlo pilot (the importance sample holds none)")
    if p_failure.bound:
        return p_failure
    n_eff = _ess(w)
    hi = est.clopper_pearson(0, max(1, int(n_eff)))[1]
    return Estimate(
        math.nan, 0.0, hi, len(h), "importance-sampling-bound", 0, bound=True,
        diagnostics={"ess": n_eff},
        notes=(f"none in the importance sample: Clopper-Pearson bound on its effective size "
               f"{n_eff:,.0f} (approximate)",),
    )  # fmt: skip


def share_of(part: np.ndarray, whole: np.ndarray, w: np.ndarray | None) -> Estimate:
    """Share of ``whole`` [n] bool that is ``part`` [n] bool (weights w [n], None: 1), with
    a Wilson interval on the effective count (Kong's ESS of the weights in ``whole``)."""
    ww = np.ones(len(whole)) if w is None else w
    tot = float(np.sum(ww[whole]))
    if tot <= 0:
        return Estimate(math.nan, 0.0, 1.0, int(whole.sum()), "wilson", 0, bound=True,
                        notes=("no collision",))  # fmt: skip
    share = float(np.sum(ww[part & whole]) / tot)
    wf = ww[whole]
    n_eff = tot * tot / float(np.sum(wf * wf))
    lo, hi = est.wilson_interval(round(share * n_eff), max(1, round(n_eff)))
    return Estimate(share, lo, hi, int(whole.sum()), "wilson", int((part & whole).sum()))


def recorded_column(rows: pd.DataFrame) -> np.ndarray:
    """[n] bool: a counted collision on the primary rider's recorded behaviour (False
    where the rows do not carry ``collision_recorded``)."""
    fail = rows["failure"].to_numpy(bool)
    if "collision_recorded" not in rows:
        return np.zeros(len(rows), bool)
    rec = rows["collision_recorded"].fillna(False).to_numpy(bool)
    return fail & rec


def synthetic_share(rows: pd.DataFrame, weighted: bool) -> Estimate:
    """The share of P(collision) on vei's run-in / run-out of the rider (not recorded),
    with a Wilson interval on the effective number of failures."""
    fail = rows["failure"].to_numpy(bool)
    rec = recorded_column(rows)
    w = rows["weight"].to_numpy(np.float64) if weighted else None
    return share_of(fail & ~rec, fail, w)


def share_sentence(share: Estimate) -> str:
    """Plain words: 'x % of P(collision) [lo-hi %] comes from the rider's synthetic
    run-in / run-out (outside its recording)'; '' without collisions."""
    if share.bound or not math.isfinite(share.value):
        return ""
    pct = f"{100 * share.value:.0f} % [{100 * share.lo:.0f}-{100 * share.hi:.0f} %]"
    if share.value >= 0.995:
        head = "every counted collision (" + pct + ") happens"
    else:
        head = f"{pct} of P(collision) comes from collisions that happen"
    return (
        f"{head} on the rider's synthetic run-in or run-out (vei's continuation, outside "
        "its recorded track); the rest on recorded behaviour"
    )
