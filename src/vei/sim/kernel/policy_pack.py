"""Which policy variants the compiled kernel runs, and their packed group (no numba).

The compiled kernel runs a policy variant (ego mode 3) when its policy is the built-in
``aeb`` or ``idm`` or a :class:`vei.policy.compiled.CompiledPolicy`, with ideal
perception (the perception delay only: no sensor model) and no V2X; every other policy
variant runs the NumPy step loop (:class:`vei.sim.observe.PolicyDriver`). One user
function per kernel run: variants of a second compiled policy in the same batch run the
NumPy loop (through the same function, :meth:`CompiledPolicy.act`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from vei.policy.aeb import AEB, AEB_PARAM_FIELDS
from vei.policy.compiled import CompiledPolicy
from vei.policy.idm import IDM, IDM_PARAM_FIELDS
from vei.sim.state import EGO_POLICY

#: kind codes of the group's kind [B]: 0 not a kernel policy, 1 aeb, 2 idm, 3 a user's.
KIND_AEB, KIND_IDM, KIND_USER = 1, 2, 3
#: Rows of the policy parameter matrix PP [N_PP, B] (VariantParams fields, in order).
PP_FIELDS: tuple[str, ...] = (*AEB_PARAM_FIELDS.values(), *IDM_PARAM_FIELDS.values())
PP_WARN, PP_PARTIAL, PP_FULL, PP_AEB_PART_A, PP_AEB_FULL_A = 0, 1, 2, 3, 4
PP_IDM_A, PP_IDM_B, PP_IDM_T, PP_IDM_S0, PP_IDM_DELTA = 5, 6, 7, 8, 9
N_PP = len(PP_FIELDS)


def _enabled(cfg: Any) -> bool:
    return cfg is not None and bool(getattr(cfg, "enabled", True))


def policy_kind(policy: Any, perception: Any, v2x: Any) -> int:
    """The kind code of one policy variant (0: the NumPy loop runs it)."""
    if _enabled(perception) or _enabled(v2x):
        return 0
    if type(policy) is AEB:
        return KIND_AEB
    if type(policy) is IDM:
        return KIND_IDM
    if isinstance(policy, CompiledPolicy):
        return KIND_USER
    return 0


def kernel_kinds(params: Any) -> tuple[npt.NDArray[np.int64], Any]:
    """([B] kind codes, the user function the kernel runs or None): 0 for every variant
    that is not a policy variant or whose policy runs the NumPy loop (the variants of
    compiled policies other than the first one's function included)."""
    b = params.batch_size
    kinds = np.zeros(b, dtype=np.int64)
    fn = None
    for i in np.flatnonzero(np.asarray(params.ego_mode) == EGO_POLICY):
        pol = params.policy[i]
        k = policy_kind(pol, params.perception[i], params.v2x[i])
        if k == KIND_USER:
            if fn is None:
                fn = pol.function
            elif pol.function is not fn:
                k = 0
        kinds[i] = k
    return kinds, fn


def kernel_mask(params: Any) -> npt.NDArray[np.bool_]:
    """[B] the variants the compiled kernel can run: every non-policy variant and the
    policy variants of :func:`kernel_kinds`."""
    kinds, _ = kernel_kinds(params)
    return (np.asarray(params.ego_mode) != EGO_POLICY) | (kinds > 0)


def policy_group(arrays: Any, params: Any) -> tuple[Any, ...]:
    """The kernel's ``pol`` group (vei.sim.kernel.policy) for ``params`` [B]."""
    from vei.sim.observe import object_table

    b = params.batch_size
    kinds, fn = kernel_kinds(params)
    pp = np.ascontiguousarray(
        np.stack([np.asarray(getattr(params, f), dtype=np.float64) for f in PP_FIELDS])
    )
    size = 0
    for i in np.flatnonzero(kinds == KIND_USER):
        size = params.policy[i].state_size
        break
    st0 = np.zeros((b, size))
    for i in np.flatnonzero(kinds == KIND_USER):
        st0[i] = params.policy[i].state0
    length, width, cat = object_table(arrays)
    delay = params.delay_steps(arrays.dt_s)
    hp = int(delay[kinds > 0].max()) + 1 if (kinds > 0).any() else 1
    path_len = float(arrays.ego_track.data[-1, arrays.ego_track.col("s_m")])
    half_diag = 0.5 * np.hypot(length, width)  # vei.models.ego_core.half_diagonal_core
    obj = np.ascontiguousarray(np.stack([length, width, cat.astype(np.float64), half_diag]))
    # the replayed others' truth of every step, as vei.sim.observe.ground_truth computes it
    no = len(arrays.other_ids)
    otr = np.zeros((6, arrays.n_steps, no))
    if no:
        yaw, sp = arrays.other_yaw_rad, arrays.other_speed_mps
        otr[0], otr[1], otr[2] = arrays.other_x_m, arrays.other_y_m, yaw
        otr[3], otr[4], otr[5] = sp * np.cos(yaw), sp * np.sin(yaw), arrays.other_active
    return (
        None if fn is None else (fn,), kinds, pp, np.ascontiguousarray(st0),
        obj, hp, path_len,
        np.full(b, -1, dtype=np.int64), np.zeros(b), otr,
    )  # fmt: skip


def check_outputs(params: Any, group: tuple[Any, ...], dt_s: float) -> None:
    """PolicyError naming the first variant (its label), step and value where a user's
    compiled policy returned a non-finite acceleration in the run of ``group``."""
    bad, vals = group[7], group[8]
    hit = np.flatnonzero(bad >= 0)
    if not hit.size:
        return
    from vei.errors import PolicyError

    i = int(hit[0])
    k = int(bad[i])
    more = f" (and {hit.size - 1} more variants)" if hit.size > 1 else ""
    raise PolicyError(
        f"compiled policy {params.policy[i].name}: returned {vals[i]} (not a finite "
        f"acceleration) for variant {params.labels[i]!r} at step {k} (t = {k * dt_s:.3f} s)"
        f"{more}"
    )


__all__ = [
    "check_outputs",
    "KIND_AEB", "KIND_IDM", "KIND_USER", "N_PP", "PP_FIELDS", "kernel_kinds", "kernel_mask",
    "policy_group", "policy_kind",
]  # fmt: skip
