"""Planner comparison on common random numbers, failure modes and Sobol indices against
scripted problems with known answers."""

from __future__ import annotations

import pytest

from vei.risk.analytic import IntervalProblem
from vei.risk.assess import assess_planner
from vei.risk.compare import compare
from vei.risk.modes import failure_kinds, failure_regions
from vei.risk.sensitivity import importance_factors, sobol_indices


def _two_planners() -> IntervalProblem:
    # A collides on [1, 2], B on [1, 1.9]: P_A - P_B = Phi(2) - Phi(1.9) = 0.00597
    return IntervalProblem({"A": (1.0, 2.0), "B": (1.0, 1.9)}, dim=2)


def test_paired_difference_monte_carlo_excludes_zero_where_true():
    prob = _two_planners()
    a = assess_planner(prob, "A", method="mc", budget=20_000, target_rel_ci=0.05, seed=0)
    b = assess_planner(prob, "B", method="mc", budget=20_000, target_rel_ci=0.05, seed=0)
    c = compare(prob, a, b, seed=0)
    truth = prob.probability("A") - prob.probability("B")
    assert c.method == "mc"
    assert c.collision.lo <= truth <= c.collision.hi
    # paired: far narrower than the two independent intervals together
    assert (c.collision.hi - c.collision.lo) < 0.25 * (
        (a.p_collision.hi - a.p_collision.lo) + (b.p_collision.hi - b.p_collision.lo)
    )
    assert c.verdict == "B safer" and "B is safer than A" in c.sentence()


def test_identical_planners_are_not_called_different():
    prob = IntervalProblem({"A": (1.0, 2.0), "A2": (1.0, 2.0)}, dim=2)
    a = assess_planner(prob, "A", method="mc", budget=5000, target_rel_ci=0.1, seed=3)
    b = assess_planner(prob, "A2", method="mc", budget=5000, target_rel_ci=0.1, seed=3)
    c = compare(prob, a, b, seed=3)
    assert c.verdict == "no significant difference" and c.collision.value == 0.0
    assert "no significant difference" in c.sentence()


def test_paired_difference_with_importance_sampling():
    prob = IntervalProblem({"A": (3.0, 3.5), "B": (3.0, 3.3)}, dim=2)
    a = assess_planner(prob, "A", method="ce", budget=20_000, target_rel_ci=0.1, seed=1)
    b = assess_planner(prob, "B", method="ce", budget=20_000, target_rel_ci=0.1, seed=1)
    c = compare(prob, a, b, seed=1)
    truth = prob.probability("A") - prob.probability("B")
    assert c.method == "mixture-is"
    assert c.collision.lo <= truth <= c.collision.hi
    assert c.verdict == "B safer"


def test_failure_regions_recover_the_interval():
    prob = IntervalProblem({"A": (0.5, 1.2)}, dim=2)
    r = assess_planner(prob, "A", method="mc", budget=20_000, target_rel_ci=0.05, seed=0)
    regions = failure_regions(r.rows, ["time_shift_s"], weighted=False)
    top = regions[0]
    lo, hi = top.bounds["time_shift_s"]
    assert lo == pytest.approx(0.5, abs=0.02) and hi == pytest.approx(1.2, abs=0.02)
    assert top.share == pytest.approx(1.0) and top.p_collision == pytest.approx(1.0)
    assert "time_shift_s in [0.5" in top.rule()
    kinds = failure_kinds(r.rows, weighted=False)
    assert kinds and abs(sum(k["share_of_p_collision"] for k in kinds) - 1) < 1e-9


def test_sobol_finds_the_quantity_that_matters():
    pytest.importorskip("SALib")
    prob = IntervalProblem({"A": (-0.5, 0.8)}, dim=3)
    s = sobol_indices(prob, "A", n=512, seed=0)
    st = {k: v["ST"] for k, v in s["collision"].items()}
    assert st["time_shift_s"] > 0.9
    assert st["noise_1"] < 0.05 and st["noise_2"] < 0.05
    f = importance_factors(["a", "b"], [3.0, 0.3])
    assert f["a"] == pytest.approx(9 / 9.09) and sum(f.values()) == pytest.approx(1.0)
