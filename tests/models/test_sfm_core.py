"""vei.models.sfm_core: the riders' desired velocity, destination force, Euler step, the
ego's repulsion, the limits' factor and the rider-rider repulsion, one implementation for
both engines (NumPy on arrays, numba on scalars): bit for bit equal on random inputs (the
repulsions to 2 and 4 ulp: NumPy's SIMD exp may round differently from the C library's on
AVX-512 CPUs), and hand-computed answers."""

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
        "ex": rng.uniform(-50, 50, N), "ey": rng.uniform(-50, 50, N),
        "c": np.cos(yaw := rng.uniform(-np.pi, np.pi, N)), "s": np.sin(yaw),
        "hl": rng.uniform(1.0, 3.0, N), "hw": rng.uniform(0.5, 1.2, N),
        "front": rng.random(N) < 0.5, "a": rng.uniform(0, 600, N), "b": rng.uniform(0, 2, N),
        "mag": np.where(rng.random(N) < 0.1, 0.0, rng.uniform(0, 400, N)),
        "cap": rng.uniform(1, 300, N),
    }  # fmt: skip


CASES = (
    ("desired_velocity_core", "desired_velocity", ("px", "py", "gx", "gy", "v0", "sigma", "paper")),
    ("destination_force_core", "destination_force", ("vx", "vy", "gx", "gy", "k")),
    ("point_mass_core", "point_mass", ("px", "py", "vx", "vy", "fx", "fy", "m", "dt")),
    ("cap_factor_core", "cap_factor", ("mag", "cap")),
    ("influential_point_core", "influential_point",
     ("px", "py", "ex", "ey", "c", "s", "hl", "hw", "front")),
    ("away_from_centre_core", "away_from_centre", ("px", "py", "ex", "ey", "c", "s")),
)  # fmt: skip


@pytest.mark.parametrize(("name", "compiled", "args"), CASES, ids=[c[0] for c in CASES])
def test_numpy_and_compiled_cores_are_bit_identical(name, compiled, args, rng_inputs) -> None:
    kernel_sfm = pytest.importorskip("vei.sim.kernel.sfm")  # needs numba
    vec = [0.05 if a == "dt" else rng_inputs[a] for a in args]
    out_np = getattr(core, name)(*vec)
    fn = getattr(kernel_sfm, compiled)
    rows = [fn(*[v if np.ndim(v) == 0 else v[i].item() for v in vec]) for i in range(N)]
    if not isinstance(out_np, tuple):  # one output
        out_np, rows = (out_np,), [(r,) for r in rows]
    for j, a in enumerate(out_np):
        b = np.array([r[j] for r in rows])
        assert np.asarray(a).tobytes() == b.tobytes(), (name, j)


def test_repulsion_core_numpy_and_compiled(rng_inputs) -> None:
    """Direction and the tiny flag bit for bit; the magnitude a exp(-b d) to 2 ulp (the
    exp to 1, then the product's rounding)."""
    kernel_sfm = pytest.importorskip("vei.sim.kernel.sfm")
    px, py = rng_inputs["px"].copy(), rng_inputs["py"].copy()
    qx, qy = rng_inputs["gx"].copy(), rng_inputs["gy"].copy()
    qx[:50], qy[:50] = px[:50], py[:50]  # the rider on the source point: tiny
    a, b = rng_inputs["a"], rng_inputs["b"]
    mag, nx, ny, tiny = core.repulsion_core(px, py, qx, qy, a, b)
    rows = [kernel_sfm.repulsion(px[i], py[i], qx[i], qy[i], a[i], b[i]) for i in range(N)]
    got = [np.array([r[j] for r in rows]) for j in range(4)]
    np.testing.assert_array_max_ulp(mag, got[0], maxulp=2)
    assert nx.tobytes() == got[1].tobytes() and ny.tobytes() == got[2].tobytes()
    assert np.array_equal(tiny, got[3]) and tiny[:50].all() and not tiny[50:].any()


def test_repulsion_and_limits_hand_values() -> None:
    # Ego at the origin heading +x, 4 x 2 m: a rider at (5, 1) is repelled from the box's
    # closest point (2, 1); from the front bumper's centre (2, 0) when front_bumper.
    q = core.influential_point_core(5.0, 1.0, 0.0, 0.0, 1.0, 0.0, 2.0, 1.0, False)
    assert (float(q[0]), float(q[1])) == (2.0, 1.0)
    q = core.influential_point_core(5.0, 1.0, 0.0, 0.0, 1.0, 0.0, 2.0, 1.0, True)
    assert (float(q[0]), float(q[1])) == (2.0, 0.0)
    # Heading +y (cos 0, sin 1): the closest point of a rider at (0.5, 7) is (0.5, 2).
    q = core.influential_point_core(0.5, 7.0, 0.0, 0.0, 0.0, 1.0, 2.0, 1.0, False)
    assert (float(q[0]), float(q[1])) == pytest.approx((0.5, 2.0))
    # 3 m away along +x: A exp(-b 3) = 500 exp(-1.5) N along (1, 0).
    mag, nx, ny, tiny = core.repulsion_core(5.0, 1.0, 2.0, 1.0, 500.0, 0.5)
    assert float(mag) == pytest.approx(500.0 * math.exp(-1.5))
    assert (float(nx), float(ny), bool(tiny)) == (1.0, 0.0, False)
    # On the source point: from the ego's centre (3-4-5), or along the heading on the centre.
    ux, uy = core.away_from_centre_core(3.0, 4.0, 0.0, 0.0, 1.0, 0.0)
    assert (float(ux), float(uy)) == pytest.approx((0.6, 0.8))
    assert tuple(map(float, core.away_from_centre_core(0.0, 0.0, 0.0, 0.0, 0.6, 0.8))) == (
        0.6,
        0.8,
    )
    # A 10 m/s velocity capped at 8 m/s: factor 0.8; a 500 N force capped at 75 kg * 4 m/s^2.
    assert float(core.cap_factor_core(10.0, 8.0)) == pytest.approx(0.8)
    assert float(core.cap_factor_core(500.0, 300.0)) == pytest.approx(0.6)


