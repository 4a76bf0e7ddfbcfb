"""The V2X channel: delivery against the configured table (statistics), the blockage
penalty exactly when a vehicle's box blocks the line (hand-built geometry), latency."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vei.config.v2x import DEFAULT_PDR, DEFAULT_PDR_DISTANCE_M, V2XConfig
from vei.policy.v2x import channel as ch
from vei.policy.v2x import model


def world(b: int, rider_xy, ego_xy=(0.0, 0.0), boxes=()):
    """b variants: one rider (index 0) and the given boxes (x, y, yaw, l, w, category)."""
    n = 1 + len(boxes)
    x = np.zeros((b, n))
    y = np.zeros((b, n))
    yaw = np.zeros((b, n))
    length = np.array([1.2] + [bx[3] for bx in boxes])
    width = np.array([0.6] + [bx[4] for bx in boxes])
    x[:, 0], y[:, 0] = rider_xy
    for j, bx in enumerate(boxes, start=1):
        x[:, j], y[:, j], yaw[:, j] = bx[0], bx[1], bx[2]
    veh = np.array([False] + [bx[5] == "vehicle" for bx in boxes])
    return model.World(
        x_m=x, y_m=y, yaw_rad=yaw, vx_mps=np.zeros((b, n)), vy_mps=np.zeros((b, n)),
        valid=np.ones((b, n), bool), length_m=length, width_m=width, is_vehicle=veh,
        ego_x_m=np.full(b, ego_xy[0]), ego_y_m=np.full(b, ego_xy[1]),
    )  # fmt: skip


def first_step(cfg: V2XConfig, w: model.World, b: int, seed_keys=None):
    """Events of step 0 (every equipped rider sends its first VAM)."""
    keys = np.arange(b) if seed_keys is None else seed_keys
    params = model.V2XParams.from_config(cfg, b)
    st = model.init_state(cfg, params, keys, np.array([0]))
    _, _, ev = model.step(cfg, params, st, w, np.array([0]), 0, 0.05, keys)
    return ev


@pytest.mark.parametrize(
    ("technology", "distance_m", "factor"),
    [("its-g5", 100.0, 1.0), ("its-g5", 150.0, 1.0), ("c-v2x-pc5", 200.0, 1.0),
     ("its-g5", 30.0, 0.5), ("c-v2x-pc5", 250.0, 0.7)],
)  # fmt: skip
def test_delivery_matches_the_table_within_4_sigma_over_10000_draws(technology, distance_m, factor):
    b = 10_000
    cfg = V2XConfig(enabled=True, technology=technology, pdr_factor=factor, nlos=False,
                    position_error_std_m=0.0)  # fmt: skip
    ev = first_step(cfg, world(b, (distance_m, 0.0)), b)
    assert ev["sent"].all()
    p = factor * float(np.interp(distance_m, DEFAULT_PDR_DISTANCE_M, DEFAULT_PDR[technology]))
    assert ev["pdr"][:, 0] == pytest.approx(p, abs=1e-12)
    share = ev["delivered"].mean()
    sigma = math.sqrt(p * (1 - p) / b)
    assert abs(share - p) <= 4 * sigma, (share, p, sigma)


def test_a_replaced_table_is_used_and_interpolated_linearly():
    cfg = V2XConfig(enabled=True, pdr_distance_m=[0, 100], pdr=[1.0, 0.0], nlos=False,
                    position_error_std_m=0.0)  # fmt: skip
    ev = first_step(cfg, world(4, (25.0, 0.0)), 4)
    assert ev["pdr"][:, 0] == pytest.approx(0.75)
    cfg = V2XConfig(enabled=True, pdr_distance_m=[0, 10], pdr=[0.9, 0.2], nlos=False)
    ev = first_step(cfg, world(2, (40.0, 0.0)), 2)
    assert ev["pdr"][:, 0] == pytest.approx(0.2)  # held beyond the last distance


@pytest.mark.parametrize(
    ("box_y", "category", "blocked"),
    [
        (0.0, "vehicle", True),  # across the line
        (0.9, "vehicle", True),  # its lower edge at y = -0.025: 2.5 cm over the line
        (0.924, "vehicle", True),  # 1 mm over
        (0.926, "vehicle", False),  # 1 mm clear
        (1.0, "vehicle", False),
        (-0.9, "vehicle", True),
        (0.0, "pedestrian", False),  # a person's box does not block the radio
        (0.0, "cyclist", False),
    ],
)
def test_blockage_applies_exactly_when_a_vehicle_box_crosses_the_line(box_y, category, blocked):
    # Rider at (20, 0), car at (0, 0); a 4.7 x 1.85 box at (10, box_y) along x blocks the
    # straight line y = 0 iff |box_y| < 1.85 / 2 = 0.925. Table PDR(d) = 1 - d / 100 and a
    # fixed 9 dB loss: a blocked link is read at 20 * 10^(9 / 30) = 39.905 m.
    cfg = V2XConfig(enabled=True, pdr_distance_m=[0, 100], pdr=[1.0, 0.0],
                    nlos_loss_db=9.0, nlos_loss_std_db=0.0, position_error_std_m=0.0)  # fmt: skip
    w = world(3, (20.0, 0.0), boxes=[(10.0, box_y, 0.0, 4.7, 1.85, category)])
    ev = first_step(cfg, w, 3)
    assert bool(ev["blocked"][0, 0]) is blocked
    d_eff = 20.0 * 10 ** (9.0 / 30.0) if blocked else 20.0
    assert ev["pdr"][:, 0] == pytest.approx(1.0 - d_eff / 100.0, abs=1e-12)
    off = first_step(V2XConfig(enabled=True, pdr_distance_m=[0, 100], pdr=[1.0, 0.0],
                               nlos=False, position_error_std_m=0.0), w, 3)  # fmt: skip
    assert not off["blocked"].any() and off["pdr"][:, 0] == pytest.approx(0.8)


def test_a_box_holding_an_end_of_the_link_does_not_block():
    # A van around the rider (rider inside its box) or around the car: ignored.
    assert not ch.links_blocked(
        np.array([20.0]), np.array([0.0]), np.array([0.0]), np.array([0.0]),
        np.array([[20.0, 0.5]]), np.array([[0.0, 0.0]]), np.zeros((1, 2)),
        np.array([[4.0, 4.0]]), np.array([[2.0, 2.0]]), np.ones((1, 2), bool),
    )[0]  # fmt: skip


def test_blockage_loss_is_clipped_normal_and_moves_the_link_farther():
    z = np.array([-3.0, -1.0, 0.0, 1.0])
    assert ch.blockage_loss(9.0, 4.5, z) == pytest.approx([0.0, 4.5, 9.0, 13.5])
    assert ch.effective_distance(10.0, 30.0, 30.0) == pytest.approx(100.0)


def test_latency_distributions():
    u = (np.arange(100_000) + 0.5) / 100_000
    uni = ch.latency(u, np.full(u.size, 0.001), np.full(u.size, 0.1), "uniform")
    assert uni.min() >= 0.001 and uni.max() <= 0.101
    assert uni.mean() == pytest.approx(0.051, abs=1e-4)
    ex = ch.latency(u, np.full(u.size, 0.001), np.full(u.size, 0.002), "exponential")
    # Exp(mean 2 ms) truncated at 10 means: mean 2 ms * (1 - 11 e^-10) / (1 - e^-10)
    trunc_mean = 0.002 * (1 - 11 * math.exp(-10)) / (1 - math.exp(-10))
    assert ex.mean() == pytest.approx(0.001 + trunc_mean, rel=1e-3)
    assert ex.max() <= ch.latency_bound(0.001, 0.002, "exponential") + 1e-15
    assert np.median(ex) == pytest.approx(0.001 + 0.002 * math.log(2), rel=1e-3)


def test_the_default_tables_are_the_link_budget_calculation():
    for tech, table in DEFAULT_PDR.items():
        got = ch.link_budget_pdr(np.array(DEFAULT_PDR_DISTANCE_M), tech)
        assert np.round(got, 3) == pytest.approx(np.array(table), abs=1e-12), tech
        assert np.all(np.diff(table) <= 0)
