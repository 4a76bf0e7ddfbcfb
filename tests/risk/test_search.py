"""Failure search: the distinct-failure count by hand, every searcher on one scripted
problem within the same budget, NSGA-II (pymoo) finding the failure region."""

from __future__ import annotations

import numpy as np
import pytest

from vei.risk.analytic import IntervalProblem
from vei.risk.search import compare_searches, distinct_failures


def test_distinct_failures_counts_occupied_grid_cells():
    x = np.array([[0.01, 0.01], [0.19, 0.05], [0.21, 0.05], [0.99, 1.0], [1.0, 0.99]])
    # cells of 5 per axis: (0,0), (0,0), (1,0), (4,4), (4,4): the upper edge is the last cell
    assert distinct_failures(x, 5) == 3
    assert distinct_failures(np.zeros((0, 2)), 5) == 0


def test_every_searcher_on_the_same_problem_and_budget():
    pytest.importorskip("pymoo")
    prob = IntervalProblem({"p": (1.5, 2.5)}, dim=3)  # failures: offset in [1.5, 2.5]
    res = {r.searcher: r for r in compare_searches(prob, "p", budget=1500, seed=0)}
    assert set(res) == {"random", "nsga2", "ce", "boundary"}
    for r in res.values():
        assert 0 < r.n_simulations <= 1500
        assert r.distinct <= r.failures
    # the region is cell 4 of the offset axis (Phi(1.5) = 0.93, Phi(2.5) = 0.994): at most
    # 5 x 5 cells of the two noise axes
    assert all(r.distinct <= 25 for r in res.values())
    assert res["nsga2"].failures > 5 * res["random"].failures  # the search concentrates
    assert res["boundary"].distinct <= 5  # a 2-D slice: the third axis stays at its median
    failing = prob.samples()
    failing = failing[failing["failure"]]
    assert ((failing["time_shift_s"] >= 1.5) & (failing["time_shift_s"] <= 2.5)).all()
