import numpy as np
import pytest

from vei.recon.threat import ThreatFigures, primary_threat, threat_figures

RATE = 20.0


def _ego():
    # Ego along +x at 5 m/s for 20 s, from x = 0.
    t = np.arange(0, 401) / RATE
    xy = np.column_stack([5.0 * t, np.zeros(t.size)])
    return t, xy, np.zeros(t.size), np.full(t.size, 5.0)


def test_crossing_rider_pet_and_distance_hand_values():
    t_e, xy_e, yaw_e, v_e = _ego()
    # Rider crosses the ego path at x = 50 m going north at 2 m/s, at t = 12 s; the ego is
    # at x = 50 at t = 10 s: PET = 2 s.
    t_r = np.arange(8 * 20, 16 * 20 + 1) / RATE
    xy_r = np.column_stack([np.full(t_r.size, 50.0), 2.0 * (t_r - 12.0)])
    f = threat_figures("escooter_1", t_r, xy_r, t_e, xy_e, yaw_e, v_e, corridor_half_width_m=2.0)
    assert f.conflict
    assert f.path_distance_m == pytest.approx(0.0, abs=1e-9)
    # Inside the corridor |y| <= 2 m from t = 11 to 13 s; the ego passes x = 50 at 10 s.
    assert f.pet_s == pytest.approx(1.0, abs=1e-9)
    # Same-time gap: at time t the ego is at 5t, the rider at (50, 2(t-12)).
    tt = t_r
    gap = np.hypot(50.0 - 5.0 * tt, 2.0 * (tt - 12.0))
    assert f.min_gap_m == pytest.approx(gap.min(), abs=1e-9)
    # Paper TTC D / v_ego while the rider is ahead and inside the corridor (t in [11, 13],
    # ego already past 50 m after t = 10 s): never ahead -> inf.
    assert f.min_ttc_paper_s == np.inf


def test_primary_threat_prefers_conflict_then_smaller_pet():
    t_e, xy_e, yaw_e, v_e = _ego()
    t_r = np.arange(0, 401) / RATE
    # A: parallel 3 m to the left, riding along with the ego (close, never in the corridor).
    xy_a = np.column_stack([5.0 * t_r + 5.0, np.full(t_r.size, 3.0)])
    # B: crosses x = 60 m going north at 1 m/s, y = t - 20: inside the 2 m corridor for
    # t in [18, 20] s; the ego passes x = 60 at 12 s: PET = 6 s.
    xy_b = np.column_stack([np.full(t_r.size, 60.0), 1.0 * (t_r - 20.0)])
    # C: crosses x = 30 m, y = t - 6.5: inside for t in [4.5, 8.5]; ego at x = 30 at 6 s: PET 0.
    xy_c = np.column_stack([np.full(t_r.size, 30.0), 1.0 * (t_r - 6.5)])
    figs = [
        threat_figures(name, t_r, xy, t_e, xy_e, yaw_e, v_e, 2.0)
        for name, xy in (("a", xy_a), ("b", xy_b), ("c", xy_c))
    ]
    assert [f.conflict for f in figs] == [False, True, True]
    assert figs[0].min_gap_m == pytest.approx(np.hypot(5.0, 3.0))
    assert figs[1].pet_s == pytest.approx(6.0, abs=1e-9)
    assert figs[2].pet_s == pytest.approx(0.0, abs=1e-9)
    # C at t = 6 s: ego (30, 0), rider (30, -0.5).
    assert figs[2].min_gap_m == pytest.approx(0.5, abs=1e-9)
    assert primary_threat(figs) == "c"
    # Among conflicting riders the PET decides, not the gap: B beats a far, later rider.
    assert primary_threat([figs[0], figs[1]]) == "b"
    # Without conflicts, the closest same-time gap wins.
    assert primary_threat([figs[0], ThreatFigures("z", 9.0, False, np.inf, 4.0, np.inf)]) == "z"
    assert primary_threat([]) is None


def test_paper_ttc_for_a_rider_standing_ahead_in_the_corridor():
    t_e, xy_e, yaw_e, v_e = _ego()
    t_r = np.arange(0, 201) / RATE
    xy_r = np.column_stack([np.full(t_r.size, 80.0), np.full(t_r.size, 1.0)])
    f = threat_figures("s", t_r, xy_r, t_e, xy_e, yaw_e, v_e, 2.0)
    # At t = 10 s (last common sample) the ego is at 50 m: D = hypot(30, 1), TTC = D / 5.
    assert f.min_ttc_paper_s == pytest.approx(np.hypot(30.0, 1.0) / 5.0)
    assert f.path_distance_m == pytest.approx(1.0)
    assert f.as_dict()["pet_s"] is not None


def test_escooters_come_before_cyclists_among_conflicting_riders():
    cyc = ThreatFigures("cyclist_1", 0.1, True, 0.5, 3.0, 1.0, "cyclist")
    esc = ThreatFigures("escooter_2", 1.5, True, 9.0, 8.0, np.inf, "escooter")
    far_esc = ThreatFigures("escooter_3", 15.0, False, np.inf, 1.0, np.inf, "escooter")
    # The conflicting e-scooter wins although the cyclist's PET is smaller.
    assert primary_threat([cyc, esc, far_esc]) == "escooter_2"
    # A non-conflicting e-scooter does not beat a conflicting cyclist.
    assert primary_threat([cyc, far_esc]) == "cyclist_1"
    # Without conflicts: the smallest same-time gap, e-scooters first among equal gaps.
    a = ThreatFigures("cyclist_4", 5.0, False, np.inf, 2.0, np.inf, "cyclist")
    b = ThreatFigures("escooter_5", 6.0, False, np.inf, 2.0, np.inf, "escooter")
    assert primary_threat([a, b]) == "escooter_5"
    assert b.as_dict()["category"] == "escooter"


def test_resolve_threat_by_agent_or_track_id_and_clear_errors():
    from vei.errors import InputError
    from vei.recon.threat import resolve_threat, with_threat
    from vei.sim.testing import crossing_scenario

    riders = {"escooter_78": ("escooter", "78"), "cyclist_60": ("cyclist", "60")}
    assert resolve_threat("escooter_78", riders, "s") == "escooter_78"
    assert resolve_threat("60", riders, "s") == "cyclist_60"
    with pytest.raises(InputError, match=r"'99' is not a rider.*cyclist_60 \(track 60\)"):
        resolve_threat("99", riders, "s")
    sc = crossing_scenario()
    rider = sc.primary_threat
    assert with_threat(sc, None) is sc
    chosen = with_threat(sc, rider)
    assert chosen.primary_threat == rider and chosen.extra["threat"]["chosen_by"] == "user"
    with pytest.raises(InputError, match="field 'threat'"):
        with_threat(sc, "ego")
