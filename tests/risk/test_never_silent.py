"""Estimators that never miss silently (issue 31.5), on scripted problems with known
answers: a run with no failure gives an honest upper bound (never nan, never a
traceback), a run whose stages met failures gives an estimate, the secondary outcomes of
an importance sample are estimated or bounded, the Monte Carlo pilot is reused by the
first rare-event stage (counted simulations), subset simulation's interval covers, and
the comparison sentence states the difference in the order it names the planners."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from benchmarks.bench_risk_methods import half_space
from scipy.special import ndtr, ndtri

from vei.risk import estimators as est
from vei.risk.analytic import IntervalProblem
from vei.risk.assess import assess_planner
from vei.risk.compare import Comparison
from vei.risk.modes import failure_kinds, failure_regions
from vei.risk.rare import cross_entropy
from vei.risk.subset import chain_gamma, subset_estimate
from vei.risk.weighted import share_of, weighted_figure

FIGURES = ("p_collision", "p_injury_relevant", "expected_injury", "p_seen_too_late",
           "p_collision_recorded")  # fmt: skip


def _finite(e) -> bool:
    return math.isfinite(e.hi) and e.lo <= e.hi and (e.bound or math.isfinite(e.value))


@pytest.mark.parametrize("method", ["ce", "subset", "auto"])
def test_no_failure_anywhere_gives_an_upper_bound(method):
    # collision iff the offset lies in [40, 41] sigma: nothing is ever seen (cross-entropy
    # even finds [9, 10] sigma, P = 1.1e-19, within this budget)
    prob = IntervalProblem({"far": (40.0, 41.0)}, dim=2)
    r = assess_planner(prob, "far", method=method, budget=6000, target_rel_ci=0.2, seed=0,
                       stage_size=1000)  # fmt: skip
    for name in FIGURES:
        e = getattr(r, name)
        assert _finite(e), (name, e)
    assert r.p_collision.bound
    # the whole budget as Monte Carlo: Clopper-Pearson 1 - 0.025^(1/n), n = 6,000
    n_mc = len(r.rows)
    assert n_mc >= 1000 and r.n_simulations <= 6000
    assert r.p_collision.hi == pytest.approx(1 - 0.025 ** (1 / n_mc), rel=1e-9)
    assert "upper bound" in r.p_collision.text() and "nan" not in r.p_collision.text()
    assert failure_kinds(r.rows, weighted=False) == []
    assert failure_kinds(pd.DataFrame(), weighted=True) == []
    assert failure_regions(pd.DataFrame(), ["time_shift_s"], True) == []


def test_stages_that_met_failures_give_an_estimate():
    # a thin slab at 2.5 sigma: P = 1e-3. The margin (distance to the slab) points at its
    # far side too, so rho-quantile steps stall; the stages hold a few failures each
    p = 1e-3
    a = 2.5
    b = float(ndtri(ndtr(a) + p))
    prob = IntervalProblem({"slab": (a, b)}, dim=3)
    truth = prob.probability()
    r = cross_entropy(lambda u, s: prob.evaluate(u, stage=s), 3, stage_size=2000,
                      budget=2000, target_rel_ci=0.1, seed=3)  # fmt: skip
    # one stage only: the budget ends before the region is reached (10 % quantile > 0)
    assert not r.reached and r.stages[0]["failures"] > 0
    e = r.probability
    assert not e.bound and e.lo <= truth <= e.hi, (e.text(), truth)
    assert r.mixture is not None and "mixture" in e.notes[-1]


def test_failures_as_elite_reach_the_region():
    # 1.5 % of the first stage fails, far fewer than rho = 10 %: its failures are the elite
    prob = IntervalProblem({"slab": (2.17, 3.5)}, dim=3)
    truth = prob.probability()
    r = cross_entropy(lambda u, s: prob.evaluate(u, stage=s), 3, stage_size=2000,
                      budget=20_000, target_rel_ci=0.1, seed=1)  # fmt: skip
    assert r.stages[0]["elite"] == "failures" and r.reached
    assert r.probability.lo <= truth <= r.probability.hi


def test_secondary_outcomes_of_an_importance_sample_are_bounded_not_nan():
    # 100 failures of equal weight 1e-3 (P = 1e-3 x 100 / 1000 = 1e-4), none injury-relevant
    w = np.full(1000, 1e-3)
    fail = np.zeros(1000, bool)
    fail[:100] = True
    pc = est.importance_sampling(fail, w, fail)
    e = weighted_figure(np.zeros(1000), w, fail, pc, part_of_failure=True)
    # P(collision)'s upper limit x Clopper-Pearson of 0 in 100 effective failures
    assert e.bound and e.hi == pytest.approx(pc.hi * (1 - 0.025 ** (1 / 100)), rel=1e-9)
    assert "nan" not in e.text()
    # an event outside the failure event falls back to the pilot's Monte Carlo figure
    pilot = est.mc_probability(np.zeros(2000, bool))
    late = weighted_figure(np.zeros(1000), w, np.zeros(1000, bool), pc, part_of_failure=False,
                           pilot=pilot)  # fmt: skip
    assert late.hi == pytest.approx(1 - 0.025 ** (1 / 2000), rel=1e-9)
    # and an event that is seen is estimated
    h = np.zeros(1000)
    h[:40] = 1
    got = weighted_figure(h, w, fail, pc, part_of_failure=True)
    assert got.value == pytest.approx(4e-5) and not got.bound


def test_share_by_hand():
    whole = np.array([1, 1, 1, 1, 0], bool)
    part = np.array([1, 0, 0, 0, 0], bool)
    s = share_of(part, whole, None)
    assert s.value == pytest.approx(0.25)
    lo, hi = est.wilson_interval(1, 4)
    assert (s.lo, s.hi) == pytest.approx((lo, hi))


@pytest.mark.parametrize("method", ["ce", "subset"])
def test_the_pilot_is_the_first_stage_not_re_simulated(method):
    prob = IntervalProblem.with_probability(1e-4, dim=3)
    r = assess_planner(prob, "scripted", method=method, budget=20_000, target_rel_ci=0.2,
                       seed=0, stage_size=1000)  # fmt: skip
    simulated = sum(len(f) for f in prob.log)
    assert simulated == r.n_simulations <= 20_000  # every simulation counted once
    stages = pd.concat(prob.log)["stage"]
    assert (stages == "mc").sum() == 1000  # the pilot, once
    assert not stages.isin(["ce-0", "ss-0"]).any()  # not drawn again as a first stage
    if method == "ce":
        assert r.rare.stages[0]["reused"]


def test_chain_gamma_by_hand():
    # 2 chains of 3 states, p = 0.5: R(1) = (1 + 1) / 4 - 0.25 = 0.25, R(2) = 1/2 - 0.25
    ind = np.array([[1, 1, 1], [0, 0, 0]], float)
    r0 = 0.25
    g = 2 * ((1 - 2 / 6) * (2 / 4 - 0.25) / r0 + (1 - 4 / 6) * (1 / 2 - 0.25) / r0)
    assert chain_gamma(ind, 0.5) == pytest.approx(g)
    # independent states: gamma ~ 0
    rng = np.random.default_rng(0)
    assert abs(chain_gamma(rng.random((2000, 10)) < 0.1, 0.1)) < 0.05


@pytest.mark.slow
def test_subset_uses_the_budget_and_covers():
    # P = 1e-2 on a linear limit-state in 3 dimensions, 40 repetitions (the benchmark runs
    # 200 at 1e-2 and 1e-4): coverage within the binomial spread of 0.95
    hits, used = 0, []
    for seed in range(40):
        e, runs, n = subset_estimate(half_space(1e-2, 3), 3, level_size=500, budget=8_000,
                                     target_rel_ci=0.1, seed=seed)  # fmt: skip
        hits += e.lo <= 1e-2 <= e.hi
        used.append(n)
        assert len(runs) >= 2  # one run cannot reach +-10 %: further runs take the budget
    assert 0.85 <= hits / 40 <= 1.0
    assert np.mean(used) > 6_000


def _cmp(verdict: str, d: float, lo: float, hi: float) -> Comparison:
    e = est.Estimate(d, lo, hi, 100, "agresti-min")
    return Comparison("none", "paper-cap", 100, "mc", e, e, e, verdict, 0)


def test_comparison_sentence_states_the_difference_in_its_order():
    # a = none collides more: P_a - P_b = +0.358, B (paper-cap) safer
    text = _cmp("B safer", 0.358, 0.30, 0.40).sentence()
    assert text.startswith("paper-cap is safer than none: P(paper-cap) - P(none) = -0.358")
    assert "[-0.4, -0.3]" in text
    text = _cmp("A safer", -0.2, -0.3, -0.1).sentence()
    assert text.startswith("none is safer than paper-cap: P(none) - P(paper-cap) = -0.2")
    assert "no significant difference" in _cmp("no significant difference", 0.1, -0.1,
                                                0.3).sentence()  # fmt: skip


def test_independent_runs_combine_by_hand():
    from vei.risk.subset import SubsetRun, combine, lognormal_interval

    a, b = SubsetRun(1e-3, 0.1), SubsetRun(3e-3, 0.1)
    # Au & Beck: var = (0.1e-3)^2 + (0.3e-3)^2 = 1e-7 ... the runs' spread is larger:
    # ((1e-3 - 2e-3)^2 + (3e-3 - 2e-3)^2) x 2 / 1 = 4e-6 -> CoV = 2e-3 / 4e-3 = 0.5, 1 dof
    p, cov, df = combine([a, b])
    assert (p, cov, df) == pytest.approx((2e-3, 0.5, 1.0))
    # close runs: Au & Beck's coefficients hold: CoV = sqrt(2 (0.1 x 2e-3)^2) / 4e-3
    p, cov, df = combine([SubsetRun(2e-3, 0.1), SubsetRun(2e-3, 0.1)])
    assert cov == pytest.approx(math.sqrt(2) * 0.1 / 2) and math.isinf(df)
    lo, hi = lognormal_interval(1.0, math.sqrt(math.e - 1))  # sqrt(ln(1 + cov^2)) = 1
    assert (lo, hi) == pytest.approx((math.exp(-1.959964), math.exp(1.959964)), rel=1e-6)
    lo, _ = lognormal_interval(1.0, math.sqrt(math.e - 1), 1.0)  # t_1 quantile 12.706
    assert lo == pytest.approx(math.exp(-12.7062), rel=1e-4)


def test_a_mixture_proposal_of_one_component_is_the_normal_proposal():
    from vei.risk.compare import _log_q

    rng = np.random.default_rng(2)
    u = rng.standard_normal((50, 3))
    mu, sd = np.array([1.0, -0.5, 0.0]), np.array([0.8, 1.2, 1.0])
    assert np.allclose(_log_q(u, [(mu, sd, 1.0)]), _log_q(u, (mu, sd)))
    # two equal halves of the same normal: the same density
    assert np.allclose(_log_q(u, [(mu, sd, 0.5), (mu, sd, 0.5)]), _log_q(u, (mu, sd)))
    # by hand at u = 0 for q = N(mu, sd^2): log q - log phi = sum(-z^2/2 - log sd)
    z = -mu / sd
    assert _log_q(np.zeros((1, 3)), (mu, sd))[0] == pytest.approx(np.sum(-0.5 * z * z - np.log(sd)))
