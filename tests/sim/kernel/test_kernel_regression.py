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
    "cross/aggressive-cap": "6bcba7287bc3217d6d572084c487381c",
    "cross/aggressive": "05121abfc43031719123f43accc6d99d",
    "cross/mixed": "1664cd6bd6c080a77fbf6b18690037aa",
    "cross/normal-cap": "165cd5bba49bb6b25b6343a3eb749e67",
    "cross/normal": "e9b500f08e91535fb2c71eb48c5f57a2",
    "cross/replay": "94c6dc69affa7c1c02cbc4fb481df0a6",
    "demo/aggressive-cap": "b41bf03b29203cfeba058d6199c8c83d",
    "demo/aggressive": "9efaa84025807b2a6c209a7e2a5bf66d",
    "demo/mixed": "b3245b1fc628abcbd09ed5b7df26f526",
    "demo/normal-cap": "5ee1e7573d6fa608f260f556ced447e8",
    "demo/normal": "64a4c8dbdb7a8d055e97f84cd038da9c",
    "demo/replay": "90f6af8823c85129504cdc4fcef4b73a",
    "riders/aggressive-cap": "c95d24511d728b47f920c3f8aaa486b1",
    "riders/aggressive": "5aa235b35d138b739806e52b584cd109",
    "riders/mixed": "d0c79acff70e5e76f7a44437a3c173e1",
    "riders/normal-cap": "10e4c5bf2e3beadd7dc77f883a58ddd0",
    "riders/normal": "dd49f6555ad813197a15926c9c4e688d",
    "riders/replay": "ed5e69ab1f6c603efcb1cee20051eede",
}

#: The same with continuations (the default since issue 22), recorded with its kernel.
DIGESTS_CONTINUED: dict[str, str] = {
    "cross/aggressive": "64790a931655852e8cad0c97db7fd9ec",
    "cross/aggressive-cap": "ea355d8f95189e6fed653763b9ac3ca5",
    "cross/mixed": "fad8f0463dd1f639c3ed8e479b79ae44",
    "cross/normal": "01e03bf8d0e8ab7da02df2c6b44abea3",
    "cross/normal-cap": "658105f5c349f247130a959d0bf73341",
    "cross/replay": "d80a96483786a6c015c4f38b44a080df",
    "demo/aggressive": "118ec1daa0ab09b03ed8e308b6da6a39",
    "demo/aggressive-cap": "97f9e19d27bb56cb8232dad01a83bcd8",
    "demo/mixed": "5298c4b49a622b6fd1f574ace4fcee0a",
    "demo/normal": "22fc70296082475f454734f5763a73c9",
    "demo/normal-cap": "dacd25591e16f44abb10932bcb37a308",
    "demo/replay": "51af4dc4ea75f76088a388bf1fb747ce",
    "riders/aggressive": "09516f7bbf084255d6c0b0f69f24bb07",
    "riders/aggressive-cap": "2583d4b3f875ed0b5a5c071d7de9bcb5",
    "riders/mixed": "3f7ddfa0df5df01569f311e4e9ac6238",
    "riders/normal": "1b3eff6e444d1db2955fef51aa23b3c2",
    "riders/normal-cap": "e54fc1fd43b804bdd54daf25fbac0c35",
    "riders/replay": "07e6b13d0d00dedc48fbdca32b36ca73",
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
