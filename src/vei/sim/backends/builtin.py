"""The built-in engine as a :class:`~vei.sim.backends.base.Backend`: an ideal plant.

The world is the engine's own kinematics: each step the ego and the rider are where the
engine's step put them (the :class:`~vei.sim.backends.base.TickCommand`'s poses), and
the replayed road users are where the recording has them. Run through
:func:`~vei.sim.backends.base.run_backend`, it reproduces
:func:`vei.sim.engine.run_cases` (tested), which is what ``--backend builtin`` runs (the
batched engine, all configurations at once, much faster). Its use is as the reference
that every other backend's loop is compared with.
"""

from __future__ import annotations

from vei.sim.backends.base import Backend, ClosedLoop, EgoMeasurement, Measurement, TickCommand


class BuiltinBackend(Backend):
    """The engine's kinematics as the world (no external simulator)."""

    name = "builtin"

    def __init__(self) -> None:
        self._loop: ClosedLoop | None = None

    def load(self, loop: ClosedLoop) -> Measurement:
        """The engine's initial state as the measurement at t = 0."""
        self._loop = loop
        loop.steering = False  # the ego is placed, not steered
        st = loop.state
        return Measurement(
            ego=EgoMeasurement(
                float(st.ego_x_m[0]),
                float(st.ego_y_m[0]),
                float(st.ego_yaw_rad[0]),
                float(st.ego_v_mps[0]),
                float(st.ego_a_mps2[0]),
            )
        )

    def step(self, command: TickCommand) -> Measurement:
        """The ego where the command's kinematics put it (the rider stays the loop's own)."""
        return Measurement(
            ego=EgoMeasurement(
                command.ego_x_m,
                command.ego_y_m,
                command.ego_yaw_rad,
                command.ego_v_mps,
                command.ego_a_mps2,
            )
        )

    def unload(self) -> None:
        """Forget the run."""
        self._loop = None
