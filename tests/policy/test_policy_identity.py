"""Built-in policies: equal parameters compare and hash equal (a set / dict keeps one),
different ones differ; AEB and IDM share their construction and bind (ConfiguredPolicy)."""

from __future__ import annotations

import numpy as np
import pytest

from vei.config import CaseConfig, EgoConfig
from vei.errors import ConfigError
from vei.policy.aeb import AEB, AEBConfig
from vei.policy.builtin import PaperCAP, PIDCruise
from vei.policy.idm import IDM, IDMConfig
from vei.sim.engine import prepare_scenario
from vei.sim.params import VariantParams
from vei.sim.testing import standing_rider_scenario


@pytest.mark.parametrize(
    ("make", "other"),
    [
        (PIDCruise, lambda: PIDCruise(kp=0.2)),
        (PaperCAP, lambda: PaperCAP(paper_per_step=True)),
        (AEB, lambda: AEB(ttc_full_s=0.5)),
        (IDM, lambda: IDM(time_headway_s=1.5)),
    ],
)
def test_equal_policies_hash_equal(make, other) -> None:
    a, b, c = make(), make(), other()
    assert a is not b and a == b and hash(a) == hash(b)
    assert len({a, b}) == 1 and {a: 1}[b] == 1
    assert a != c and len({a, c}) == 2


def test_bound_policies_hash_by_their_per_variant_values() -> None:
    arrays = prepare_scenario(standing_rider_scenario(duration_s=2.0))
    case = CaseConfig(name="x", rider="replay", ego=EgoConfig(policy="aeb"))
    p2 = VariantParams.from_case(case, arrays, 2)
    a, b = AEB().bind(p2), AEB().bind(p2)
    assert a == b and hash(a) == hash(b)
    p3 = p2.with_values(aeb_ttc_full_s=np.array([0.9, 0.5]))
    c = AEB().bind(p3)
    assert a != c
    np.testing.assert_array_equal(c.p["ttc_full_s"], [0.9, 0.5])
    assert type(c) is AEB and isinstance(c.pid, PIDCruise)


def test_aeb_and_idm_share_construction() -> None:
    assert AEB(AEBConfig(ttc_full_s=0.7)) == AEB(ttc_full_s=0.7)
    assert IDM(IDMConfig(min_gap_m=3.0)) == IDM(min_gap_m=3.0)
    assert IDM(min_gap_m=3.0).p["min_gap_m"] == 3.0
    for cls, cfg in ((AEB, AEBConfig()), (IDM, IDMConfig())):
        with pytest.raises(ConfigError, match="not both"):
            cls(cfg, delta=1.0)
        with pytest.raises(ConfigError, match=f"{cls.name}: .*unexpected keyword"):
            cls(bogus=1.0)
    with pytest.raises(ConfigError, match="config must be an IDMConfig"):
        IDM(AEBConfig())
