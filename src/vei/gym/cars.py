"""The vector env's reacting cars (``traffic.cars_react``), NumPy backend.

Reacting cars (vei.sim.traffic: IDM cars that notice a deviation from their recorded
leader) are stepped by the engine's own NumPy step (:func:`vei.sim.step.step`), the
vector env's backend 'numpy'; the vector env keeps, per environment, their SimState
fields (vei.sim.traffic.CAR_FLOAT_FIELDS, car_mode) and the contact latches and
secondary-collision summaries (vei.sim.contacts.initial_contact_state), which decide
when a touched car stops. The compiled backend refuses them by name (:data:`CARS_NUMBA`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: The refusal of the compiled backend (backend='numba') where cars react.
CARS_NUMBA = (
    "the vector env's compiled backend (backend='numba') does not model reacting cars "
    "(traffic.cars_react): use backend='numpy' (or 'auto'), which steps them with the "
    "engine's own step (docs/gym.md)"
)


def reacting_cars(world: Any) -> bool:
    """True where the configuration's cars react (traffic.cars_react) and some scenario of
    the world (vei.gym.world.World) has a reacting car."""
    return bool(world.scenarios[0].params.cars_react[0]) and any(
        ws.arrays.traffic.n for ws in world.scenarios
    )


def car_state_arrays(world: Any, b: int) -> dict[str, np.ndarray]:
    """Per-environment arrays of the reacting cars' and contact latches' SimState fields:
    name -> [b, ...] with each trailing axis padded to the largest scenario's (C cars or
    n_o others; the padded columns are never read), dtype of the engine's field."""
    from vei.sim.contacts import initial_contact_state
    from vei.sim.traffic import initial_traffic_state

    shapes: dict[str, tuple[tuple[int, ...], np.dtype]] = {}
    for ws in world.scenarios:
        a = ws.arrays
        f0 = {
            **initial_traffic_state(a, 1),
            **initial_contact_state(1, len(a.other_ids), a.traffic.n),
        }
        for name, v in f0.items():
            old = shapes.get(name, (v.shape[1:], v.dtype))[0]
            shapes[name] = (
                tuple(max(x, y) for x, y in zip(old, v.shape[1:], strict=True)),
                v.dtype,
            )
    return {name: np.zeros((b, *sh), dt) for name, (sh, dt) in shapes.items()}


__all__ = ["CARS_NUMBA", "car_state_arrays", "reacting_cars"]
