"""An example compiled ego policy: the engine's compiled kernel runs it (docs/policy.md).

The rule of ``examples/my_policy.py`` written as one numba function on arrays: brake at
``DECEL_MPS2`` while the time to reach the nearest road user in the ego's path is below
``TTC_BRAKE_S`` (or something in the path is closer than ``STOP_GAP_M``), else hold the
cruise speed with a proportional controller. It keeps one number of state per variant:
how long it has been braking [s] (``state[0]``), to show how a policy owns its memory.

Run it:  vei run --policy examples/my_compiled_policy.py:MyCompiledPolicy ...
         vei risk SCEN --policy examples/my_compiled_policy.py:MyCompiledPolicy
The same function runs through the Python policy API where the compiled kernel does not
run (``--kernel numpy``, a perception model, V2X); a test checks that both agree.
"""

from __future__ import annotations

import math

import numba

from vei.policy.compiled import (
    E_CRUISE,
    E_DT,
    E_SPEED,
    O_GAP,
    O_VALID,
    O_VX,
    CompiledPolicy,
)

TTC_BRAKE_S = 1.8  # brake below this time to collision [s]
DECEL_MPS2 = 6.0  # braking demand [m/s^2]
K_SPEED = 0.5  # speed controller gain [1/s]
STOP_GAP_M = 5.0  # keep braking while something in the path is closer than this [m]


@numba.njit
def brake_on_ttc(ego, objs, state):
    """Demanded acceleration [m/s^2] of one variant at one step.

    ego [N_EGO] and objs [N_OBJ, N] are read by the row names of vei.policy.compiled
    (E_*, O_*); state [1] is this variant's memory (time spent braking [s]), updated here.
    """
    ttc = math.inf
    near = math.inf
    for j in range(objs.shape[1]):
        if objs[O_VALID, j] > 0.5 and math.isfinite(objs[O_GAP, j]):
            gap = objs[O_GAP, j]
            near = min(near, gap)
            closing = -objs[O_VX, j]
            if closing > 0.1:
                ttc = min(ttc, gap / closing)
    if ttc < TTC_BRAKE_S or near < STOP_GAP_M:
        state[0] += ego[E_DT]
        return -DECEL_MPS2
    state[0] = 0.0
    return K_SPEED * (ego[E_CRUISE] - ego[E_SPEED])


#: ``--policy examples/my_compiled_policy.py:MyCompiledPolicy`` builds this.
MyCompiledPolicy = CompiledPolicy.factory(brake_on_ttc, state_size=1)
