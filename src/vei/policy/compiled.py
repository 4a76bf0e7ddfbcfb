"""Compiled ego policies: a numba function the engine's compiled kernel calls every step.

A Python policy (:class:`vei.policy.base.Policy`) runs the NumPy step loop; a compiled
policy runs inside the compiled kernel (:mod:`vei.sim.kernel`), at the kernel's speed. It
is one numba-compiled function of a fixed signature, called once per variant and step::

    import numba
    from vei.policy.compiled import CompiledPolicy, E_SPEED, E_CRUISE, O_VALID, O_GAP

    @numba.njit
    def brake_for_gap(ego, objs, state):     # -> demanded acceleration [m/s^2]
        ...

    MyCompiled = CompiledPolicy.factory(brake_for_gap, state_size=1)

Arguments (all float64, C-contiguous; read the rows by the names below):

- ``ego`` [N_EGO]: the ego at step k (rows E_*: time, step, speed, acceleration, arc
  length, path length, cruise speed, actuator limits, footprint, collided as 0 / 1);
- ``objs`` [N_OBJ, N]: the road users of :class:`vei.policy.observation.Observation`
  (the primary rider, the extra riders, the replayed others) by rows O_*: valid (0 / 1),
  relative pose and velocity in the ego frame, footprint, age of the sample, category
  code, path gap and lateral offset; invalid entries hold 0 and +inf exactly as in the
  Observation;
- ``state`` [state_size]: the policy's own memory for this variant, starting at
  ``state0`` (zeros by default); the function updates it in place.

It returns the demanded acceleration [m/s^2] (float64; the engine clips it to the car's
limits). A non-finite return stops the run with a :class:`vei.errors.PolicyError` naming
the variant and the step. The same function also runs through the Python policy API
(:meth:`CompiledPolicy.act`, used where the compiled kernel is not: ``kernel='numpy'``,
a perception model or V2X); both give the same result (a test checks it).

The function is checked when the policy is made (:func:`check_function`): it must be a
numba ``@njit`` function (or a plain Python function, compiled here) that compiles for
:data:`SIGNATURE` and returns a finite float on a probe observation; each failure is a
ConfigError naming what is wrong.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.errors import ConfigError, DependencyError
from vei.policy.base import PolicyAction
from vei.policy.observation import Observation

# Rows of ``ego`` [N_EGO].
E_T, E_DT, E_SPEED, E_ACCEL, E_S, E_PATH_LEN, E_CRUISE = 0, 1, 2, 3, 4, 5, 6
E_MAX_ACCEL, E_MAX_DECEL, E_LENGTH, E_WIDTH, E_COLLIDED = 7, 8, 9, 10, 11
N_EGO = 12
#: Observation fields of the ego rows, in row order.
EGO_ROWS = (
    "t_s", "dt_s", "ego_speed_mps", "ego_accel_mps2", "ego_s_m", "path_length_m",
    "cruise_speed_mps", "max_accel_mps2", "max_decel_mps2", "ego_length_m", "ego_width_m",
    "collided",
)  # fmt: skip
# Rows of ``objs`` [N_OBJ, N].
O_VALID, O_X, O_Y, O_YAW, O_VX, O_VY, O_LENGTH, O_WIDTH = 0, 1, 2, 3, 4, 5, 6, 7
O_AGE, O_CATEGORY, O_GAP, O_LATERAL = 8, 9, 10, 11
N_OBJ = 12
#: Observation fields of the object rows, in row order.
OBJ_ROWS = (
    "valid", "rel_x_m", "rel_y_m", "rel_yaw_rad", "rel_vx_mps", "rel_vy_mps", "length_m",
    "width_m", "age_s", "category", "path_gap_m", "path_lateral_m",
)  # fmt: skip
#: The signature as text (messages, docs).
SIGNATURE_TEXT = "float64(float64[::1] ego, float64[:, ::1] objs, float64[::1] state)"


def signature() -> Any:
    """The numba signature every compiled policy has (needs numba)."""
    from numba import types

    arr1 = types.Array(types.float64, 1, "C")
    return types.float64(arr1, types.Array(types.float64, 2, "C"), arr1)


def _numba() -> Any:
    try:
        import numba
    except ImportError:
        raise DependencyError("compiled policies need numba (pip install numba)") from None
    return numba


def check_function(fn: Any, state_size: int, name: str) -> Any:
    """``fn`` compiled for :data:`SIGNATURE_TEXT` (a numba dispatcher with that one
    signature), checked; ConfigError naming ``name`` and what is wrong otherwise.

    Checks: a callable; compiles for the signature (a numba typing error is reported with
    the signature expected); on a probe observation (ego at 5 m/s, no road user valid, a
    zero state of ``state_size``) it returns a finite float.
    """
    numba = _numba()
    from numba.core.registry import CPUDispatcher

    if not callable(fn):
        raise ConfigError(f"compiled policy {name}: {fn!r} is not a function")
    py = fn.py_func if isinstance(fn, CPUDispatcher) else fn
    if not callable(py) or not hasattr(py, "__code__"):
        raise ConfigError(
            f"compiled policy {name}: need a Python function or a numba @njit function, "
            f"got {type(fn).__name__}"
        )
    if py.__code__.co_argcount != 3:
        raise ConfigError(
            f"compiled policy {name}: the function must take 3 arguments (ego, objs, "
            f"state) as {SIGNATURE_TEXT}, it takes {py.__code__.co_argcount}"
        )
    try:
        disp = numba.njit(signature(), cache=False, nogil=True)(py)
    except Exception as exc:  # noqa: BLE001 - numba's typing errors: name the signature
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ConfigError(
            f"compiled policy {name}: does not compile as {SIGNATURE_TEXT} (it must return "
            f"one float64 and read the arrays as float64): {type(exc).__name__}: {first}"
        ) from None
    ego = np.zeros(N_EGO)
    ego[E_DT], ego[E_SPEED], ego[E_CRUISE] = 0.04, 5.0, 8.0
    ego[E_MAX_ACCEL], ego[E_MAX_DECEL], ego[E_LENGTH], ego[E_WIDTH] = 3.0, 8.0, 4.5, 1.8
    objs = np.zeros((N_OBJ, 1))
    objs[O_AGE] = objs[O_GAP] = objs[O_LATERAL] = np.inf
    try:
        out = disp(ego, objs, np.zeros(state_size))
    except Exception as exc:  # noqa: BLE001 - a user's code
        raise ConfigError(
            f"compiled policy {name}: raised {type(exc).__name__} on a probe observation "
            f"(no road user valid): {exc}"
        ) from None
    if not isinstance(out, float) or not math.isfinite(out):
        raise ConfigError(
            f"compiled policy {name}: returned {out!r} on a probe observation (ego at 5 m/s, "
            "no road user valid); it must return a finite acceleration [m/s^2]"
        )
    return disp


class CompiledPolicy:
    """A compiled ego policy (module docstring): the engine's compiled kernel calls
    ``function`` per variant and step; :meth:`act` runs it through the Python policy API.

    Args:
        function: the policy function (numba @njit or plain Python; compiled and checked
            here, :func:`check_function`).
        state_size: length of the per-variant state array (>= 0).
        state0: its values at t = 0 (default zeros), finite.
        name: how messages name the policy (default the function's name).
    """

    def __init__(
        self,
        function: Callable[..., float],
        state_size: int = 0,
        state0: Sequence[float] | npt.ArrayLike | None = None,
        name: str | None = None,
    ) -> None:
        self.name = name or getattr(function, "__name__", type(function).__name__)
        if isinstance(state_size, bool) or not isinstance(state_size, int) or state_size < 0:
            raise ConfigError(
                f"compiled policy {self.name}: state_size must be an int >= 0, got {state_size!r}"
            )
        s0 = np.zeros(state_size) if state0 is None else np.asarray(state0)
        if s0.dtype.kind not in "fiu" or s0.shape != (state_size,):
            raise ConfigError(
                f"compiled policy {self.name}: state0 must be {state_size} numbers (float64), "
                f"got dtype {s0.dtype} shape {s0.shape}"
            )
        if not np.all(np.isfinite(s0)):
            raise ConfigError(f"compiled policy {self.name}: state0 has NaN or infinite values")
        self.state0 = np.ascontiguousarray(s0, dtype=np.float64)
        self.state_size = state_size
        self.source = function
        self.function = check_function(function, state_size, self.name)

    @classmethod
    def factory(cls, function: Callable[..., float], state_size: int = 0, **defaults: Any) -> type:
        """A class for ``--policy file.py:Name`` (``Name = CompiledPolicy.factory(fn, 2)``):
        ``Name(**params)`` is a CompiledPolicy of ``function`` (params: ``state0``,
        ``name``; ``defaults`` are theirs when not given)."""
        base = cls

        class Made(base):  # type: ignore[valid-type, misc]
            def __init__(self, **params: Any) -> None:
                base.__init__(self, function, state_size, **{**defaults, **params})

        Made.__name__ = Made.__qualname__ = getattr(function, "__name__", "compiled_policy")
        Made.__module__ = getattr(function, "__module__", __name__)
        return Made

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickled as its function (by numba's own pickling), state size, state0 and name;
        compiled again on unpickling (a sweep's worker processes)."""
        return (_rebuild, (self.source, self.state_size, self.state0, self.name))

    def init_state(self, batch_size: int) -> npt.NDArray[np.float64]:
        """[B, state_size] the state at t = 0 (state0 in every row)."""
        return np.tile(self.state0, (batch_size, 1))

    def act(
        self, obs: Observation, state: npt.NDArray[np.float64]
    ) -> tuple[PolicyAction, npt.NDArray[np.float64]]:
        """The function on each variant of ``obs`` (the Python policy API)."""
        ego, objs = pack_observation(obs)
        new = np.array(state, dtype=np.float64, order="C", copy=True)
        acc = run_batch(self.function, ego, objs, new)
        bad = np.flatnonzero(~np.isfinite(acc))
        if bad.size:
            raise ConfigError(
                f"compiled policy {self.name}: returned {acc[bad[0]]} for variant {bad[0]} "
                f"(of {acc.size}) at t = {obs.t_s[bad[0]]:.3f} s"
            )
        return PolicyAction(accel_mps2=acc), new


def _rebuild(source: Any, state_size: int, state0: Any, name: str) -> CompiledPolicy:
    return CompiledPolicy(source, state_size, state0, name)


def pack_observation(obs: Observation) -> tuple[np.ndarray, np.ndarray]:
    """(ego [B, N_EGO], objs [B, N_OBJ, N]) float64 of an Observation (rows E_*, O_*)."""
    b, n = obs.batch_size, obs.n_objects
    ego = np.empty((b, N_EGO))
    for r, f in enumerate(EGO_ROWS):
        ego[:, r] = np.broadcast_to(np.asarray(getattr(obs, f), dtype=np.float64), (b,))
    objs = np.empty((b, N_OBJ, n))
    for r, f in enumerate(OBJ_ROWS):
        objs[:, r, :] = np.broadcast_to(np.asarray(getattr(obs, f), dtype=np.float64), (b, n))
    return ego, objs


_RUN_BATCH: Any = None


def run_batch(fn: Any, ego: np.ndarray, objs: np.ndarray, state: np.ndarray) -> np.ndarray:
    """[B] the compiled ``fn`` on each variant's rows (state [B, S] updated in place)."""
    global _RUN_BATCH
    numba = _numba()
    if _RUN_BATCH is None:

        @numba.njit(nogil=True)  # a closure: not cached (compiles in ~0.5 s)
        def _run(fns, ego, objs, state):  # type: ignore[no-untyped-def]
            f = fns[0]
            out = np.empty(ego.shape[0])
            for i in range(ego.shape[0]):
                out[i] = f(ego[i], objs[i], state[i])
            return out

        _RUN_BATCH = _run
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", numba.NumbaExperimentalFeatureWarning)
        return _RUN_BATCH((fn,), np.ascontiguousarray(ego), np.ascontiguousarray(objs), state)


__all__ = [
    "CompiledPolicy", "E_ACCEL", "E_COLLIDED", "E_CRUISE", "E_DT", "E_LENGTH", "E_MAX_ACCEL",
    "E_MAX_DECEL", "E_PATH_LEN", "E_S", "E_SPEED", "E_T", "E_WIDTH", "EGO_ROWS", "N_EGO",
    "N_OBJ", "OBJ_ROWS", "O_AGE", "O_CATEGORY", "O_GAP", "O_LATERAL", "O_LENGTH", "O_VALID",
    "O_VX", "O_VY", "O_WIDTH", "O_X", "O_Y", "O_YAW", "SIGNATURE_TEXT", "check_function",
    "pack_observation", "run_batch", "signature",
]  # fmt: skip
