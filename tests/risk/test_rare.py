"""The rare-event estimators against known answers, and why vei's cross-entropy loop is
its own: OpenTURNS' StandardSpaceCrossEntropyImportanceSampling refits its standard
deviations every stage and stalls before a failure region far out along one coordinate."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import ndtr

from vei.risk.analytic import IntervalProblem
from vei.risk.rare import cross_entropy, subset_simulation


def _far_problem() -> IntervalProblem:
    # collision iff the offset lies in [4, 6] (standard normal): P = Phi(6) - Phi(4)
    return IntervalProblem({"far": (4.0, 6.0)}, dim=2)


def test_openturns_cross_entropy_stalls_far_out():
    ot = pytest.importorskip("openturns")
    prob = _far_problem()

    def g(x):
        return prob.evaluate(np.asarray(x), stage="ot")["margin"].to_numpy()[:, None]

    fn = ot.PythonFunction(2, 1, func_sample=g)
    event = ot.ThresholdEvent(
        ot.CompositeRandomVector(fn, ot.RandomVector(ot.Normal(2))), ot.Less(), 0.0
    )
    ot.RandomGenerator.SetSeed(1)
    algo = ot.StandardSpaceCrossEntropyImportanceSampling(event, 0.1)
    algo.setMaximumOuterSampling(1)
    algo.setBlockSize(1000)
    calls = {"n": 0}

    def stop():
        calls["n"] += 1
        return calls["n"] >= 12  # 12 stages of 1,000

    algo.setStopCallback(stop)
    with pytest.raises(RuntimeError, match="stopped"):
        algo.run()
    levels = list(algo.getThresholdPerStep())
    assert min(levels) > 0.1  # never reached the failure region


def test_vei_cross_entropy_reaches_it():
    prob = _far_problem()
    truth = float(ndtr(6.0) - ndtr(4.0))
    r = cross_entropy(lambda u, s: prob.evaluate(u, stage=s), 2, stage_size=1000,
                      budget=20_000, target_rel_ci=0.1, seed=1)  # fmt: skip
    assert r.reached and len(r.stages) <= 5
    e = r.probability
    assert abs(e.value - truth) <= (e.hi - e.lo) / 2 * 3.2905 / 1.95996
    assert e.rel_ci <= 0.1 and e.reliable
    assert r.n_simulations <= 10_000
    # the proposal sits in the failure region; the irrelevant dimension keeps its spread
    assert 4.0 <= r.proposal["mean"][0] <= 4.6
    assert 0.7 <= r.proposal["std"][1] <= 1.3


def test_partial_answer_when_the_budget_ends_first():
    prob = IntervalProblem({"far": (9.0, 10.0)}, dim=2)
    r = cross_entropy(lambda u, s: prob.evaluate(u, stage=s), 2, stage_size=500,
                      budget=1_000, target_rel_ci=0.1, seed=0)  # fmt: skip
    assert not r.reached and r.probability.bound and not r.probability.reliable
    assert "partial answer" in r.notes[0]


def test_subset_simulation_known_answer():
    prob = _far_problem()
    truth = float(ndtr(6.0) - ndtr(4.0))
    r = subset_simulation(lambda u, s: prob.evaluate(u, stage=s), 2, level_size=2000,
                          budget=40_000, seed=2)  # fmt: skip
    assert r.reached
    e = r.probability
    assert e.lo <= truth <= e.hi, (e.text(), truth)
    assert "Au & Beck" in e.notes[0]
