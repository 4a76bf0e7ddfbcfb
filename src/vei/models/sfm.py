"""Social-force e-scooter rider (paper Section III-C; DESIGN.md "Models").

``m a = f_des + f_veh`` on a point mass, integrated with semi-implicit Euler:

- ``f_des = k_des (v_des - v)``;
- ``v_des = v0 (g - p) / sqrt(|g - p|^2 + sigma^2)`` ('normalised', default: speed ~v0 far
  from the goal g, decaying to 0 at it) or the paper's literal
  ``v_des = v0 (g - p) / (|g - p|^2 + sigma^2)`` ('paper');
- ``f_rider = A_r exp(-b_r d) n`` from every other social-force rider and recorded
  pedestrian when several riders are simulated (:func:`rider_force`; d = gap between
  their discs);
- ``f_veh = A exp(-b d) n``, d = distance from the vehicle's influential point q to the
  rider, n = unit vector from q to the rider. Where the rider is inside the vehicle's box
  (d = 0) n points from the box centre to the rider (or along the vehicle's heading if
  they coincide).

Pure functions over arrays of any broadcastable shape (the engine uses ``[B]``); vectors
are passed as separate x / y component arrays. SI units throughout.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from vei.models import sfm_core as core

FloatArray = npt.NDArray[np.float64]
ArrayLike = npt.ArrayLike

#: Gap [m] beyond which another rider / pedestrian exerts no repulsion (rider_force).
RIDER_FORCE_CUTOFF_M = core.RIDER_FORCE_CUTOFF_M


def desired_velocity(
    px_m: ArrayLike,
    py_m: ArrayLike,
    gx_m: ArrayLike,
    gy_m: ArrayLike,
    v0_mps: ArrayLike,
    sigma_m: ArrayLike,
    paper_form: ArrayLike = False,
) -> tuple[FloatArray, FloatArray]:
    """Desired velocity v_des towards the goal g.

    Args:
        px_m, py_m: rider position [...] (m).
        gx_m, gy_m: goal position s_des [...] (m).
        v0_mps: nominal speed v0 [...] (m/s).
        sigma_m: regulariser sigma [...] (m), > 0.
        paper_form: [...] bool; True = the paper's literal form (denominator
            |d|^2 + sigma^2, so the speed is v0 |d| / (|d|^2 + sigma^2), at most
            v0 / (2 sigma) in m/s when v0 and sigma are read as numbers), False = normalised
            (denominator sqrt(|d|^2 + sigma^2): speed v0 |d| / sqrt(|d|^2 + sigma^2)).
    Returns:
        (vx_mps, vy_mps) [...].
    """
    f64 = np.float64
    vx, vy = core.desired_velocity_core(
        np.asarray(px_m, f64), np.asarray(py_m, f64), np.asarray(gx_m, f64),
        np.asarray(gy_m, f64), np.asarray(v0_mps, f64), np.asarray(sigma_m, f64),
        np.asarray(paper_form, dtype=bool),
    )  # fmt: skip
    return np.asarray(vx), np.asarray(vy)


def destination_force(
    vdes_x_mps: ArrayLike,
    vdes_y_mps: ArrayLike,
    vx_mps: ArrayLike,
    vy_mps: ArrayLike,
    k_des_nspm: ArrayLike,
) -> tuple[FloatArray, FloatArray]:
    """f_des = k_des (v_des - v).

    Args:
        vdes_x_mps, vdes_y_mps: desired velocity [...] (m/s).
        vx_mps, vy_mps: current velocity [...] (m/s).
        k_des_nspm: gain [...] (N s/m).
    Returns:
        (fx_n, fy_n) [...] force [N].
    """
    k = np.asarray(k_des_nspm, dtype=np.float64)
    fx, fy = core.destination_force_core(
        np.asarray(vdes_x_mps), np.asarray(vdes_y_mps), np.asarray(vx_mps), np.asarray(vy_mps), k
    )
    return np.asarray(fx), np.asarray(fy)


def influential_point(
    px_m: ArrayLike,
    py_m: ArrayLike,
    ego_x_m: ArrayLike,
    ego_y_m: ArrayLike,
    ego_yaw_rad: ArrayLike,
    ego_length_m: ArrayLike,
    ego_width_m: ArrayLike,
    front_bumper: ArrayLike = False,
) -> tuple[FloatArray, FloatArray]:
    """The ego's influential point s_influence for a rider at p.

    Args:
        px_m, py_m: rider position [...] (m).
        ego_x_m, ego_y_m, ego_yaw_rad, ego_length_m, ego_width_m: ego box [...] (m, rad).
        front_bumper: [...] bool; True = centre of the front edge, False = the point of
            the ego's box closest to the rider.
    Returns:
        (qx_m, qy_m) [...].
    """
    qx, qy = core.influential_point_core(
        np.asarray(px_m, dtype=np.float64), np.asarray(py_m, dtype=np.float64),
        np.asarray(ego_x_m, dtype=np.float64), np.asarray(ego_y_m, dtype=np.float64),
        np.cos(ego_yaw_rad), np.sin(ego_yaw_rad),
        0.5 * np.asarray(ego_length_m, dtype=np.float64),
        0.5 * np.asarray(ego_width_m, dtype=np.float64),
        np.asarray(front_bumper, dtype=bool),
    )  # fmt: skip
    return np.asarray(qx), np.asarray(qy)


def vehicle_force(
    px_m: ArrayLike,
    py_m: ArrayLike,
    qx_m: ArrayLike,
    qy_m: ArrayLike,
    a_veh_n: ArrayLike,
    b_veh_per_m: ArrayLike,
    ego_x_m: ArrayLike | None = None,
    ego_y_m: ArrayLike | None = None,
    ego_yaw_rad: ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray]:
    """f_veh = A exp(-b d) n from the influential point q to the rider p.

    Args:
        px_m, py_m: rider position [...] (m).
        qx_m, qy_m: influential point [...] (m).
        a_veh_n: amplitude A [...] (N). b_veh_per_m: decay b [...] (1/m).
        ego_x_m, ego_y_m, ego_yaw_rad: ego centre and heading, used for the direction n
            only where p coincides with q (rider inside the box): n then points from the
            ego centre to the rider, or along the ego's heading if they coincide too.
    Returns:
        (fx_n, fy_n) [...] force [N].
    """
    mag, nx, ny, tiny = core.repulsion_core(
        np.asarray(px_m, dtype=np.float64), np.asarray(py_m, dtype=np.float64),
        np.asarray(qx_m, dtype=np.float64), np.asarray(qy_m, dtype=np.float64),
        np.asarray(a_veh_n, dtype=np.float64), np.asarray(b_veh_per_m, dtype=np.float64),
    )  # fmt: skip
    if np.any(tiny):
        if ego_x_m is None or ego_y_m is None or ego_yaw_rad is None:
            ux, uy = np.ones_like(nx), np.zeros_like(ny)
        else:
            ux, uy = core.away_from_centre_core(
                np.asarray(px_m, dtype=np.float64), np.asarray(py_m, dtype=np.float64),
                np.asarray(ego_x_m, dtype=np.float64), np.asarray(ego_y_m, dtype=np.float64),
                np.cos(ego_yaw_rad), np.sin(ego_yaw_rad),
            )  # fmt: skip
        nx, ny = np.where(tiny, ux, nx), np.where(tiny, uy, ny)
    return np.asarray(mag * nx), np.asarray(mag * ny)


def cap_force(fx_n: ArrayLike, fy_n: ArrayLike, fmax_n: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """The rider's force capped at the magnitude fmax (max_accel m) [N]: scaled by
    :func:`vei.models.sfm_core.cap_factor_core` where |F| > fmax, unchanged elsewhere.

    Args:
        fx_n, fy_n: force [...] (N). fmax_n: cap [...] (N, > 0).
    Returns:
        (fx_n, fy_n) [...].
    """
    fx, fy = np.asarray(fx_n, dtype=np.float64), np.asarray(fy_n, dtype=np.float64)
    fmag = np.sqrt(fx * fx + fy * fy)
    scale = np.where(fmag > fmax_n, core.cap_factor_core(fmag, fmax_n), 1.0)
    return fx * scale, fy * scale


def cap_speed(
    x0_m: ArrayLike, y0_m: ArrayLike, px_m: ArrayLike, py_m: ArrayLike, vx_mps: ArrayLike,
    vy_mps: ArrayLike, speed_mps: ArrayLike, vmax_mps: ArrayLike, dt_s: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:  # fmt: skip
    """After a step from (x0, y0) to (px, py) [m] with velocity (vx, vy) and speed [m/s]:
    the velocity capped at vmax [m/s] (:func:`vei.models.sfm_core.cap_factor_core`) and,
    where capped, the position stepped again with it (``p0 + v dt``, as the step).

    Returns:
        (px_m, py_m, vx_mps, vy_mps, speed_mps) [...].
    """
    speed = np.asarray(speed_mps, dtype=np.float64)
    over = speed > vmax_mps
    sc = np.where(over, core.cap_factor_core(speed, vmax_mps), 1.0)
    vx, vy, sp = np.asarray(vx_mps) * sc, np.asarray(vy_mps) * sc, speed * sc
    px = np.where(over, np.asarray(x0_m) + vx * dt_s, px_m)
    py = np.where(over, np.asarray(y0_m) + vy * dt_s, py_m)
    return px, py, vx, vy, sp


def point_mass_step(
    px_m: ArrayLike,
    py_m: ArrayLike,
    vx_mps: ArrayLike,
    vy_mps: ArrayLike,
    fx_n: ArrayLike,
    fy_n: ArrayLike,
    mass_kg: ArrayLike,
    dt_s: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """One semi-implicit (symplectic) Euler step of a point mass.

    ``v' = v + F/m dt; p' = p + v' dt``. Under a constant force from (p0, v0) after n steps
    (t = n dt): ``v_n = v0 + a t`` exactly and ``p_n = p0 + v0 t + a t^2 / 2 + a t dt / 2``,
    i.e. the position error against the analytic solution is exactly ``a t dt / 2``.

    Args:
        px_m, py_m, vx_mps, vy_mps: state [...] (m, m/s).
        fx_n, fy_n: force [...] (N). mass_kg: [...] (kg). dt_s: step (s).
    Returns:
        (px_m, py_m, vx_mps, vy_mps) after the step.
    """
    out = core.point_mass_core(
        np.asarray(px_m), np.asarray(py_m), np.asarray(vx_mps), np.asarray(vy_mps),
        np.asarray(fx_n), np.asarray(fy_n), np.asarray(mass_kg, dtype=np.float64), dt_s,
    )  # fmt: skip
    return tuple(np.asarray(o) for o in out)  # type: ignore[return-value]


def social_force(
    px_m: ArrayLike,
    py_m: ArrayLike,
    vx_mps: ArrayLike,
    vy_mps: ArrayLike,
    gx_m: ArrayLike,
    gy_m: ArrayLike,
    ego_x_m: ArrayLike,
    ego_y_m: ArrayLike,
    ego_yaw_rad: ArrayLike,
    ego_length_m: ArrayLike,
    ego_width_m: ArrayLike,
    *,
    k_des_nspm: ArrayLike,
    v0_mps: ArrayLike,
    sigma_m: ArrayLike,
    a_veh_n: ArrayLike,
    b_veh_per_m: ArrayLike,
    use_vehicle_force: ArrayLike = True,
    paper_form: ArrayLike = False,
    front_bumper: ArrayLike = False,
) -> tuple[FloatArray, FloatArray]:
    """Total social force f_des + f_veh on the rider [N] (f_veh only where enabled).

    Args:
        px_m, py_m, vx_mps, vy_mps: rider state [...] (m, m/s).
        gx_m, gy_m: goal s_des [...] (m).
        ego_x_m, ego_y_m, ego_yaw_rad, ego_length_m, ego_width_m: ego box [...].
        k_des_nspm: effective destination gain [...] (N s/m) (k_des * k_des_factor).
        v0_mps, sigma_m, a_veh_n, b_veh_per_m: model parameters [...].
        use_vehicle_force, paper_form, front_bumper: [...] bool switches.
    Returns:
        (fx_n, fy_n) [...].
    """
    vdx, vdy = desired_velocity(px_m, py_m, gx_m, gy_m, v0_mps, sigma_m, paper_form)
    fx, fy = destination_force(vdx, vdy, vx_mps, vy_mps, k_des_nspm)
    use = np.asarray(use_vehicle_force, dtype=bool)
    if use.ndim == 0 and not bool(use):
        return fx, fy
    qx, qy = influential_point(
        px_m, py_m, ego_x_m, ego_y_m, ego_yaw_rad, ego_length_m, ego_width_m, front_bumper
    )
    hx, hy = vehicle_force(px_m, py_m, qx, qy, a_veh_n, b_veh_per_m, ego_x_m, ego_y_m, ego_yaw_rad)
    if use.ndim == 0:
        return fx + hx, fy + hy
    return fx + np.where(use, hx, 0.0), fy + np.where(use, hy, 0.0)


def rider_force(
    px_m: ArrayLike,
    py_m: ArrayLike,
    qx_m: ArrayLike,
    qy_m: ArrayLike,
    radii_m: ArrayLike,
    a_rider_n: ArrayLike,
    b_rider_per_m: ArrayLike,
) -> tuple[FloatArray, FloatArray]:
    """Repulsion ``A_r exp(-b_r d) n`` on a rider at p from another rider / pedestrian at q.

    ``d = |p - q| - radii`` is the gap between the two agents' discs (negative where they
    overlap: the force keeps growing, it is not clipped), ``n = (p - q) / |p - q|``. Where
    the centres coincide (|p - q| < 1e-9 m) the direction is undefined and the force is 0.
    Agents farther apart than ``RIDER_FORCE_CUTOFF_M`` (gap) exert no force (less than
    A_r exp(-10 b_r): 2e-6 N at the defaults).

    Args:
        px_m, py_m: position of the rider the force acts on [...] (m).
        qx_m, qy_m: position of the other agent [...] (m).
        radii_m: sum of the two radii [...] (m).
        a_rider_n: amplitude A_r [...] (N). b_rider_per_m: decay b_r [...] (1/m).
    Returns:
        (fx_n, fy_n) [...] force [N].
    """
    dx, dy, dc, gap, acts = core.rider_gap_core(
        np.asarray(px_m, dtype=np.float64), np.asarray(py_m, dtype=np.float64),
        np.asarray(qx_m, dtype=np.float64), np.asarray(qy_m, dtype=np.float64),
        np.asarray(radii_m, dtype=np.float64),
    )  # fmt: skip
    inv = np.where(
        acts,
        core.rider_repulsion_core(
            np.where(acts, dc, 1.0), gap,
            np.asarray(a_rider_n, dtype=np.float64), np.asarray(b_rider_per_m, dtype=np.float64),
        ),
        0.0,
    )  # fmt: skip
    return inv * dx, inv * dy


def speed_from_recording(
    speed_mps: ArrayLike,
    lookahead_m: float,
    sigma_m: float,
    fallback_v0_mps: float,
    fallback_max_speed_mps: float | None,
    moving_threshold_mps: float = 0.5,
) -> tuple[float, float | None]:
    """Speed parameters of a calibrated rider from its own recorded speeds.

    v0 is chosen so that the cruise speed of the normalised desired velocity at the
    look-ahead distance, ``v0 L / sqrt(L^2 + sigma^2)``, equals the median of the recorded
    speeds above ``moving_threshold_mps``; the speed limit is the 99th percentile of the
    recorded speeds (at least that median). A rider that never moves keeps the fallbacks.

    Args:
        speed_mps: [N] recorded speeds [m/s] (NaN ignored).
        lookahead_m: look-ahead L [m] (> 0). sigma_m: sigma [m] (> 0).
        fallback_v0_mps, fallback_max_speed_mps: used when no sample moves.
        moving_threshold_mps: a sample moves above this speed [m/s].
    Returns:
        (v0_mps, max_speed_mps).
    """
    sp = np.asarray(speed_mps, dtype=np.float64)
    sp = sp[np.isfinite(sp)]
    moving = sp[sp > moving_threshold_mps]
    if moving.size == 0:
        return float(fallback_v0_mps), fallback_max_speed_mps
    med = float(np.median(moving))
    v0 = med * float(np.hypot(lookahead_m, sigma_m)) / float(lookahead_m)
    return v0, max(float(np.quantile(sp, 0.99)), med)
