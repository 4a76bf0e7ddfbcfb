"""The compiled kernel's outputs, bit for bit, against digests recorded before its split.

The kernel was one 796-line module; it was split by idea (today the package vei.sim.kernel:
layout, scalar, ego, sfm, riders, loop). Before the split
every output of ``simulate(kernel='numba')`` was recorded on three scenes (the demo, the
crossing scene with a replayed cyclist, the crossing scene with three more social-force
e-scooters) for the paper's five configurations (7 time shifts each) and a mixed batch
(every configuration and model option, 18 variants); the SHA-256 of each (scene,
configuration) set of arrays is below. A refactoring of the kernel must keep them: any
change of a result, even in the last bit, changes the digest.

Issue 22 (riders arrive and leave) changed the results on purpose: every road user now
enters along its run-in and leaves along its run-out (vei.continuation), so a scene's
rider is present longer and a social-force rider keeps riding past its last recorded
sample. The digests above are therefore checked on the scenes *without* continuations
(``SimConfig(continuation=ContinuationConfig(enabled=False))``): the kernel itself must
still give the recorded outputs bit for bit there. The scenes with continuations (the
default) have their own digests, :data:`DIGESTS_CONTINUED`, recorded with issue 22's
kernel by the procedure below.

Issue 32.4 (one truth for every rider) changed the results on purpose: the primary
rider's velocity is its recorded speed along its recorded heading, like every replayed
road user's, no longer a finite difference of its positions; both dicts were re-recorded.

Re-recording (only for a deliberate model change; say why in the commit): run
``NPY_DISABLE_CPU_FEATURES="<the AVX-512 features>" OPENBLAS_CORETYPE=Haswell python -m
tests.sim.kernel.test_kernel_regression`` (the environment :func:`_avx2_env` builds: the
test prints it on failure) with the recorded numba on x86-64, and paste the printed
digests into the dict(s) whose results changed.

Floating-point results of compiled code depend on the compiler and the maths library, so
the digests are checked where they were recorded (numba 0.68.1 on x86-64); elsewhere the
kernel-vs-NumPy tests (test_kernel.py) still bound the results. The kernel's inputs are
prepared with NumPy and OpenBLAS, whose AVX-512 loops (NumPy's SIMD exp / arctan2 / hypot,
OpenBLAS's SkylakeX kernels) round some results differently from their AVX2 loops; the
digests are therefore computed in a child process with both held to their AVX2 code
(``NPY_DISABLE_CPU_FEATURES``, ``OPENBLAS_CORETYPE=Haswell``: the code of the machine they
were recorded on), so they hold on any x86-64 machine with AVX2.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vei.config import PAPER_CASES, ContinuationConfig, SimConfig, case_preset
from vei.sim.engine import _RECORDED, simulate
from vei.sim.state import VariantParams, prepare_scenario
from vei.sim.testing import TrackSpec, crossing_scenario, four_rider_scenario

numba = pytest.importorskip("numba")

RECORDED_WITH = ("0.68.1", "x86_64")

#: sha256 (first 32 hex digits) of each (scene, configuration), recorded before the split.
DIGESTS = {
    "cross/aggressive": "a90b8e4d03b13142325c140bbdabd8c0",
    "cross/aggressive-cap": "cfeabec42286592f553e03132613d14a",
    "cross/mixed": "89f19e199927a45d9de6df176dbf19b8",
    "cross/normal": "e295a1ec5f853e9ed70fc7cc627b3c2b",
    "cross/normal-cap": "a80619c70b5cf618f432cff8f432a0c1",
    "cross/replay": "892fa136128705ae8124a25f9d1a50a9",
    "demo/aggressive": "9881b5a7f86d4d3d3dcec2f3e525460b",
    "demo/aggressive-cap": "5ca043d90e8811298ddb94af299e6bea",
    "demo/mixed": "8a7bcca7c3f8731bb99b86a0fa820524",
    "demo/normal": "327cb6f0045b559385e5d85c2eb6dfca",
    "demo/normal-cap": "a257894ae70de6c5bcc1590ca59f9805",
    "demo/replay": "32867ce7242d18e3be20df5478ffdf7e",
    "riders/aggressive": "ae2881529660fc4cba71fcfbb4ce73aa",
    "riders/aggressive-cap": "6d6facb607086406f31b486cb0be60bb",
    "riders/mixed": "c7eb260f29ecf8df3bdf529f5e69c4f2",
    "riders/normal": "b766d73d352532b3246cee35c65b5e57",
    "riders/normal-cap": "e0855c2992b3d30836585df8db5be56f",
    "riders/replay": "0e50cf7e1c0e7302748bad716032f9d3",
}

#: The same with continuations (the default since issue 22), recorded with its kernel.
DIGESTS_CONTINUED: dict[str, str] = {
    "cross/aggressive": "585f1937795fe9c50ab4b4a3b1ae9610",
    "cross/aggressive-cap": "ca2058707b197de97a677710cd1a4913",
    "cross/mixed": "974be1dea5d34c1499434a56f2be1a3a",
    "cross/normal": "99884bf2d9400798caae93ea85f930c6",
    "cross/normal-cap": "83e0f4bb39113038ae81f65af1488ba3",
    "cross/replay": "c4eab96a3d500770e3ba9f419d87b930",
    "demo/aggressive": "f0302c820f5bad500a63ef25a83dd940",
    "demo/aggressive-cap": "b7f82dc3333c4a47a41441dd2d78e2a2",
    "demo/mixed": "eb31203cc5987cf8f1b6e9c0c12334d0",
    "demo/normal": "7405f6bccf433599d8ace4dab810b02d",
    "demo/normal-cap": "a208a25259e768da5df0461232d9189f",
    "demo/replay": "669f8fc7a27e4d65b0b79b5935cc519c",
    "riders/aggressive": "6fc5ad439283c5af33be875fb520bdfa",
    "riders/aggressive-cap": "4c60f0a2c73e491b0b47a62cc721e8b5",
    "riders/mixed": "67ffb849a87601df1c5635ee0e93609f",
    "riders/normal": "13d9016ddfcb22f63f3c5cd7c5182820",
    "riders/normal-cap": "a1ca3cbd8bed56a95058b41fbc662aed",
    "riders/replay": "c63d0abc0b589bcbfeddd26d662f36f4",
}

_EXTRA = (
    "extra_x_m", "extra_y_m", "extra_yaw_rad", "extra_speed_mps", "extra_accel_mps2",
    "extra_active", "extra_hit",
)  # fmt: skip
_FINAL = ("ego_s_m", "pid_integral_m", "rider_prog_m", "hist", "rider_done", "cap_state")


def _mixed(arrays, base: float) -> VariantParams:
    """Every configuration and model option in one batch (as tests/sim/test_engine.py)."""
    parts = []
    for i, name in enumerate((*PAPER_CASES, "replay-speed")):
        shifts = base + np.array([-1.0, 0.0, 0.7]) + 0.1 * i
        parts.append(VariantParams.from_case(case_preset(name), arrays, 3, time_shift_s=shifts))
    p = VariantParams.concat(parts)
    i = np.arange(p.batch_size)
    return p.with_values(
        perception_delay_s=np.where(i % 2 == 0, 0.0, 0.4),
        k_des_nspm=p.k_des_nspm * (1.0 + 0.1 * (i % 3)),
        cruise_speed_mps=5.6 + 0.2 * (i % 4),
        front_bumper=i % 5 == 1,
        paper_vdes=i == 7,
        paper_per_step=i % 3 == 2,
        max_speed_mps=np.where(i == 8, 4.0, np.inf),
        max_accel_mps2=np.where(i == 10, 1.0, np.inf),
    )


def _scenes(continued: bool):
    from vei.experiments.demo_data import demo_interaction
    from vei.recon.pipeline import reconstruct
    from vei.sim.timeshift import find_time_shift

    cont = ContinuationConfig(enabled=continued)
    sim = SimConfig(continuation=cont)
    demo = reconstruct(demo_interaction())
    t = np.arange(0, 501) / 20.0
    cyclist = TrackSpec("cyclist", t, np.full_like(t, 20.0), np.zeros_like(t),
                        np.full_like(t, np.pi / 2), np.zeros_like(t))  # fmt: skip
    shift = (60.0 - 2.35) / 5.6 - (2.0 + 15.0 / 4.4)
    riders = SimConfig(sfm_riders="all", continuation=cont)
    return (
        ("demo", prepare_scenario(demo, sim), float(find_time_shift(demo, sim=sim))),
        ("cross", prepare_scenario(crossing_scenario(others=[("c2", cyclist)]), sim), shift),
        ("riders", prepare_scenario(four_rider_scenario(), riders), 4.9),
    )


def _digest(result) -> str:
    arrays = {name: getattr(result, name) for name, _, _ in _RECORDED}
    arrays.update({f: getattr(result, f) for f in _EXTRA if getattr(result, f) is not None})
    arrays["hit_other"] = result.hit_other
    arrays["collision_time_s"] = result.collision_time_s
    arrays["min_center_distance_m"] = result.min_center_distance_m
    arrays.update({f"final_{f}": getattr(result.final_state, f) for f in _FINAL})
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(np.asarray(arrays[name]))
        h.update(name.encode())
        h.update(str(a.dtype).encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()[:32]


def _digests(continued: bool = False) -> dict[str, str]:
    """The digest of every (scene, configuration), computed in this process."""
    got = {}
    for scene, arrays, base in _scenes(continued):
        sets = {
            c: VariantParams.from_case(
                case_preset(c), arrays, 7, time_shift_s=base + np.linspace(-2.0, 2.0, 7)
            )
            for c in PAPER_CASES
        }
        sets["mixed"] = _mixed(arrays, base)
        for name, params in sets.items():
            result = simulate(arrays, params, kernel="numba")
            if name == "mixed":  # both outcomes present: the digests cover collisions too
                assert result.collision.any() and (~result.collision).any()
            got[f"{scene}/{name}"] = _digest(result)
    return got


def _avx2_env() -> dict[str, str] | None:
    """This environment with NumPy's and OpenBLAS's AVX-512 code switched off (module
    docstring); None when this NumPy has no AVX2 (x86-64-v3) loops to fall back to."""
    try:
        from numpy._core import _multiarray_umath as umath
    except ImportError:  # pragma: no cover - NumPy 1.x
        from numpy.core import _multiarray_umath as umath
    found = {f for f, on in umath.__cpu_features__.items() if on}
    if not ("X86_V3" in found or {"AVX2", "FMA3"} <= found):
        return None
    off = [f for f in umath.__cpu_dispatch__ if "AVX512" in f or f == "X86_V4"]
    return dict(os.environ, NPY_DISABLE_CPU_FEATURES=" ".join(off), OPENBLAS_CORETYPE="Haswell")


@pytest.mark.skipif(
    (numba.__version__, platform.machine()) != RECORDED_WITH,
    reason=f"digests recorded with numba {RECORDED_WITH[0]} on {RECORDED_WITH[1]}",
)
def test_kernel_outputs_bit_identical_to_the_recorded_digests() -> None:
    env = _avx2_env()
    if env is None:
        pytest.skip("this CPU / NumPy has no AVX2 loops (the digests' inputs were made with them)")
    root = Path(__file__).resolve().parents[3]
    run = subprocess.run(
        [sys.executable, "-m", "tests.sim.kernel.test_kernel_regression"],
        cwd=root, env=env, capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    got = json.loads(run.stdout.strip().splitlines()[-1])
    changed = sorted(k for k in DIGESTS if got["off"][k] != DIGESTS[k])
    assert not changed, f"kernel outputs without continuations changed for {changed}"
    changed = sorted(k for k in got["on"] if got["on"][k] != DIGESTS_CONTINUED.get(k))
    assert not changed, (
        f"kernel outputs with continuations changed for {changed}; env "
        f"{ {k: env[k] for k in ('NPY_DISABLE_CPU_FEATURES', 'OPENBLAS_CORETYPE')} }; got {got['on']}"
    )


if __name__ == "__main__":  # the child process of the test above
    print(json.dumps({"off": _digests(False), "on": _digests(True)}))
