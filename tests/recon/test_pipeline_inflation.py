"""ReconstructionConfig.posterior_std_inflation: validated, 'calibrated' = the fitted
factor for ML noise (1 for a fixed noise), and a number scales the reported posterior std
and the spread of the posterior samples by exactly that factor (the mean is unchanged)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from vei.errors import ConfigError
from vei.experiments.demo_data import demo_interaction
from vei.recon.calibration import POSTERIOR_STD_INFLATION
from vei.recon.pipeline import ReconstructionConfig, reconstruct
from vei.recon.samples import sample_rider


@pytest.fixture(scope="module")
def scenarios():
    inter = demo_interaction()
    return {
        c: reconstruct(inter, ReconstructionConfig(interp="kalman", posterior_std_inflation=c))
        for c in (1.0, 2.0, "calibrated")
    }


@pytest.mark.parametrize("bad", [0, -1.0, math.nan, math.inf, True, "wide", None])
def test_invalid_inflation_is_a_config_error(bad) -> None:
    with pytest.raises(ConfigError, match="posterior_std_inflation"):
        ReconstructionConfig(posterior_std_inflation=bad)


def test_calibrated_is_the_fitted_factor_for_ml_noise_only() -> None:
    cal = ReconstructionConfig()
    assert cal.posterior_std_inflation == "calibrated"
    assert cal.std_inflation("ml") == POSTERIOR_STD_INFLATION == 1.461
    assert cal.std_inflation("fixed") == 1.0
    one = ReconstructionConfig(posterior_std_inflation=1.3)
    assert one.std_inflation("ml") == one.std_inflation("fixed") == 1.3
    fixed = reconstruct(
        demo_interaction(),
        ReconstructionConfig(interp="kalman", noise_estimate="fixed", posterior_std_inflation=1.7),
    )
    assert fixed.extra["reconstruction"]["noise"]["std_inflation"] == 1.7


def test_inflation_scales_the_reported_std_and_the_samples_spread(scenarios) -> None:
    one, two, cal = scenarios[1.0], scenarios[2.0], scenarios["calibrated"]
    assert [s.extra["reconstruction"]["noise"]["std_inflation"] for s in (one, two, cal)] == [
        1.0,
        2.0,
        POSTERIOR_STD_INFLATION,
    ]
    pd.testing.assert_frame_equal(one.trajectories, two.trajectories)  # the mean: unchanged
    std = {k: s.extra["reconstruction"]["tracks"][0]["std_m"] for k, s in scenarios.items()}
    for key in ("mean", "max"):
        assert std[2.0][key] == pytest.approx(2.0 * std[1.0][key], rel=1e-12)
        assert std["calibrated"][key] == pytest.approx(1.461 * std[1.0][key], rel=1e-12)
    # Same seed: every sample's deviation from the mean path is scaled by the factor.
    a, b, c = (sample_rider(s, 40, seed=3) for s in (one, two, cal))
    mean = one.trajectories[one.trajectories["agent_id"] == a.agent_id][["x_m", "y_m"]].to_numpy(
        np.float64
    )
    dev_a, dev_b, dev_c = (s.xy_m - mean for s in (a, b, c))
    assert np.abs(dev_a).max() > 0.01  # the samples do spread
    np.testing.assert_allclose(dev_b, 2.0 * dev_a, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(dev_c, 1.461 * dev_a, rtol=1e-9, atol=1e-12)
    ratio = np.std(b.xy_m, axis=0).mean() / np.std(a.xy_m, axis=0).mean()
    assert ratio == pytest.approx(2.0, rel=1e-9)
