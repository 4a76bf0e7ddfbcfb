"""The V2X channel against 3GPP TR 37.885 by hand: path loss of the LOS / NLOSv / NLOS
states (Table 6.2.1-1), the vehicle blockage cases (clause 6.2.1), the link budget of each
technology (one allocation), delivery at the occluded crossing's distances, statistics of
the delivery draws, a measured table in place of the budget, latency."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vei.config.v2x import V2XConfig
from vei.policy.v2x import channel as ch
from vei.policy.v2x import model

LOG_FC = math.log10(5.9)  # 0.7708520


def world(b: int, rider_xy, ego_xy=(0.0, 0.0), boxes=(), buildings=None):
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
        ego_x_m=np.full(b, ego_xy[0]), ego_y_m=np.full(b, ego_xy[1]), buildings=buildings,
    )  # fmt: skip


def first_step(cfg: V2XConfig, w: model.World, b: int, seed_keys=None):
    """Events of step 0 (every equipped rider sends its first VAM)."""
    keys = np.arange(b) if seed_keys is None else seed_keys
    params = model.V2XParams.from_config(cfg, b)
    st = model.init_state(cfg, params, keys, np.array([0]))
    _, _, ev = model.step(cfg, params, st, w, np.array([0]), 0, 0.05, keys)
    return ev


def phi(z: float) -> float:
    return 0.5 * (1.0 + math.erf(z / math.sqrt(2.0)))


# ------------------------------------------------------------------ TR 37.885 by hand
def test_path_loss_laws_of_table_6_2_1_1_by_hand():
    # urban LOS at 60 m: 38.77 + 16.7 x 1.7781513 + 18.2 x 0.7708520 = 82.4946 dB
    assert ch.pathloss_los_db(60.0) == pytest.approx(82.4946, abs=1e-4)
    # highway LOS at 100 m: 32.4 + 20 x 2 + 20 x 0.7708520 = 87.8170 dB
    assert ch.pathloss_los_db(100.0, "highway") == pytest.approx(87.8170, abs=1e-4)
    # urban NLOS at 100 m: 36.85 + 30 x 2 + 18.9 x 0.7708520 = 111.4191 dB
    assert ch.pathloss_nlos_db(100.0) == pytest.approx(111.4191, abs=1e-4)
    # NLOSv = LOS + blockage
    got = ch.path_loss_db(np.array([60.0, 60.0, 60.0]), np.array([ch.LOS, ch.NLOSV, ch.NLOS]),
                          blockage_db=9.0)  # fmt: skip
    assert got == pytest.approx([82.4946, 91.4946, 36.85 + 30 * math.log10(60) + 18.9 * LOG_FC],
                                abs=1e-4)  # fmt: skip
    assert ch.SHADOWING_STD_DB == (3.0, 3.0, 4.0)


@pytest.mark.parametrize(
    ("blocker_m", "mean_db", "std_db"),
    [(3.0, 9.0, 4.5),  # a truck, bus or van above both antennas (1.5, 1.6 m): case 2
     (1.6, 5.0, 4.0),  # a car as tall as the car's antenna: case 3 (not strictly above)
     (1.55, 5.0, 4.0),  # between the antennas: case 3
     (1.4, 0.0, 0.0)],  # below both: case 1
)  # fmt: skip
def test_blockage_cases_of_clause_6_2_1(blocker_m, mean_db, std_db):
    mean, std = ch.blockage_stats_db(np.array([60.0]), 1.5, 1.6, np.array([blocker_m]))
    assert (mean[0], std[0]) == pytest.approx((mean_db, std_db))


def test_blockage_grows_beyond_543_m():
    # 15 log10(1000) - 41 = 4 dB on top of case 2's 9 dB; 0 below 10^(41/15) = 543.4 m
    mean, _ = ch.blockage_stats_db(np.array([1000.0, 500.0]), 1.5, 1.6, np.array([3.0, 3.0]))
    assert mean == pytest.approx([13.0, 9.0])
    assert ch.blockage_loss(9.0, 4.5, np.array([-3.0, -1.0, 0.0, 1.0])) == pytest.approx(
        [0.0, 4.5, 9.0, 13.5]
    )


def test_each_technology_has_one_allocation():
    its = ch.LINK_BUDGET["its-g5"]
    # -174 dBm/Hz + 10 log10(10 MHz) + 9 dB = -95 dBm; 23 + 0 + 3 + 95 - 5.92 = 115.08 dB
    assert its.noise_dbm == pytest.approx(-95.0)
    assert its.max_path_loss_db == pytest.approx(115.08)
    pc5 = ch.LINK_BUDGET["c-v2x-pc5"]
    # 40 PRBs carry 350 bytes at MCS 4 (TBS 2856 bits); R = 2856 / (40 x 12 x 9 x 2) =
    # 0.330556, eta = 12 x 14 x 2 x R / 180 = 0.617037 b/s/Hz, SNR = 2^(eta / 0.4) - 1 =
    # 1.91350 = 2.818 dB; the noise over the same 40 PRBs: 7.2 MHz
    assert ch.pc5_snr_threshold_db() == pytest.approx(2.818, abs=1e-3)
    assert pc5.snr_10_db == pytest.approx(2.82) and pc5.bandwidth_hz == pytest.approx(7.2e6)
    assert pc5.noise_dbm == pytest.approx(-174.0 + 68.5733 + 9.0, abs=1e-4)
    assert pc5.max_path_loss_db == pytest.approx(26.0 + 96.4267 - 2.82, abs=1e-4)
    # the former 20-PRB noise bandwidth would need a threshold fitting 20 PRBs: at MCS 4
    # 20 PRBs carry 1416 bits only, so the one allocation is 40 PRBs
    assert ch.PC5_PRBS * ch.PRB_HZ == pc5.bandwidth_hz


def test_delivery_against_los_and_nlosv_curves_by_hand():
    d = np.array([60.0, 80.0])
    # The occluded crossing, ITS-G5, NLOSv at the mean 9 dB: SNR = 26 + 95 - (PL_LOS + 9):
    # 29.51 dB at 60 m, 27.42 dB at 80 m; (SNR - 5.92) / 3 > 7: delivery 1.0 (the corner
    # law of the former tables gave 0.63 and 0.28)
    got = ch.link_pdr(d, np.full(2, ch.NLOSV), "its-g5", blockage_db=9.0)
    assert got == pytest.approx([1.0, 1.0], abs=1e-9)
    # A distance where the NLOSv curve falls: 1000 m, case 2 mean 9 + 4 dB: PL = 38.77 +
    # 50.1 + 14.0295 + 13 = 115.8995, SNR = 5.1005, z = (5.1005 - 5.92) / 3 = -0.27317
    p = ch.link_pdr(np.array([1000.0]), np.array([ch.NLOSV]), "its-g5", blockage_db=13.0)
    assert p[0] == pytest.approx(phi(-0.27317), abs=1e-4)
    assert p[0] == pytest.approx(0.3924, abs=1e-4)
    # LOS at 3545 m: PL = 52.7995 + 16.7 x 3.54962 = 112.0782 = 115.08 - 3: one sigma
    p = ch.link_pdr(np.array([3545.0]), np.array([ch.LOS]), "its-g5")
    assert p[0] == pytest.approx(phi(1.0), abs=1e-3)
    # NLOS (a building) at 100 m: SNR = 121 - 111.4191 = 9.5809, z = 3.6609 / 4 = 0.91523
    p = ch.link_pdr(np.array([100.0]), np.array([ch.NLOS]), "its-g5")
    assert p[0] == pytest.approx(0.8200, abs=1e-4)
    # PC5 NLOS at 200 m: PL = 36.85 + 69.0309 + 14.5691 = 120.4500; SNR = 26 + 96.4267 -
    # 120.45 = 1.9767; z = (1.9767 - 2.82) / 4 = -0.21083
    p = ch.link_pdr(np.array([200.0]), np.array([ch.NLOS]), "c-v2x-pc5")
    assert p[0] == pytest.approx(phi(-0.21083), abs=1e-4)


# ------------------------------------------------------------------ the model's links
def test_the_occluded_crossing_link_is_nlosv_case_2_and_delivered():
    # the study's geometry: rider at (60, -2.2), a 5.9 x 2.1 van at (56, -2.5), the car at
    # (0, 0) and (-20, 0): the van blocks the line (a truck / van: case 2)
    van = (56.0, -2.5, 0.0, 5.9, 2.1, "vehicle")
    for ego_x in (0.0, -20.0):
        w = world(4000, (60.0, -2.2), ego_xy=(ego_x, 0.0), boxes=[van])
        ev = first_step(V2XConfig(enabled=True, position_error_std_m=0.0), w, 4000)
        assert (ev["link"][:, 0] == ch.NLOSV).all() and ev["blocked"].all()
        # the blockage draws: max(0, N(9, 4.5)); the mean 9.3 (clipped at 0)
        loss = ev["loss_db"][:, 0]
        assert loss.min() >= 0.0 and loss.mean() == pytest.approx(9.0, abs=0.3)
        # delivery 1.0 at the mean loss; over the draws only losses beyond ~20 dB (z >
        # 2.4) cost a little
        assert ev["pdr"][:, 0].mean() > 0.995 and ev["delivered"].mean() > 0.995
        assert np.median(ev["pdr"][:, 0]) == pytest.approx(1.0, abs=1e-6)


def test_a_passenger_car_blocks_with_case_3():
    car = (10.0, 0.0, 0.0, 4.7, 1.85, "vehicle")
    w = world(4000, (20.0, 0.0), boxes=[car])
    ev = first_step(V2XConfig(enabled=True, position_error_std_m=0.0), w, 4000)
    loss = ev["loss_db"][:, 0]
    # case 3: max(0, N(5, 4)): mean 5 + 4 phi(1.25) - 5 Phi(-1.25) = 5.1 dB
    mean = 5.0 * (1 - phi(-1.25)) + 4.0 * math.exp(-0.5 * 1.25**2) / math.sqrt(2 * math.pi)
    assert loss.mean() == pytest.approx(mean, abs=0.2)


def test_nlosv_delivery_share_matches_the_tr_curve_over_20000_draws():
    # Far enough for the NLOSv curve to fall (ITS-G5, case 2 at 1200 m): the share of
    # delivered VAMs is E[Phi((SNR_LOS - max(0, 9 + far + 4.5 z) - 5.92) / 3)]
    b = 20_000
    van = (600.0, 0.0, 0.0, 8.0, 2.5, "vehicle")
    w = world(b, (1200.0, 0.0), boxes=[van])
    ev = first_step(V2XConfig(enabled=True, position_error_std_m=0.0), w, b)
    assert (ev["link"][:, 0] == ch.NLOSV).all()
    d3 = math.hypot(1200.0, 0.1)
    far = 15 * math.log10(d3) - 41.0
    snr = 26.0 + 95.0 - (38.77 + 16.7 * math.log10(d3) + 18.2 * LOG_FC)
    z = np.linspace(-8, 8, 16001)
    w_z = np.exp(-0.5 * z * z) / math.sqrt(2 * math.pi) * (z[1] - z[0])
    loss = np.maximum(0.0, 9.0 + far + 4.5 * z)
    expected = float(np.sum(w_z * np.vectorize(phi)((snr - loss - 5.92) / 3.0)))
    assert 0.2 < expected < 0.8
    share = ev["delivered"].mean()
    assert abs(share - expected) <= 4 * math.sqrt(expected * (1 - expected) / b), (share, expected)


@pytest.mark.parametrize(
    ("technology", "distance_m", "factor"),
    [("its-g5", 3000.0, 1.0), ("its-g5", 4500.0, 0.5), ("c-v2x-pc5", 6000.0, 0.7)],
)  # fmt: skip
def test_los_delivery_matches_the_link_budget_within_4_sigma(technology, distance_m, factor):
    b = 10_000
    cfg = V2XConfig(enabled=True, technology=technology, pdr_factor=factor,
                    position_error_std_m=0.0)  # fmt: skip
    ev = first_step(cfg, world(b, (distance_m, 0.0)), b)
    assert ev["sent"].all() and (ev["link"][:, 0] == ch.LOS).all()
    p = factor * float(ch.link_pdr(np.array([distance_m]), np.array([ch.LOS]), technology)[0])
    assert ev["pdr"][:, 0] == pytest.approx(p, abs=1e-12)
    share = ev["delivered"].mean()
    assert abs(share - p) <= 4 * math.sqrt(p * (1 - p) / b), (share, p)


def test_highway_los_is_shorter_than_urban():
    u = ch.link_pdr(np.array([2500.0]), np.array([ch.LOS]), "its-g5")[0]
    h = ch.link_pdr(np.array([2500.0]), np.array([ch.LOS]), "its-g5", environment="highway")[0]
    # highway: PL = 47.817 + 20 log10(2500) = 115.776 > 115.08: below one half; urban:
    # 52.7995 + 16.7 log10(2500) = 109.545, z = (115.08 - 109.545) / 3 = 1.845
    assert h == pytest.approx(phi((115.08 - 115.7764) / 3.0), abs=1e-3)
    assert u == pytest.approx(phi(1.845), abs=1e-3)


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
def test_a_given_table_is_the_los_curve_and_blocked_links_read_farther(box_y, category, blocked):
    # Rider at (20, 0), car at (0, 0); a 4.7 x 1.85 box at (10, box_y) along x blocks the
    # straight line y = 0 iff |box_y| < 1.85 / 2 = 0.925. Table PDR(d) = 1 - d / 100 and a
    # fixed 9 dB loss: a blocked link is read at 20 x 10^(9 / 16.7) (the urban LOS slope)
    # = 69.18 m.
    cfg = V2XConfig(enabled=True, pdr_distance_m=[0, 100], pdr=[1.0, 0.0],
                    nlos_loss_db=9.0, nlos_loss_std_db=0.0, position_error_std_m=0.0)  # fmt: skip
    w = world(3, (20.0, 0.0), boxes=[(10.0, box_y, 0.0, 4.7, 1.85, category)])
    ev = first_step(cfg, w, 3)
    assert bool(ev["blocked"][0, 0]) is blocked
    d_eff = 20.0 * 10 ** (9.0 / 16.7) if blocked else 20.0
    assert ev["pdr"][:, 0] == pytest.approx(1.0 - d_eff / 100.0, abs=1e-12)
    off = first_step(V2XConfig(enabled=True, pdr_distance_m=[0, 100], pdr=[1.0, 0.0],
                               nlos=False, position_error_std_m=0.0), w, 3)  # fmt: skip
    assert not off["blocked"].any() and off["pdr"][:, 0] == pytest.approx(0.8)
    slope = first_step(V2XConfig(enabled=True, pdr_distance_m=[0, 100], pdr=[1.0, 0.0],
                                 nlos_loss_db=9.0, nlos_loss_std_db=0.0,
                                 pdr_slope_db_per_decade=30.0, position_error_std_m=0.0), w, 3)  # fmt: skip
    d_eff = 20.0 * 10 ** (9.0 / 30.0) if blocked else 20.0
    assert slope["pdr"][:, 0] == pytest.approx(1.0 - d_eff / 100.0, abs=1e-12)


def test_a_replaced_table_is_interpolated_linearly_and_held():
    cfg = V2XConfig(enabled=True, pdr_distance_m=[0, 100], pdr=[1.0, 0.0],
                    position_error_std_m=0.0)  # fmt: skip
    ev = first_step(cfg, world(4, (25.0, 0.0)), 4)
    assert ev["pdr"][:, 0] == pytest.approx(0.75)
    cfg = V2XConfig(enabled=True, pdr_distance_m=[0, 10], pdr=[0.9, 0.2])
    ev = first_step(cfg, world(2, (40.0, 0.0)), 2)
    assert ev["pdr"][:, 0] == pytest.approx(0.2)  # held beyond the last distance


def test_a_box_holding_an_end_of_the_link_does_not_block():
    from vei.policy.v2x.links import links_blocked

    # A van around the rider (rider inside its box) or around the car: ignored.
    assert not links_blocked(
        np.array([20.0]), np.array([0.0]), np.array([0.0]), np.array([0.0]),
        np.array([[20.0, 0.5]]), np.array([[0.0, 0.0]]), np.zeros((1, 2)),
        np.array([[4.0, 4.0]]), np.array([[2.0, 2.0]]), np.ones((1, 2), bool),
    )[0]  # fmt: skip


def test_latency_distributions_and_the_pc5_default():
    u = (np.arange(100_000) + 0.5) / 100_000
    fixed, jitter, dist = V2XConfig(technology="c-v2x-pc5").latency
    uni = ch.latency(u, np.full(u.size, fixed), np.full(u.size, jitter), dist)
    assert uni.min() >= 0.001 and uni.max() <= 0.045
    # mean 23 ms: ITS-G5's 3 ms plus the 20 ms of the field comparison (docs/v2x.md)
    assert uni.mean() == pytest.approx(0.023, abs=1e-4)
    ex = ch.latency(u, np.full(u.size, 0.001), np.full(u.size, 0.002), "exponential")
    # Exp(mean 2 ms) truncated at 10 means: mean 2 ms * (1 - 11 e^-10) / (1 - e^-10)
    trunc_mean = 0.002 * (1 - 11 * math.exp(-10)) / (1 - math.exp(-10))
    assert ex.mean() == pytest.approx(0.001 + trunc_mean, rel=1e-3)
    assert ex.max() <= ch.latency_bound(0.001, 0.002, "exponential") + 1e-15
    assert np.median(ex) == pytest.approx(0.001 + 0.002 * math.log(2), rel=1e-3)
    assert uni.mean() / ex.mean() == pytest.approx(23.0 / 3.0, rel=2e-3)
