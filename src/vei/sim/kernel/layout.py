"""Packed layout of the compiled kernel's arrays (shared by vei.sim.kernel and the kernel).

Rows of the parameter matrix ``P [N_PARAMS, B]`` (one per :data:`PARAM_FIELDS`, a
:class:`vei.sim.params.VariantParams` field), of the float output ``O [B, N_OUT, T]``, and
the :class:`vei.sim.state.SimState` fields of the initial / final state rows. The packing
side (:mod:`vei.sim.kernel`) and the compiled side (:mod:`vei.sim.kernel.loop` and its
helpers) both import these names from here, so neither imports the other's module.
"""

from __future__ import annotations

from vei.config.settings import SETTINGS

#: VariantParams fields in the order of the rows of P: the settings declared as kernel rows
#: (vei.config.settings.SETTINGS, in their order).
PARAM_FIELDS: tuple[str, ...] = tuple(s.field for s in SETTINGS if s.kernel)
N_PARAMS = len(PARAM_FIELDS)


def row(field: str) -> int:
    """The row of P holding the VariantParams field ``field`` (a plain int: numba reads the
    P_* names below as compile-time constants)."""
    return PARAM_FIELDS.index(field)


# Rows of the packed parameter matrix P [N_PARAMS, B] (names the compiled kernel imports).
P_SHIFT = row("time_shift_s")
P_SFM = row("rider_sfm")
P_KDES = row("k_des_nspm")
P_AVEH = row("a_veh_n")
P_BVEH = row("b_veh_per_m")
P_V0 = row("v0_mps")
P_MASS = row("mass_kg")
P_SIGMA = row("sigma_m")
P_LOOK = row("lookahead_m")
P_ARRIVE = row("arrive_radius_m")
P_USEVF = row("use_vehicle_force")
P_PAPERV = row("paper_vdes")
P_FRONTB = row("front_bumper")
P_VMAX = row("max_speed_mps")
P_AMAX_R = row("max_accel_mps2")
P_MODE = row("ego_mode")
P_VD = row("cruise_speed_mps")
P_KP = row("kp")
P_KI = row("ki")
P_KD = row("kd")
P_ILIM = row("integral_limit")
P_IWIN = row("integral_window_s")
P_AMAX = row("max_accel_mps2_ego")
P_DMAX = row("max_decel_mps2_ego")
P_LAG = row("actuator_lag_s")
P_TSAFE = row("t_safe_s")
P_DBUF = row("d_buf_m")
P_AMIN = row("a_min_mps2")
P_HALFW = row("corridor_half_width_m")
P_RANGE = row("detection_range_m")
P_RELEASE = row("release_margin_m")
P_RECTOL = row("recover_tolerance_mps")
P_PAPERLAW = row("paper_per_step")
P_DELAY = row("perception_delay_s")
P_SFR = row("speed_from_recording")
P_ARR = row("a_rider_n")
P_BRR = row("b_rider_per_m")
P_USERF = row("use_rider_force")
# issue 32: the rider brakes for a standing or slow car in its way
P_OBST = row("obstacle_braking")
P_OBSTA = row("obstacle_decel_mps2")
P_OBSTM = row("obstacle_margin_m")
P_OBSTV = row("obstacle_speed_mps")
# issue 24: the rider's decision (vei.models.decision_core)
P_DECIDE = row("decide")
P_TC = row("critical_gap_s")
P_HORIZON = row("decision_horizon_s")
P_YDEC = row("yield_decel_mps2")
P_STOPM = row("stop_margin_m")
P_CLEARM = row("clear_margin_m")
# issue 24: reacting cars (vei.models.traffic_core)
P_REACT = row("cars_react")
P_CV0 = row("car_v0_mps")
P_CT = row("car_headway_s")
P_CS0 = row("car_min_gap_m")
P_CA = row("car_accel_mps2")
P_CB = row("car_decel_mps2")
P_CDELTA = row("car_delta")
P_CBMAX = row("car_max_decel_mps2")
P_CREACT = row("car_reaction_s")
P_CTRIG = row("car_trigger_mps2")

# Rows of the float output O [N_OUT, T, B] (same order as vei.sim.result._RECORDED floats).
O_S, O_X, O_Y, O_YAW, O_V, O_A, O_U, O_RX, O_RY, O_RYAW, O_RSP, O_RVX, O_RVY, O_RA = range(14)
N_OUT = 14

#: SimState float fields in the packed order of the kernel's S0 / FS rows.
FLOAT_FIELDS = (
    "ego_s_m", "ego_x_m", "ego_y_m", "ego_yaw_rad", "ego_v_mps", "ego_a_mps2", "ego_act_mps2", "ego_cmd",
    "pid_integral_m", "pid_prev_error_mps", "cap_state", "rider_x_m", "rider_y_m", "rider_yaw_rad",
    "rider_vx_mps", "rider_vy_mps", "rider_speed_mps", "rider_a_mps2", "rider_prog_m",
    "rider_decision",
)  # fmt: skip
#: SimState bool fields in the order of B0 / FB rows.
BOOL_FIELDS = ("rider_active", "rider_started", "collided", "rider_done")
