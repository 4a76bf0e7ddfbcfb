"""Compiled kernel of the built-in engine (optional; needs numba).

The same model, the same order of operations and the same formulas as
:func:`vei.sim.engine.step` (the NumPy reference, which stays the pure step API), written
as one loop per variant over all steps and compiled with numba. Each variant is computed
independently of the others (``prange`` over variants, no reductions across them), so B
single runs equal one batch of B bit for bit, and two runs are bit-identical. Against the
NumPy path results agree to rounding (libm vs NumPy's vectorised exp/cos/atan2): a test
bounds the difference.

:func:`available` tells whether numba can be imported; :func:`run` is called by
:func:`vei.sim.engine.simulate` with ``kernel='numba'`` (or 'auto' when available).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from vei.errors import DependencyError

# Rows of the packed parameter matrix P [N_PARAMS, B].
(
    P_SHIFT, P_SFM, P_KDES, P_AVEH, P_BVEH, P_V0, P_MASS, P_SIGMA, P_LOOK, P_ARRIVE, P_USEVF, P_PAPERV,
    P_FRONTB, P_VMAX, P_AMAX_R, P_MODE, P_VD, P_KP, P_KI, P_KD, P_ILIM, P_IWIN, P_AMAX, P_DMAX, P_LAG,
    P_TSAFE, P_DBUF, P_AMIN, P_HALFW, P_RANGE, P_RELEASE, P_RECTOL, P_PAPERLAW, P_DELAY,
) = range(34)  # fmt: skip
N_PARAMS = 34

# Rows of the float output O [N_OUT, T, B] (same order as engine._RECORDED floats).
O_S, O_X, O_Y, O_YAW, O_V, O_A, O_U, O_RX, O_RY, O_RYAW, O_RSP, O_RVX, O_RVY, O_RA = range(14)
N_OUT = 14

_KERNEL: Any = None


def available() -> bool:
    """True when numba can be imported (the compiled kernel can run)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def _build() -> Any:  # noqa: C901 - one compiled function by design
    global _KERNEL
    if _KERNEL is not None:
        return _KERNEL
    try:
        import numba
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise DependencyError("the compiled engine kernel needs numba (pip install numba)") from exc

    njit = numba.njit

    @njit(cache=True, inline="always")
    def idx(t0: float, dt: float, n: int, q: float) -> tuple[int, float]:
        f = (q - t0) * (1.0 / dt)
        if f < 0.0:
            f = 0.0
        elif f > n - 1.0:
            f = n - 1.0
        i = int(f)
        if i > n - 2:
            i = max(n - 2, 0)
        return i, f - i

    @njit(cache=True, inline="always")
    def sat(ax, ay, ayaw, al, aw, bx, by, byaw, bl, bw) -> bool:  # type: ignore[no-untyped-def]
        ca, sa = math.cos(ayaw), math.sin(ayaw)
        cb, sb = math.cos(byaw), math.sin(byaw)
        dx, dy = bx - ax, by - ay
        hla, hwa, hlb, hwb = 0.5 * al, 0.5 * aw, 0.5 * bl, 0.5 * bw
        cd = abs(ca * cb + sa * sb)
        sd = abs(sa * cb - ca * sb)
        eps = 1e-9
        if abs(dx * ca + dy * sa) > hla + hlb * cd + hwb * sd + eps:
            return False
        if abs(-dx * sa + dy * ca) > hwa + hlb * sd + hwb * cd + eps:
            return False
        if abs(dx * cb + dy * sb) > hlb + hla * cd + hwa * sd + eps:
            return False
        if abs(-dx * sb + dy * cb) > hwb + hla * sd + hwa * cd + eps:
            return False
        return True

    @njit(cache=True, parallel=True)
    def kernel(  # type: ignore[no-untyped-def]
        T, dt, hist_len, record,
        path, p_s0, p_ds,  # ego path [10, N]: x y yaw cos sin, then their slopes
        etab, e_t0, e_dt,  # ego track [4, M]: s, speed, slopes
        rtab, r_t0, r_dt, r_tend,  # rider track [14, M]: x y yaw sp vx vy arc, slopes
        rpath, rp_s0, rp_ds, rp_len, rp_ex, rp_ey,  # rider path [10, N]
        Le, We, Lr, Wr,
        oX, oY, oYAW, oACT, oL, oW,  # others [T, no], [no]
        P,  # params [N_PARAMS, B]
        S0,  # initial float state [19, B] (layout of FS)
        B0,  # initial bool state [4, B] (active, started, collided, done) as uint8
        O,  # out float [N_OUT, T, B] (record) or [N_OUT, 1, B]
        OB,  # out uint8 [3, T, B]: cap_state, rider_active, collided
        OH,  # out uint8 [T, B, no]: hit_other latch
        H0,  # initial hit_other [B, no] uint8
        FS,  # final float state [19, B]: s x y yaw v a_rep a_act u pid_i pid_e cap rx ry ryaw rvx rvy rsp racc prog
        FB,  # final bool state [4, B]
        FH,  # final hist [4, hist_len, B]
        coll_t, min_d,  # [B]
    ):  # fmt: skip
        B = P.shape[1]
        n_p = path.shape[1]
        n_e = etab.shape[1]
        n_r = rtab.shape[1]
        n_rp = rpath.shape[1]
        no = oL.shape[0]
        reach = 0.5 * (math.hypot(Le, We) + math.hypot(Lr, Wr))
        for b in numba.prange(B):
            shift = P[P_SHIFT, b]
            sfm = P[P_SFM, b] > 0.5
            mode = int(P[P_MODE, b])
            delay = int(P[P_DELAY, b])
            vd = P[P_VD, b]
            # state
            s = S0[0, b]
            ex = S0[1, b]
            ey = S0[2, b]
            eyaw = S0[3, b]
            v = S0[4, b]
            a_rep = S0[5, b]
            a_act = S0[6, b]
            u = S0[7, b]
            pid_i = S0[8, b]
            pid_e = S0[9, b]
            cap = int(S0[10, b])
            rx = S0[11, b]
            ry = S0[12, b]
            ryaw = S0[13, b]
            rvx = S0[14, b]
            rvy = S0[15, b]
            rsp = S0[16, b]
            r_acc = S0[17, b]
            prog = S0[18, b]
            r_act = B0[0, b] > 0
            r_started = B0[1, b] > 0
            collided = B0[2, b] > 0
            r_done = B0[3, b] > 0
            hit = np.empty(no, dtype=np.bool_)
            for j in range(no):
                hit[j] = H0[b, j] > 0
            hx = np.zeros(hist_len)
            hy = np.zeros(hist_len)
            hyaw = np.zeros(hist_len)
            hact = np.zeros(hist_len)
            hx[0], hy[0], hyaw[0], hact[0] = rx, ry, ryaw, 1.0 if r_act else 0.0
            ct = np.nan
            if collided:
                ct = 0.0
            md = np.inf
            if r_act:
                md = math.sqrt((rx - ex) ** 2 + (ry - ey) ** 2)
            for k in range(T - 1):
                t_new = (k + 1) * dt
                # ---------------- ego
                if mode == 0:
                    i, w = idx(e_t0, e_dt, n_e, t_new)
                    s_new = etab[0, i] + w * etab[2, i]
                    v_new = etab[1, i] + w * etab[3, i]
                    a_act_n = (v_new - v) / dt
                    a_rep_n = a_act_n
                    den = P[P_AMAX, b] if a_act_n >= 0.0 else P[P_DMAX, b]
                    u = min(1.0, max(-1.0, a_act_n / den))
                else:
                    err = vd - v
                    braking = False
                    a_brake = 0.0
                    if mode == 2:
                        if hist_len == 1 or delay == 0:
                            px, py, pyaw, pact = rx, ry, ryaw, r_act
                        else:
                            lag_k = k - delay
                            slot = lag_k % hist_len
                            px, py, pyaw = hx[slot], hy[slot], hyaw[slot]
                            pact = hact[slot] > 0.5 and lag_k >= 0
                        ahead = False
                        gap = np.inf
                        if pact and not collided:
                            i, w = idx(p_s0, p_ds, n_p, s)
                            qx = path[0, i] + w * path[5, i]
                            qy = path[1, i] + w * path[6, i]
                            qc = path[3, i] + w * path[8, i]
                            qs = path[4, i] + w * path[9, i]
                            s_q = s + (px - qx) * qc + (py - qy) * qs
                            i, w = idx(p_s0, p_ds, n_p, s_q)
                            fx_ = path[0, i] + w * path[5, i]
                            fy_ = path[1, i] + w * path[6, i]
                            pc = path[3, i] + w * path[8, i]
                            ps = path[4, i] + w * path[9, i]
                            ddx, ddy = px - fx_, py - fy_
                            s_q = s_q + ddx * pc + ddy * ps
                            lat = ddy * pc - ddx * ps
                            d_front = s_q - s - 0.5 * Le
                            if abs(lat) <= P[P_HALFW, b] and d_front + 0.5 * math.hypot(Lr, Wr) > 0.0:
                                cr, sr = math.cos(pyaw), math.sin(pyaw)
                                ext = 0.5 * Lr * abs(cr * pc + sr * ps) + 0.5 * Wr * abs(sr * pc - cr * ps)
                                g = d_front - ext
                                if d_front + ext > 0.0 and g <= P[P_RANGE, b]:
                                    ahead = True
                                    gap = max(g, 0.0)
                        a_min = P[P_AMIN, b]
                        d_buf = P[P_DBUF, b]
                        d_safe = max(v * v / (2.0 * abs(a_min)), P[P_TSAFE, b] * v) + d_buf
                        trigger = ahead and gap < d_safe
                        release = cap == 1 and (not trigger) and ((not ahead) or gap > d_safe + P[P_RELEASE, b])
                        recovered = cap == 2 and abs(v - vd) <= P[P_RECTOL, b]
                        new = cap
                        if trigger:
                            new = 1
                        elif release:
                            new = 2
                        elif recovered:
                            new = 0
                        braking = new == 1
                        if P[P_PAPERLAW, b] > 0.5:
                            room = d_safe - d_buf
                            a = max(-v * v / (2.0 * room), a_min) if room > 0 else 0.0
                        else:
                            gg = gap if ahead else 1e9
                            room = gg - d_buf
                            if room > 0:
                                a = max(-v * v / (2.0 * room), a_min)
                            else:
                                a = a_min if v > 0 else 0.0
                        a_brake = a if braking else 0.0
                        if not collided:
                            cap = new
                        if release:
                            pid_i = 0.0
                            pid_e = err
                    decay = math.exp(-dt / P[P_IWIN, b])
                    pid_i = pid_i * decay + err * dt
                    ki = P[P_KI, b]
                    lim = P[P_ILIM, b] / (ki if ki > 0 else 1.0)
                    pid_i = min(max(pid_i, -lim), lim)
                    deriv = (err - pid_e) / dt
                    u = min(1.0, max(-1.0, P[P_KP, b] * err + ki * pid_i + P[P_KD, b] * deriv))
                    pid_e = err
                    if braking:
                        den = P[P_AMAX, b] if a_brake >= 0.0 else P[P_DMAX, b]
                        u = min(1.0, max(-1.0, a_brake / den))
                    a_cmd = u * (P[P_AMAX, b] if u >= 0.0 else P[P_DMAX, b])
                    tau = P[P_LAG, b]
                    alpha = -math.expm1(-dt / tau) if tau > 0 else 1.0
                    a_act_n = a_act + alpha * (a_cmd - a_act)
                    v_new = max(0.0, v + a_act_n * dt)
                    s_new = s + v_new * dt
                    if v_new <= 0.0 and a_act_n < 0.0:
                        a_rep_n = (v_new - v) / dt
                    else:
                        a_rep_n = a_act_n
                if collided:
                    s_new = s
                    v_new = 0.0
                    a_act_n = 0.0
                    a_rep_n = 0.0
                    u = 0.0
                i, w = idx(p_s0, p_ds, n_p, s_new)
                ex_n = path[0, i] + w * path[5, i]
                ey_n = path[1, i] + w * path[6, i]
                eyaw_n = path[2, i] + w * path[7, i]
                # ---------------- rider
                t_rec = t_new - shift
                in_span = t_rec >= r_t0 - 1e-9 and t_rec <= r_tend + 1e-9
                prev_x, prev_y, prev_yaw, prev_sp, prev_act = rx, ry, ryaw, rsp, r_act
                if not sfm:
                    if in_span:
                        i, w = idx(r_t0, r_dt, n_r, t_rec)
                        nrx = rtab[0, i] + w * rtab[7, i]
                        nry = rtab[1, i] + w * rtab[8, i]
                        nryaw = rtab[2, i] + w * rtab[9, i]
                        nrsp = rtab[3, i] + w * rtab[10, i]
                        nrvx = rtab[4, i] + w * rtab[11, i]
                        nrvy = rtab[5, i] + w * rtab[12, i]
                    else:
                        j0 = 0 if t_rec < r_t0 else n_r - 1
                        nrx, nry, nryaw = rtab[0, j0], rtab[1, j0], rtab[2, j0]
                        nrsp = nrvx = nrvy = 0.0
                    n_act = in_span
                    if r_started and not in_span:
                        r_done = True
                    r_started = r_started or in_span
                    nprog = prog
                else:
                    nrx, nry, nryaw, nrvx, nrvy, nrsp, nprog, n_act = rx, ry, ryaw, rvx, rvy, rsp, prog, r_act
                    if r_act and not collided:
                        i, w = idx(rp_s0, rp_ds, n_rp, prog)
                        qx = rpath[0, i] + w * rpath[5, i]
                        qy = rpath[1, i] + w * rpath[6, i]
                        qc = rpath[3, i] + w * rpath[8, i]
                        qs = rpath[4, i] + w * rpath[9, i]
                        pr = max(prog + (rx - qx) * qc + (ry - qy) * qs, prog)
                        i, w = idx(rp_s0, rp_ds, n_rp, min(pr + P[P_LOOK, b], rp_len))
                        gx = rpath[0, i] + w * rpath[5, i]
                        gy = rpath[1, i] + w * rpath[6, i]
                        dx, dy = gx - rx, gy - ry
                        q = dx * dx + dy * dy + P[P_SIGMA, b] ** 2
                        den = q if P[P_PAPERV, b] > 0.5 else math.sqrt(q)
                        f = P[P_V0, b] / den
                        kd_ = P[P_KDES, b]
                        fx = kd_ * (f * dx - rvx)
                        fy = kd_ * (f * dy - rvy)
                        if P[P_USEVF, b] > 0.5:
                            c, sn = math.cos(eyaw), math.sin(eyaw)
                            hl, hw = 0.5 * Le, 0.5 * We
                            if P[P_FRONTB, b] > 0.5:
                                qx2 = ex + hl * c
                                qy2 = ey + hl * sn
                            else:
                                ddx, ddy = rx - ex, ry - ey
                                lx = min(max(ddx * c + ddy * sn, -hl), hl)
                                ly = min(max(-ddx * sn + ddy * c, -hw), hw)
                                qx2 = ex + lx * c - ly * sn
                                qy2 = ey + lx * sn + ly * c
                            dx2, dy2 = rx - qx2, ry - qy2
                            d = math.sqrt(dx2 * dx2 + dy2 * dy2)
                            mag = P[P_AVEH, b] * math.exp(-P[P_BVEH, b] * d)
                            if d < 1e-9:
                                e2x, e2y = rx - ex, ry - ey
                                de = math.sqrt(e2x * e2x + e2y * e2y)
                                if de > 1e-9:
                                    nx_, ny_ = e2x / de, e2y / de
                                else:
                                    nx_, ny_ = c, sn
                            else:
                                nx_, ny_ = dx2 / d, dy2 / d
                            fx = fx + mag * nx_
                            fy = fy + mag * ny_
                        m = P[P_MASS, b]
                        limits = math.isfinite(P[P_VMAX, b]) or math.isfinite(P[P_AMAX_R, b])
                        if limits:
                            fmag = math.sqrt(fx * fx + fy * fy)
                            fmax = P[P_AMAX_R, b] * m
                            if fmag > fmax:
                                sc = fmax / fmag if fmag > 0 else 1.0
                                fx, fy = fx * sc, fy * sc
                        inv_m = 1.0 / m
                        vx2 = rvx + fx * inv_m * dt
                        vy2 = rvy + fy * inv_m * dt
                        x2 = rx + vx2 * dt
                        y2 = ry + vy2 * dt
                        sp2 = math.sqrt(vx2 * vx2 + vy2 * vy2)
                        if limits:
                            vmax = P[P_VMAX, b]
                            if sp2 > vmax:
                                sc = vmax / sp2 if sp2 > 0 else 1.0
                                vx2, vy2, sp2 = vx2 * sc, vy2 * sc, sp2 * sc
                                x2, y2 = rx + vx2 * dt, ry + vy2 * dt
                        yaw2 = math.atan2(vy2, vx2) if sp2 > 0.05 else ryaw
                        arrived = (x2 - rp_ex) ** 2 + (y2 - rp_ey) ** 2 <= P[P_ARRIVE, b] ** 2
                        leaving = arrived and t_rec > r_tend + 1e-9
                        nrx, nry, nryaw = x2, y2, yaw2
                        if leaving:
                            nrvx = nrvy = nrsp = 0.0
                        else:
                            nrvx, nrvy, nrsp = vx2, vy2, sp2
                        nprog = pr
                        n_act = not leaving
                        if r_act and not n_act:
                            r_done = True
                    if not r_started and in_span:
                        i, w = idx(r_t0, r_dt, n_r, t_rec)
                        nrx = rtab[0, i] + w * rtab[7, i]
                        nry = rtab[1, i] + w * rtab[8, i]
                        nryaw = rtab[2, i] + w * rtab[9, i]
                        nrsp = rtab[3, i] + w * rtab[10, i]
                        nrvx = rtab[4, i] + w * rtab[11, i]
                        nrvy = rtab[5, i] + w * rtab[12, i]
                        nprog = rtab[6, i] + w * rtab[13, i]
                        n_act = True
                        r_started = True
                if collided:
                    nrx, nry, nryaw = prev_x, prev_y, prev_yaw
                    nrvx = nrvy = nrsp = 0.0
                    n_act = prev_act
                r_acc = (nrsp - prev_sp) / dt if (n_act and prev_act) else 0.0
                if collided:
                    r_acc = 0.0
                # ---------------- collision
                if n_act and not collided:
                    ddx, ddy = nrx - ex_n, nry - ey_n
                    if ddx * ddx + ddy * ddy <= reach * reach:
                        if sat(ex_n, ey_n, eyaw_n, Le, We, nrx, nry, nryaw, Lr, Wr):
                            collided = True
                            ct = t_new
                            v_new = 0.0
                            a_act_n = 0.0
                            a_rep_n = 0.0
                            nrvx = nrvy = nrsp = 0.0
                            r_acc = 0.0
                for j in range(no):
                    if oACT[k + 1, j] and not hit[j]:
                        ddx, ddy = oX[k + 1, j] - ex_n, oY[k + 1, j] - ey_n
                        rr = 0.5 * (math.hypot(Le, We) + math.hypot(oL[j], oW[j]))
                        if ddx * ddx + ddy * ddy <= rr * rr:
                            if sat(ex_n, ey_n, eyaw_n, Le, We, oX[k + 1, j], oY[k + 1, j], oYAW[k + 1, j], oL[j], oW[j]):
                                hit[j] = True
                # ---------------- commit
                s, ex, ey, eyaw, v, a_act, a_rep = s_new, ex_n, ey_n, eyaw_n, v_new, a_act_n, a_rep_n
                rx, ry, ryaw, rvx, rvy, rsp, prog, r_act = nrx, nry, nryaw, nrvx, nrvy, nrsp, nprog, n_act
                if hist_len > 1:
                    slot = (k + 1) % hist_len
                    hx[slot], hy[slot], hyaw[slot] = rx, ry, ryaw
                    hact[slot] = 1.0 if r_act else 0.0
                if r_act:
                    dd = math.sqrt((rx - ex) * (rx - ex) + (ry - ey) * (ry - ey))
                    if dd < md:
                        md = dd
                if record:
                    kk = k + 1
                    O[O_S, kk, b] = s
                    O[O_X, kk, b] = ex
                    O[O_Y, kk, b] = ey
                    O[O_YAW, kk, b] = eyaw
                    O[O_V, kk, b] = v
                    O[O_A, kk, b] = a_rep
                    O[O_U, kk, b] = u
                    O[O_RX, kk, b] = rx
                    O[O_RY, kk, b] = ry
                    O[O_RYAW, kk, b] = ryaw
                    O[O_RSP, kk, b] = rsp
                    O[O_RVX, kk, b] = rvx
                    O[O_RVY, kk, b] = rvy
                    O[O_RA, kk, b] = r_acc
                    OB[0, kk, b] = cap
                    OB[1, kk, b] = 1 if r_act else 0
                    OB[2, kk, b] = 1 if collided else 0
                    for j in range(no):
                        OH[kk, b, j] = 1 if hit[j] else 0
            FS[0, b] = s
            FS[1, b] = ex
            FS[2, b] = ey
            FS[3, b] = eyaw
            FS[4, b] = v
            FS[5, b] = a_rep
            FS[6, b] = a_act
            FS[7, b] = u
            FS[8, b] = pid_i
            FS[9, b] = pid_e
            FS[10, b] = cap
            FS[11, b] = rx
            FS[12, b] = ry
            FS[13, b] = ryaw
            FS[14, b] = rvx
            FS[15, b] = rvy
            FS[16, b] = rsp
            FS[17, b] = r_acc
            FS[18, b] = prog
            FB[0, b] = 1 if r_act else 0
            FB[1, b] = 1 if r_started else 0
            FB[2, b] = 1 if collided else 0
            FB[3, b] = 1 if r_done else 0
            for h in range(hist_len):
                FH[0, h, b] = hx[h]
                FH[1, h, b] = hy[h]
                FH[2, h, b] = hyaw[h]
                FH[3, h, b] = hact[h]
            coll_t[b] = ct
            min_d[b] = md
            for j in range(no):
                H0[b, j] = 1 if hit[j] else 0

    _KERNEL = kernel
    return kernel


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
    "paper_per_step", "perception_delay_s",
)  # fmt: skip


