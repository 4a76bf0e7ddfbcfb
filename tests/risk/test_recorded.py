"""Risk that rests on recorded behaviour (issue 31.1, the risk side): P(collision on the
rider's recorded behaviour) from the same sample as the total, the share from vei's
synthetic continuations, a spec that counts only recorded collisions; run configurations
for the failures the estimate rests on; SALib's warnings said in vei's words."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from vei.errors import ConfigError
from vei.risk.analytic import IntervalProblem
from vei.risk.assess import figures
from vei.risk.output import config_rows
from vei.risk.problem import add_outcomes
from vei.risk.variation import parse_variation
from vei.risk.weighted import share_sentence


def _rows() -> pd.DataFrame:
    # 6 samples: 4 collisions, 1 of them on recorded behaviour, 1 seen too late
    return pd.DataFrame({
        "collision": [True, True, True, True, False, False],
        "collision_recorded": [True, False, False, False, False, False],
        "seen_too_late": [False, False, False, True, False, False],
        "impact_speed_mps": [8.0, 3.0, 7.0, 9.0, np.nan, np.nan],
        "injury_risk": [0.1, 0.01, 0.05, 0.2, 0.0, 0.0],
        "min_gap_m": [0.0, 0.0, 0.0, 0.0, 1.5, 0.3],
    })  # fmt: skip


def test_only_recorded_collisions_count_when_asked():
    every = add_outcomes(_rows(), 5.56)
    assert list(every["failure"]) == [True, True, True, False, False, False]
    rec = add_outcomes(_rows(), 5.56, only_recorded=True)
    assert list(rec["failure"]) == [True, False, False, False, False, False]
    # an uncounted collision is a miss at margin 0 (not < 0)
    assert list(rec["margin"]) == [-1.0, 0.0, 0.0, 0.0, 1.5, 0.3]
    assert list(rec["injury_relevant"]) == [True, False, False, False, False, False]


def test_recorded_figure_and_share_by_hand():
    f = figures(add_outcomes(_rows(), 5.56), weighted=False)
    assert f["p_collision"].value == pytest.approx(3 / 6)
    assert f["p_collision_recorded"].value == pytest.approx(1 / 6)
    share = f["share_synthetic"]
    assert share.value == pytest.approx(2 / 3)  # 2 of the 3 counted collisions
    text = share_sentence(share)
    assert text.startswith("67 % [") and "synthetic run-in or run-out" in text
    # weighted: weights 1, 3, 0, ... -> P = (1 + 3) / 6, recorded 1 / 6, share 3 / 4
    rows = add_outcomes(_rows(), 5.56)
    rows["weight"] = [1.0, 3.0, 0.0, 1.0, 1.0, 1.0]
    f = figures(rows, weighted=True)
    assert f["p_collision"].value == pytest.approx(4 / 6)
    assert f["p_collision_recorded"].value == pytest.approx(1 / 6)
    assert f["share_synthetic"].value == pytest.approx(3 / 4)


def test_spec_failure_count():
    m = parse_variation({"failure": {"count": "recorded"}})
    assert m.failure_count == "recorded"
    assert parse_variation(m.to_dict()) == m
    d = parse_variation({})
    assert d.failure_count == "all" and "failure" not in d.to_dict()  # digests unchanged
    with pytest.raises(ConfigError, match="failure: unknown key.s. on; expected count"):
        parse_variation({"failure": {"on": "recorded"}})
    with pytest.raises(ConfigError, match="failure.count must be one of all, recorded"):
        parse_variation({"failure": {"count": "run-in"}})
    with pytest.raises(ConfigError, match="failure must be a mapping"):
        parse_variation({"failure": "recorded"})


def test_configs_for_the_failures_the_estimate_rests_on():
    samples = pd.DataFrame({
        "variant_id": [f"v{i}" for i in range(8)],
        "collision": [True, True, False, True, True, False, False, True],
        "in_estimate": [False, False, False, True, True, True, True, False],
    })  # fmt: skip
    import vei.risk.output as out

    keep = (out.MAX_FAILURE_CONFIGS, out.OTHER_CONFIGS)
    out.MAX_FAILURE_CONFIGS, out.OTHER_CONFIGS = 3, 1
    try:
        got = config_rows(samples, "failures")
    finally:
        out.MAX_FAILURE_CONFIGS, out.OTHER_CONFIGS = keep
    # the estimate's collisions v3, v4 first, then the earliest other collision v0; one
    # sample without collision, also from the estimate (v5)
    assert list(got["variant_id"]) == ["v3", "v4", "v0", "v5"]


def test_salib_warnings_are_said_in_vei_words():
    pytest.importorskip("SALib")
    from vei.risk.sensitivity import few_failures_note, sobol_indices

    # a collision interval so thin that the Sobol sample holds about one collision
    prob = IntervalProblem({"A": (2.5, 2.51)}, dim=3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a leaked warning fails the test
        s = sobol_indices(prob, "A", n=64, seed=0)
    assert few_failures_note(s) is not None
    assert all("Warning" not in n for n in s["notes"])


@pytest.mark.slow
def test_recorded_collisions_on_a_shared_recording(tmp_path, trafficmonitoring_root):
    """audi_08_klinikum_rechtsabbiegen_02 (the cyclist turning beside the car; shifts
    4.4-4.6 s meet it on its recorded track, 4.8-5.2 s on its run-in: tests/continuation/
    test_where.py): P(collision on recorded) lies below the total, the console says the
    synthetic share, and a spec counting only recorded collisions gives, on the same
    samples, exactly the first run's P(collision on recorded)."""
    from vei.cli.main import main
    from vei.risk.run import assess_risk

    inter, scen = tmp_path / "inter", tmp_path / "scen"
    name = "audi_08_klinikum_rechtsabbiegen_02"
    assert main(["import", "trafficmonitoring", "--root", str(trafficmonitoring_root),
                 "--scenario", name, "--out", str(inter)]) == 0  # fmt: skip
    assert main(["reconstruct", str(inter), "--out", str(scen), "--no-figure"]) == 0
    spec = {"base": "normal", "time_shift_reference": "zero",
            "variation": {"time_shift_s": {"dist": "uniform", "min": 4.3, "max": 5.3},
                          "rider": None}}  # fmt: skip
    every = assess_risk(scen, parse_variation(spec), method="mc", budget=1000,
                        target_rel_ci=0.01, sobol_n=0)  # fmt: skip
    p = every.planners[0]
    rec, tot = p.p_collision_recorded, p.p_collision
    assert 0 < rec.value < tot.value and rec.lo <= rec.value <= rec.hi
    assert 0 < p.share_synthetic.value < 1
    only = assess_risk(scen, parse_variation({**spec, "failure": {"count": "recorded"}}),
                       method="mc", budget=1000, target_rel_ci=0.01, sobol_n=0)  # fmt: skip
    q = only.planners[0].p_collision
    assert q.value == pytest.approx(rec.value) and (q.lo, q.hi) == pytest.approx((rec.lo, rec.hi))
    assert only.planners[0].share_synthetic.value == 0.0
    from vei.cli.risk_cmd import print_result

    lines: list[str] = []

    class _Console:
        def print(self, text: str) -> None:
            lines.append(text)

    print_result(every, _Console())
    assert any("P(collision on recorded)" in ln for ln in lines)
    assert any("synthetic run-in or run-out" in ln for ln in lines)
    lines.clear()
    print_result(only, _Console())
    assert any("only collisions on the rider's recorded behaviour count" in ln for ln in lines)
