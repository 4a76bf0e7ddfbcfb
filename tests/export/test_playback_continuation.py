"""Issue 22: an export with continuations plays in esmini as well as one without.

A real recording reconstructed with its map (the Ingolstadt SUMO network: lanes, so the
run-ins and run-outs follow them where a rider is on one) is exported twice, as recorded
and with every road user's run-in and run-out (what ``vei export openscenario`` without
``--config`` writes), and played headless in esmini: every entity's deviation from the
file's vertices stays as small as without continuations (median within 0.1 m of it and
within the playback bounds), and no entity has a frame outside its own span.
"""

from __future__ import annotations

import re

import pytest

from vei.cli.export_cmd import replay_trajectories
from vei.export.openscenario import export_openscenario
from vei.export.playback import MAX_DEVIATION_M, MAX_MEDIAN_DEVIATION_M, play_xosc
from vei.types import CONTINUATION_COLUMN

NAME = "stadtmitte_12_audi_geradeaus_03"


@pytest.mark.slow
def test_export_with_continuations_plays_in_esmini(playback_world, esmini, tmp_path) -> None:
    world = playback_world(NAME)
    agents = list(world.scenario.agents)
    reports = {}
    trajs = {
        "recorded": world.scenario.trajectories,
        "continued": replay_trajectories(world.scenario),
    }
    assert trajs["continued"][CONTINUATION_COLUMN].any()
    for key, traj in trajs.items():
        path = export_openscenario(traj, agents, tmp_path / key, xodr=world.xodr, name=key)
        reports[key] = play_xosc(path, esmini=esmini, work_dir=tmp_path / key / "play")
        assert reports[key].returncode == 0
        assert reports[key].issues() == [], (key, reports[key].issues())
    text = (tmp_path / "continued" / "continued.xosc").read_text()
    assert re.search(r'name="vei:recorded_span_s" value="[-0-9.]+ [0-9.]+"', text)
    assert "vei:recorded_span_s" not in (tmp_path / "recorded" / "recorded.xosc").read_text()
    before = {e.name: e for e in reports["recorded"].entities}
    after = {e.name: e for e in reports["continued"].entities}
    spans = trajs["continued"].groupby("agent_id")["t_s"].agg(["min", "max"])
    assert set(after) == set(spans.index.astype(str))
    longer = 0
    for aid, (t0, t1) in spans.iterrows():
        e = after[str(aid)]
        assert e.outside == 0 and e.missing == 0, e
        if e.frames:
            assert e.first_s >= t0 - 1e-6 and e.last_s <= t1 + 1e-6, e
        if t1 - t0 >= 0.1:
            assert e.median_dev_m < MAX_MEDIAN_DEVIATION_M and e.max_dev_m < MAX_DEVIATION_M, e
            assert abs(e.median_dev_m - before[str(aid)].median_dev_m) <= 0.1, (e, before[str(aid)])
        longer += e.frames > before[str(aid)].frames
    assert longer >= 1  # somebody arrives earlier or leaves later than recorded
