"""Pure conversions between vei's plane frame and CARLA's, and CARLA defaults.

vei's world frame is right-handed: x east, y north [m], yaw counter-clockwise from +x
[rad] (the OpenDRIVE inertial frame of the scenario's map). CARLA (Unreal Engine) is
left-handed: it loads an OpenDRIVE map with its y axis negated, and its yaw is in degrees,
clockwise seen from above. So, at the boundary:

    x_carla = x,  y_carla = -y,  yaw_carla_deg = -degrees(yaw_rad)

and the same flip for velocities (vy_carla = -vy). These functions import nothing of
CARLA (they work on floats and NumPy arrays of any shape) so they are tested without a
server; ``vei.sim.backends.carla`` wraps them in ``carla.Location``/``carla.Rotation``.
"""

from __future__ import annotations

import numpy as np

#: Default CARLA blueprint per vei category. CARLA has no e-scooter: the default for
#: ``escooter`` is the small bicycle ``vehicle.diamondback.century`` (a two-wheeler with
#: a rider, close to an e-scooter's footprint and speeds); change it with the
#: ``blueprints`` argument (e.g. a walker ``walker.pedestrian.0001``).
DEFAULT_BLUEPRINTS: dict[str, str] = {
    "ego": "vehicle.lincoln.mkz_2020",
    "vehicle": "vehicle.tesla.model3",
    "escooter": "vehicle.diamondback.century",
    "cyclist": "vehicle.bh.crossbike",
    "pedestrian": "walker.pedestrian.0001",
}


def wrap_deg(angle_deg: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles [deg] to [-180, 180). Shape preserved; floats in, float out."""
    out = (np.asarray(angle_deg, dtype=float) + 180.0) % 360.0 - 180.0
    return float(out) if np.ndim(out) == 0 else out


def wrap_rad(angle_rad: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles [rad] to [-pi, pi). Shape preserved; floats in, float out."""
    out = (np.asarray(angle_rad, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi
    return float(out) if np.ndim(out) == 0 else out


def world_to_carla_xy(x_m, y_m):
    """Plane position (x east, y north) [m] -> CARLA location (x, y) [m]; any shape."""
    return np.asarray(x_m, dtype=float) * 1.0, -np.asarray(y_m, dtype=float)


def carla_to_world_xy(x_carla_m, y_carla_m):
    """CARLA location (x, y) [m] -> plane position (x east, y north) [m]; any shape."""
    return np.asarray(x_carla_m, dtype=float) * 1.0, -np.asarray(y_carla_m, dtype=float)


def yaw_to_carla_deg(yaw_rad):
    """Yaw CCW from +x [rad] -> CARLA yaw [deg] (clockwise), wrapped to [-180, 180)."""
    return wrap_deg(-np.degrees(np.asarray(yaw_rad, dtype=float)))


def carla_deg_to_yaw(yaw_carla_deg):
    """CARLA yaw [deg] (clockwise) -> yaw CCW from +x [rad], wrapped to [-pi, pi)."""
    return wrap_rad(-np.radians(np.asarray(yaw_carla_deg, dtype=float)))


def world_to_carla_velocity(vx_mps, vy_mps):
    """Plane velocity (vx east, vy north) [m/s] -> CARLA velocity (vx, vy) [m/s]."""
    return np.asarray(vx_mps, dtype=float) * 1.0, -np.asarray(vy_mps, dtype=float)


def carla_to_world_velocity(vx_carla_mps, vy_carla_mps):
    """CARLA velocity (vx, vy) [m/s] -> plane velocity (vx east, vy north) [m/s]."""
    return np.asarray(vx_carla_mps, dtype=float) * 1.0, -np.asarray(vy_carla_mps, dtype=float)


def command_to_pedals(command: float) -> tuple[float, float]:
    """Longitudinal command in [-1, 1] -> (throttle, brake), each in [0, 1].

    Positive commands are throttle, negative ones brake (CARLA's VehicleControl has the
    two pedals separately); values outside [-1, 1] are clipped.
    """
    c = float(np.clip(command, -1.0, 1.0))
    return (c, 0.0) if c >= 0.0 else (0.0, -c)


def pure_pursuit_steer(
    x_m: float,
    y_m: float,
    yaw_rad: float,
    path_xy_m: np.ndarray,
    *,
    lookahead_m: float,
    wheelbase_m: float,
    max_steer_rad: float,
) -> float:
    """Pure-pursuit steering on a path, as a CARLA steer value in [-1, 1].

    Args:
        x_m, y_m, yaw_rad: the vehicle's rear-axle position [m] and yaw [rad] (vei frame).
        path_xy_m: [N, 2] path vertices [m] (vei frame), in driving order.
        lookahead_m: look-ahead distance [m] (> 0).
        wheelbase_m: wheelbase [m] (> 0).
        max_steer_rad: the vehicle's maximum road-wheel angle [rad] (steer = +-1).

    Returns:
        steer in [-1, 1], CARLA's sign: positive steers right (clockwise), so a target
        on the vehicle's left (vei: positive lateral offset) gives a negative value.

    The target is the first path point at least ``lookahead_m`` from the vehicle, searched
    from the path point closest to it (the last point if none is that far). The road-wheel
    angle is ``atan(2 L sin(alpha) / ld)`` with alpha the target's bearing in the vehicle
    frame and ld its distance.
    """
    path = np.asarray(path_xy_m, dtype=float)
    if path.ndim != 2 or path.shape[1] != 2 or len(path) == 0:
        raise ValueError("path_xy_m must have shape [N, 2] with N >= 1")
    d = np.hypot(path[:, 0] - x_m, path[:, 1] - y_m)
    i0 = int(np.argmin(d))
    ahead = np.nonzero(d[i0:] >= lookahead_m)[0]
    target = path[i0 + int(ahead[0])] if ahead.size else path[-1]
    dx, dy = target[0] - x_m, target[1] - y_m
    ld = float(np.hypot(dx, dy))
    if ld < 1e-6:
        return 0.0
    alpha = np.arctan2(dy, dx) - yaw_rad
    delta = float(np.arctan2(2.0 * wheelbase_m * np.sin(alpha), ld))
    return float(np.clip(-delta / max_steer_rad, -1.0, 1.0))
