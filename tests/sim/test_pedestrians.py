"""Social-force pedestrians (vei.models.pedestrian_core, vei.sim.pedestrians): hand values
of the law, a pedestrian that steps back for the car it would have walked into, replayed
when off, the rider repelled by them, and the compiled kernel's fallback."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from vei.config import SimConfig, TrafficConfig, case_preset
from vei.models import pedestrian_core as core
from vei.sim.engine import simulate
from vei.sim.state import VariantParams, prepare_scenario
from vei.sim.testing import TrackSpec, make_scenario
from vei.types import EGO_ID


def test_law_by_hand() -> None:
    # driving term: (v0 d / sqrt(d^2 + 0.3^2) - v) / tau
    ax, ay = core.drive_accel_core(0.0, 0.0, 2.0, 0.0, 0.5, 0.0, 1.3, 0.5)
    assert ax == pytest.approx((1.3 * 2.0 / math.sqrt(4.0 + 0.09) - 0.5) / 0.5) and ay == 0.0
    # HFV among pedestrians, head-on (in view: weight 1): A/m exp((r_ij - d) / B)
    ax, ay = core.repulsion_accel_core(1.0, 0.0, 0.4, 2000.0, 0.08, 80.0, -1.0, 0.0, 0.75)
    assert ax == pytest.approx(2000.0 / 80.0 * math.exp(-0.4 / 0.08)) and ay == 0.0
    # from behind it counts lambda = 0.75 as much; standing: isotropic
    bx, _ = core.repulsion_accel_core(1.0, 0.0, 0.4, 2000.0, 0.08, 80.0, 1.0, 0.0, 0.75)
    assert bx == pytest.approx(0.75 * ax)
    sx, _ = core.repulsion_accel_core(1.0, 0.0, 0.4, 2000.0, 0.08, 80.0, 0.0, 0.0, 0.75)
    assert sx == pytest.approx(ax)
    # beyond the cutoff nothing; caps
    assert core.repulsion_accel_core(20.0, 0.0, 19.0, 2000.0, 0.08, 80.0, 0.0, 0.0, 0.75) == (
        0.0,
        0.0,
    )
    assert core.speed_cap_core(3.0, 4.0, 1.0) == pytest.approx((0.78, 1.04))
    assert core.accel_cap_core(30.0, 40.0, 5.0) == pytest.approx((3.0, 4.0))


def _scene():
    """The ego at 5 m/s along +x; a pedestrian crossing its lane at x = 30 m at 1.3 m/s
    (recorded: the car passes while it is on the lane, their boxes touch); a rider far off."""
    t = np.arange(0, 401) / 20.0
    z = np.zeros_like(t)
    ego = TrackSpec("ego", t, 5.0 * t, z, z, np.full_like(t, 5.0))
    tp = t[t >= 2.5]
    ped = TrackSpec("pedestrian", tp, np.full_like(tp, 30.0), -6.0 + 1.3 * (tp - 2.5),
                    np.full_like(tp, math.pi / 2), np.full_like(tp, 1.3))  # fmt: skip
    rider = TrackSpec("escooter", t, np.full_like(t, 200.0), np.full_like(t, 30.0),
                      np.full_like(t, math.pi / 2), z)  # fmt: skip
    return make_scenario({EGO_ID: ego, "p1": ped, "r1": rider}, primary_threat="r1")


@pytest.fixture(scope="module")
def run():
    a = prepare_scenario(_scene(), SimConfig())
    ps = [
        VariantParams.from_case(
            dataclasses.replace(case_preset("replay"), traffic=TrafficConfig(pedestrians=on)),
            a,
            1,
            cruise_speed_mps=5.0,
        )  # fmt: skip
        for on in (False, True)
    ]
    return a, simulate(a, VariantParams.concat(ps), kernel="numpy")


def test_the_pedestrian_steps_back_for_the_car(run) -> None:
    a, r = run
    assert a.peds.n == 1 and a.peds.v0_mps[0] == pytest.approx(1.3)
    fr = r.to_frame()
    rec = fr[(fr.variant == 0) & (fr.agent_id == "p1")]
    sim = fr[(fr.variant == 1) & (fr.agent_id == "p1")]
    # replayed (off): its recording, and the car hits it (a secondary collision)
    j = a.other_ids.index("p1")
    k = np.rint(rec.t_s.to_numpy() / 0.05).astype(int)
    np.testing.assert_allclose(rec.y_m.to_numpy(), a.other_y_m[k, j], atol=1e-12)
    fs = r.final_state
    assert fs.sec_count[0] == 1 and {fs.sec_striker[0], fs.sec_struck[0]} == {0, 2 + j}
    # walking by the social force it stops short of the car's side and lets it pass
    ego = fr[(fr.variant == 1) & (fr.agent_id == "ego")].set_index("t_s")
    passing = sim[(ego.loc[sim.t_s, "x_m"].to_numpy() > 30.0 - 2.35 - 0.3)
                  & (ego.loc[sim.t_s, "x_m"].to_numpy() < 30.0 + 2.35 + 0.3)]  # fmt: skip
    assert (passing.y_m < -0.925 - 0.3).all()  # never touches the car's side
    assert passing.speed_mps.min() < 0.3
    assert fs.sec_count[1] == 0
    # ... and walks on afterwards at its own speed, on its path (x = 30)
    late = sim[sim.t_s >= 9.0]
    assert late.speed_mps.iloc[-1] == pytest.approx(1.3, abs=0.05)
    assert np.abs(late.x_m - 30.0).max() < 0.3


def test_the_compiled_kernel_runs_pedestrians_on_the_numpy_step(run) -> None:
    pytest.importorskip("numba")
    a, r = run
    params = r.params
    rn = simulate(a, params, kernel="numba")
    assert rn.ped_x_m is not None
    np.testing.assert_array_equal(rn.ped_y_m, r.ped_y_m)
