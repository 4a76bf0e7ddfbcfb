"""Packed layout of the compiled kernel's arrays (shared by vei.sim.kernel and the kernel).

Rows of the parameter matrix ``P [N_PARAMS, B]`` (one per :data:`PARAM_FIELDS`, a
:class:`vei.sim.params.VariantParams` field), of the float output ``O [B, N_OUT, T]``, and
the :class:`vei.sim.state.SimState` fields of the initial / final state rows. The packing
side (:mod:`vei.sim.kernel`) and the compiled side (:mod:`vei.sim._kernel_numba` and its
helpers) both import these names from here, so neither imports the other's module.
"""

from __future__ import annotations

# Rows of the packed parameter matrix P [N_PARAMS, B].
(
    P_SHIFT, P_SFM, P_KDES, P_AVEH, P_BVEH, P_V0, P_MASS, P_SIGMA, P_LOOK, P_ARRIVE, P_USEVF, P_PAPERV,
    P_FRONTB, P_VMAX, P_AMAX_R, P_MODE, P_VD, P_KP, P_KI, P_KD, P_ILIM, P_IWIN, P_AMAX, P_DMAX, P_LAG,
    P_TSAFE, P_DBUF, P_AMIN, P_HALFW, P_RANGE, P_RELEASE, P_RECTOL, P_PAPERLAW, P_DELAY,
    P_SFR, P_ARR, P_BRR, P_USERF,
) = range(38)  # fmt: skip
N_PARAMS = 38

# Rows of the float output O [N_OUT, T, B] (same order as vei.sim.result._RECORDED floats).
O_S, O_X, O_Y, O_YAW, O_V, O_A, O_U, O_RX, O_RY, O_RYAW, O_RSP, O_RVX, O_RVY, O_RA = range(14)
N_OUT = 14

#: SimState float fields in the packed order of the kernel's S0 / FS rows.
FLOAT_FIELDS = (
    "ego_s_m", "ego_x_m", "ego_y_m", "ego_yaw_rad", "ego_v_mps", "ego_a_mps2", "ego_act_mps2", "ego_cmd",
    "pid_integral_m", "pid_prev_error_mps", "cap_state", "rider_x_m", "rider_y_m", "rider_yaw_rad",
    "rider_vx_mps", "rider_vy_mps", "rider_speed_mps", "rider_a_mps2", "rider_prog_m",
)  # fmt: skip
#: SimState bool fields in the order of B0 / FB rows.
BOOL_FIELDS = ("rider_active", "rider_started", "collided", "rider_done")
#: VariantParams fields in the order of the rows of P.
PARAM_FIELDS = (
    "time_shift_s", "rider_sfm", "k_des_nspm", "a_veh_n", "b_veh_per_m", "v0_mps", "mass_kg", "sigma_m",
    "lookahead_m", "arrive_radius_m", "use_vehicle_force", "paper_vdes", "front_bumper", "max_speed_mps",
    "max_accel_mps2", "ego_mode", "cruise_speed_mps", "kp", "ki", "kd", "integral_limit", "integral_window_s",
    "max_accel_mps2_ego", "max_decel_mps2_ego", "actuator_lag_s", "t_safe_s", "d_buf_m", "a_min_mps2",
    "corridor_half_width_m", "detection_range_m", "release_margin_m", "recover_tolerance_mps",
    "paper_per_step", "perception_delay_s", "speed_from_recording", "a_rider_n", "b_rider_per_m",
    "use_rider_force",
)  # fmt: skip
assert len(PARAM_FIELDS) == N_PARAMS
