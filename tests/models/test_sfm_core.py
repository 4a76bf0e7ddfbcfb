"""vei.models.sfm_core: the riders' desired velocity, destination force and Euler step,
one implementation for both engines (NumPy on arrays, numba on scalars): bit for bit equal
on random inputs, and hand-computed answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vei.models import sfm_core as core

N = 3000


@pytest.fixture(scope="module")
def rng_inputs() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(11)
    return {
        "px": rng.uniform(-50, 50, N), "py": rng.uniform(-50, 50, N),
        "gx": rng.uniform(-50, 50, N), "gy": rng.uniform(-50, 50, N),
        "v0": rng.uniform(0, 8, N), "sigma": rng.uniform(0.01, 3, N),
        "paper": rng.random(N) < 0.3,
        "vx": rng.normal(0, 4, N), "vy": rng.normal(0, 4, N),
        "k": rng.uniform(0, 200, N), "fx": rng.normal(0, 300, N), "fy": rng.normal(0, 300, N),
        "m": rng.uniform(40, 150, N),
    }  # fmt: skip


CASES = (
    ("desired_velocity_core", "desired_velocity", ("px", "py", "gx", "gy", "v0", "sigma", "paper")),
    ("destination_force_core", "destination_force", ("vx", "vy", "gx", "gy", "k")),
    ("point_mass_core", "point_mass", ("px", "py", "vx", "vy", "fx", "fy", "m", "dt")),
)


@pytest.mark.parametrize(("name", "compiled", "args"), CASES, ids=[c[0] for c in CASES])
def test_numpy_and_compiled_cores_are_bit_identical(name, compiled, args, rng_inputs) -> None:
    kernel_sfm = pytest.importorskip("vei.sim._kernel_sfm")  # needs numba
    vec = [0.05 if a == "dt" else rng_inputs[a] for a in args]
    out_np = getattr(core, name)(*vec)
    fn = getattr(kernel_sfm, compiled)
    rows = [fn(*[v if np.ndim(v) == 0 else v[i].item() for v in vec]) for i in range(N)]
    for j, a in enumerate(out_np):
        b = np.array([r[j] for r in rows])
        assert np.asarray(a).tobytes() == b.tobytes(), (name, j)


def test_cores_hand_values() -> None:
    # Goal 3-4-5 away, v0 = 5, sigma = 0: normalised form -> speed 5 along (0.6, 0.8); the
    # paper's form -> v0 d / |d|^2 = (0.6, 0.8).
    vx, vy = core.desired_velocity_core(0.0, 0.0, 3.0, 4.0, 5.0, 0.0, False)
    assert (float(vx), float(vy)) == pytest.approx((3.0, 4.0))
    vx, vy = core.desired_velocity_core(0.0, 0.0, 3.0, 4.0, 5.0, 0.0, True)
    assert (float(vx), float(vy)) == pytest.approx((0.6, 0.8))
    # sigma softens: |v| = v0 |d| / sqrt(|d|^2 + sigma^2) = 5 * 5 / sqrt(26).
    vx, vy = core.desired_velocity_core(0.0, 0.0, 3.0, 4.0, 5.0, 1.0, False)
    assert math.hypot(float(vx), float(vy)) == pytest.approx(25.0 / math.sqrt(26.0))
    fx, fy = core.destination_force_core(3.0, 4.0, 1.0, 1.0, 100.0)
    assert (float(fx), float(fy)) == (200.0, 300.0)
    # 100 N on 50 kg for 0.1 s from rest at the origin: v = 0.2 m/s, x = 0.02 m (semi-implicit).
    x, y, vx, vy = core.point_mass_core(0.0, 0.0, 0.0, 0.0, 100.0, 0.0, 50.0, 0.1)
    assert (float(x), float(vx), float(y), float(vy)) == pytest.approx((0.02, 0.2, 0.0, 0.0))