def test_numpy_limits_cap_only_where_they_bind() -> None:
    from vei.models import sfm

    fx, fy = sfm.cap_force(
        np.array([300.0, 30.0]), np.array([400.0, 40.0]), np.array([250.0, 250.0])
    )
    assert fx.tolist() == pytest.approx([150.0, 30.0]) and fy.tolist() == pytest.approx(
        [200.0, 40.0]
    )
    # From (0, 0) with 0.1 s steps: 10 m/s capped at 8 (position re-stepped: 0.8 m), 5 m/s kept
    # (position as the step gave it, untouched).
    px, py, vx, vy, sp = sfm.cap_speed(
        np.zeros(2), np.zeros(2), np.array([1.0, 0.5]), np.array([0.0, 0.0]),
        np.array([10.0, 5.0]), np.zeros(2), np.array([10.0, 5.0]), 8.0, 0.1,
    )  # fmt: skip
    assert px.tolist() == pytest.approx([0.8, 0.5]) and vx.tolist() == pytest.approx([8.0, 5.0])
    assert sp.tolist() == pytest.approx([8.0, 5.0]) and py.tolist() == [0.0, 0.0]


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


def test_rider_repulsion_numpy_and_compiled(rng_inputs) -> None:
    """vei.models.sfm.rider_force (NumPy, masked) and the kernel's rforce (a branch) run the
    same cores: zero where they do not act (cutoff, coincident centres), elsewhere equal to
    4 ulp (the exp to 1 ulp, then a product, a division and a product round it)."""
    kernel_scalar = pytest.importorskip("vei.sim.kernel.scalar")
    from vei.models import sfm

    rng = np.random.default_rng(5)
    px, py = rng_inputs["px"] / 4, rng_inputs["py"] / 4  # within ~25 m: some beyond the cutoff
    qx, qy = rng_inputs["gx"] / 4, rng_inputs["gy"] / 4
    qx[:20], qy[:20] = px[:20], py[:20]  # coincident centres: no direction, no force
    radii = rng.uniform(0.3, 1.5, N)
    a, b = rng_inputs["a"], rng_inputs["b"]
    fx, fy = sfm.rider_force(px, py, qx, qy, radii, a, b)
    rows = [
        kernel_scalar.rforce(px[i], py[i], qx[i], qy[i], radii[i], a[i], b[i]) for i in range(N)
    ]
    gx, gy = np.array([r[0] for r in rows]), np.array([r[1] for r in rows])
    np.testing.assert_array_max_ulp(fx, gx, maxulp=4)
    np.testing.assert_array_max_ulp(fy, gy, maxulp=4)
    gap = np.hypot(px - qx, py - qy) - radii
    off = (gap > core.RIDER_FORCE_CUTOFF_M) | (np.arange(N) < 20)
    assert off.sum() > 100 and (~off).sum() > 100
    assert not fx[off].any() and not gx[off].any() and fx[~off].all()


def test_rider_repulsion_hand_values() -> None:
    # Centres 3 m apart along +x, radii 1 m: gap 2 m, 2 exp(-2) N along (1, 0).
    dx, dy, dc, gap, acts = core.rider_gap_core(3.0, 0.0, 0.0, 0.0, 1.0)
    assert (float(dx), float(dy), float(dc), float(gap), bool(acts)) == (3.0, 0.0, 3.0, 2.0, True)
    inv = core.rider_repulsion_core(dc, gap, 2.0, 1.0)
    assert float(inv * dx) == pytest.approx(2.0 * math.exp(-2.0))
    # overlapping discs (gap -0.5): the force keeps growing, 2 exp(0.5) N
    dx, dy, dc, gap, acts = core.rider_gap_core(0.0, 1.5, 0.0, 0.0, 2.0)
    assert bool(acts) and float(core.rider_repulsion_core(dc, gap, 2.0, 1.0) * dy) == (
        pytest.approx(2.0 * math.exp(0.5))
    )
    assert not bool(core.rider_gap_core(12.0, 0.0, 0.0, 0.0, 1.0)[4])  # gap 11 m > cutoff
    assert not bool(core.rider_gap_core(1.0, 1.0, 1.0, 1.0, 1.0)[4])  # same centre
