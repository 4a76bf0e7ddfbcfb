import math

import pytest

from vei.metrics.kinematics import ego_speed_mean, ego_speed_min, ego_speed_std, peak_deceleration

from .helpers import make_trace


def test_peak_deceleration_ignores_the_crash_step():
    tr = make_trace(
        ego_xy=[0.0, 0.0],
        other_xy=[50.0, 0.0],
        ego_speed=[5.0, 4.9, 4.6, 4.4, 4.4, 0.0],
        ego_accel=[0.0, -1.0, -3.0, -2.0, 0.0, -88.0],
        collided=[False] * 5 + [True],
    )
    assert peak_deceleration(tr)[0] == pytest.approx(3.0)
    never = make_trace(ego_xy=[0.0, 0.0], other_xy=[50.0, 0.0], ego_speed=5.0, ego_accel=[0.5, 0.2])
    assert peak_deceleration(never)[0] == 0.0


def test_speed_statistics_population_std():
    tr = make_trace(ego_xy=[0.0, 0.0], other_xy=[50.0, 0.0], ego_speed=[5.0, 5.0, 5.0, 0.0])
    # mean 3.75; deviations 1.25 x3 and 3.75: var = (3 * 1.5625 + 14.0625) / 4 = 4.6875
    assert ego_speed_std(tr)[0] == pytest.approx(math.sqrt(4.6875))
    assert ego_speed_mean(tr)[0] == pytest.approx(3.75)
    assert ego_speed_min(tr)[0] == 0.0