def _path_rows(path: Any) -> np.ndarray:
    vals = path._values  # type: ignore[attr-defined]
    slopes = path._slopes  # type: ignore[attr-defined]
    names = ("x", "y", "yaw", "cos", "sin")
    return np.ascontiguousarray(np.stack([vals[n] for n in names] + [slopes[n] for n in names]))


def _table_rows(table: Any, names: tuple[str, ...]) -> np.ndarray:
    cols = table._cols  # type: ignore[attr-defined]
    slopes = table._slopes  # type: ignore[attr-defined]
    return np.ascontiguousarray(np.stack([cols[n] for n in names] + [slopes[n] for n in names]))


def run(arrays: Any, params: Any, state0: Any, hist_len: int, record: bool) -> dict[str, Any]:
    """Run the compiled kernel from ``state0`` over all steps of ``arrays``.

    Args:
        arrays: ScenarioArrays. params: VariantParams [B]. state0: SimState at k = 0 (from
        :func:`vei.sim.engine.initial_state`). hist_len: perception ring length H.
        record: keep the time series.
    Returns:
        dict with 'series' (name -> [T, B] arrays of engine._RECORDED, or None), 'hit'
        ([T, B, n_o] or None), 'final' (SimState fields), 'collision_time_s',
        'min_center_distance_m'.
    """
    kernel = _build()
    t_n = arrays.n_steps
    b = params.batch_size
    no = len(arrays.other_ids)
    p_mat = np.ascontiguousarray(
        np.stack([np.asarray(getattr(params, f), dtype=np.float64) for f in PARAM_FIELDS])
    )
    p_mat[P_DELAY] = params.delay_steps(arrays.dt_s)
    s0 = np.ascontiguousarray(np.stack([np.asarray(getattr(state0, f), dtype=np.float64) for f in FLOAT_FIELDS]))
    b0 = np.ascontiguousarray(np.stack([np.asarray(getattr(state0, f)).astype(np.uint8) for f in BOOL_FIELDS]))
    tt = t_n if record else 1
    out = np.empty((N_OUT, tt, b))
    outb = np.zeros((3, tt, b), dtype=np.uint8)
    outh = np.zeros((tt, b, no), dtype=np.uint8)
    h0 = np.ascontiguousarray(state0.hit_other.astype(np.uint8))
    if record:
        first = (
            state0.ego_s_m, state0.ego_x_m, state0.ego_y_m, state0.ego_yaw_rad, state0.ego_v_mps,
            state0.ego_a_mps2, state0.ego_cmd, state0.rider_x_m, state0.rider_y_m, state0.rider_yaw_rad,
            state0.rider_speed_mps, state0.rider_vx_mps, state0.rider_vy_mps, state0.rider_a_mps2,
        )  # fmt: skip
        for j, val in enumerate(first):
            out[j, 0] = val
        outb[0, 0] = state0.cap_state
        outb[1, 0] = state0.rider_active
        outb[2, 0] = state0.collided
        outh[0] = h0
    fs = np.empty((len(FLOAT_FIELDS), b))
    fb = np.empty((len(BOOL_FIELDS), b), dtype=np.uint8)
    fh = np.empty((4, hist_len, b))
    coll_t = np.empty(b)
    min_d = np.empty(b)
    tr, rp, et = arrays.rider_track, arrays.rider_path, arrays.ego_track
    kernel(
        t_n, float(arrays.dt_s), int(hist_len), bool(record),
        _path_rows(arrays.ego_path), float(arrays.ego_path.s_start_m), float(arrays.ego_path.ds_m),
        _table_rows(et, ("s_m", "speed_mps")), float(et.t0_s), float(et.dt_s),
        _table_rows(tr, ("x_m", "y_m", "yaw_rad", "speed_mps", "vx_mps", "vy_mps", "arc_m")),
        float(tr.t0_s), float(tr.dt_s), float(tr.t_end_s),
        _path_rows(rp), float(rp.s_start_m), float(rp.ds_m), float(rp.length_m), float(rp.end_x_m), float(rp.end_y_m),
        float(arrays.ego_length_m), float(arrays.ego_width_m), float(arrays.rider_length_m), float(arrays.rider_width_m),
        np.ascontiguousarray(arrays.other_x_m), np.ascontiguousarray(arrays.other_y_m),
        np.ascontiguousarray(arrays.other_yaw_rad), np.ascontiguousarray(arrays.other_active),
        np.ascontiguousarray(arrays.other_length_m, dtype=np.float64),
        np.ascontiguousarray(arrays.other_width_m, dtype=np.float64),
        p_mat, s0, b0, out, outb, outh, h0, fs, fb, fh, coll_t, min_d,
    )  # fmt: skip
    final = {f: fs[j].copy() for j, f in enumerate(FLOAT_FIELDS)}
    final["cap_state"] = fs[FLOAT_FIELDS.index("cap_state")].astype(np.int8)
    for j, f in enumerate(BOOL_FIELDS):
        final[f] = fb[j].astype(bool)
    final["hit_other"] = h0.astype(bool)
    final["hist"] = fh
    final["k"] = t_n - 1
    series = None
    hit = None
    if record:
        names = (
            "ego_s_m", "ego_x_m", "ego_y_m", "ego_yaw_rad", "ego_speed_mps", "ego_accel_mps2", "ego_command",
            "rider_x_m", "rider_y_m", "rider_yaw_rad", "rider_speed_mps", "rider_vx_mps", "rider_vy_mps",
            "rider_accel_mps2",
        )  # fmt: skip
        series = {n: out[j] for j, n in enumerate(names)}
        series["cap_state"] = outb[0].astype(np.int8)
        series["rider_active"] = outb[1].astype(bool)
        series["collided"] = outb[2].astype(bool)
        hit = outh.astype(bool)
    return {
        "series": series,
        "hit": hit,
        "final": final,
        "collision_time_s": coll_t,
        "min_center_distance_m": min_d,
    }
