"""numba-compiled loop of the built-in engine (imported only when numba is used).

See :mod:`vei.sim.kernel` for the contract; this module holds the compiled functions at
module level so that numba's on-disk cache (``cache=True``) works across processes.
"""

# ruff: noqa: E501, N803, N806
from __future__ import annotations

import math

import numba
import numpy as np

from vei.sim.kernel import (
    N_OUT,
    O_A,
    O_RA,
    O_RSP,
    O_RVX,
    O_RVY,
    O_RX,
    O_RY,
    O_RYAW,
    O_S,
    O_U,
    O_V,
    O_X,
    O_Y,
    O_YAW,
    P_AMAX,
    P_AMAX_R,
    P_AMIN,
    P_ARR,
    P_ARRIVE,
    P_AVEH,
    P_BRR,
    P_BVEH,
    P_DBUF,
    P_DELAY,
    P_DMAX,
    P_FRONTB,
    P_HALFW,
    P_ILIM,
    P_IWIN,
    P_KD,
    P_KDES,
    P_KI,
    P_KP,
    P_LAG,
    P_LOOK,
    P_MASS,
    P_MODE,
    P_PAPERLAW,
    P_PAPERV,
    P_RANGE,
    P_RECTOL,
    P_RELEASE,
    P_SFM,
    P_SFR,
    P_SHIFT,
    P_SIGMA,
    P_TSAFE,
    P_USERF,
    P_USEVF,
    P_V0,
    P_VD,
    P_VMAX,
)

__all__ = ["N_OUT", "kernel"]

#: Gap [m] beyond which riders / pedestrians do not repel (vei.models.sfm.RIDER_FORCE_CUTOFF_M).
CUTOFF_M = 10.0


@numba.njit(cache=True)
def rforce(px, py, qx, qy, rs, a, bb):  # type: ignore[no-untyped-def]
    """Rider repulsion on p from q (vei.models.sfm.rider_force)."""
    dx = px - qx
    dy = py - qy
    dc = math.sqrt(dx * dx + dy * dy)
    gap = dc - rs
    if dc < 1e-9 or gap > CUTOFF_M:
        return 0.0, 0.0
    inv = a * math.exp(-bb * gap) / dc
    return inv * dx, inv * dy


@numba.njit(cache=True)
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


@numba.njit(cache=True)
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


# parallel=True: variants are independent (per-variant scratch, no reduction across them),
# so the prange loop spreads them over the cores without changing any result.
@numba.njit(cache=True, parallel=True)
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
    OUT,  # out float [B, N_OUT, T] (record) or [B, N_OUT, 1]
    OB,  # out uint8 [B, 3, T]: cap_state, rider_active, collided
    OH,  # out uint8 [B, T, no]: hit_other latch
    H0,  # initial hit_other [B, no] uint8
    FS,  # final float state [19, B]: s x y yaw v a_rep a_act u pid_i pid_e cap rx ry ryaw rvx rvy rsp racc prog
    FB,  # final bool state [4, B]
    FH,  # final hist [4, hist_len, B]
    coll_t, min_d,  # [B]
    R, xtab, xt0, xdt, xtend, xnr,  # extra riders: tracks [R, 14, M], [R] (vei.sim.riders)
    xpath, xps0, xpds, xpn, xplen, xpex, xpey,  # their paths [R, 10, N], [R]
    xL, xW, xrad, xmed, xp99, prad, rep_on,  # footprints, radii, recorded speeds, mode
    ped_idx, ped_rad,  # pedestrian obstacles: indices into the others, radii
    XS0, XB0,  # initial extra state [8, B, R] floats, [4, B, R] uint8 (act, started, done, hit)
    OX, OXB,  # out [B, 5, T, R] (x y yaw speed accel), [B, 2, T, R] uint8 (active, hit)
    XFS, XFB,  # final extra state [8, B, R], [4, B, R]
):  # fmt: skip
    B = P.shape[1]
    n_p = path.shape[1]
    n_e = etab.shape[1]
    n_r = rtab.shape[1]
    n_rp = rpath.shape[1]
    no = oL.shape[0]
    reach = 0.5 * (math.hypot(Le, We) + math.hypot(Lr, Wr))
    n_ped = ped_idx.shape[0]
    for b in numba.prange(B):
        use_rf = rep_on and P[P_USERF, b] > 0.5
        a_rr = P[P_ARR, b]
        b_rr = P[P_BRR, b]
        xs = np.empty((8, R))
        xb = np.empty((4, R), dtype=np.bool_)
        nxs = np.empty((8, R))
        nxb = np.empty((4, R), dtype=np.bool_)
        xv0 = np.empty(R)
        xvmax = np.empty(R)
        for j in range(R):
            for f in range(8):
                xs[f, j] = XS0[f, b, j]
            for f in range(4):
                xb[f, j] = XB0[f, b, j] > 0
            med = xmed[j]
            if P[P_SFR, b] > 0.5 and math.isfinite(med):
                lk = P[P_LOOK, b]
                xv0[j] = med * math.hypot(lk, P[P_SIGMA, b]) / lk
                xvmax[j] = max(xp99[j], med)
            else:
                xv0[j] = P[P_V0, b]
                xvmax[j] = P[P_VMAX, b]
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
                            ext = 0.5 * Lr * abs(cr * pc + sr * ps) + 0.5 * Wr * abs(
                                sr * pc - cr * ps
                            )
                            g = d_front - ext
                            if d_front + ext > 0.0 and g <= P[P_RANGE, b]:
                                ahead = True
                                gap = max(g, 0.0)
                    a_min = P[P_AMIN, b]
                    d_buf = P[P_DBUF, b]
                    d_safe = max(v * v / (2.0 * abs(a_min)), P[P_TSAFE, b] * v) + d_buf
                    trigger = ahead and gap < d_safe
                    release = (
                        cap == 1
                        and (not trigger)
                        and ((not ahead) or gap > d_safe + P[P_RELEASE, b])
                    )
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
                nrx, nry, nryaw, nrvx, nrvy, nrsp, nprog, n_act = (
                    rx,
                    ry,
                    ryaw,
                    rvx,
                    rvy,
                    rsp,
                    prog,
                    r_act,
                )
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
                    if use_rf:
                        sx = 0.0
                        sy = 0.0
                        for mm in range(R):
                            if xb[0, mm]:
                                hx_, hy_ = rforce(
                                    rx, ry, xs[0, mm], xs[1, mm], prad + xrad[mm], a_rr, b_rr
                                )
                                sx += hx_
                                sy += hy_
                        for q in range(n_ped):
                            jj = ped_idx[q]
                            if oACT[k, jj]:
                                hx_, hy_ = rforce(
                                    rx, ry, oX[k, jj], oY[k, jj], prad + ped_rad[q], a_rr, b_rr
                                )
                                sx += hx_
                                sy += hy_
                        fx = fx + sx
                        fy = fy + sy
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
            # ---------------- extra riders (state at step k; ego contact at k + 1)
            if R > 0:
                # (inlined: a call of a separate compiled function with ~40
                # arguments per variant and step cost 4x the one-rider step)
                for j in range(R):
                    for f in range(8):
                        nxs[f, j] = xs[f, j]
                    for f in range(4):
                        nxb[f, j] = xb[f, j]
                    n_j = xnr[j]
                    in_span = t_new >= xt0[j] - 1e-9 and t_new <= xtend[j] + 1e-9
                    if not sfm:
                        if in_span:
                            i, w = idx(xt0[j], xdt[j], n_j, t_new)
                            nxs[0, j] = xtab[j, 0, i] + w * xtab[j, 7, i]
                            nxs[1, j] = xtab[j, 1, i] + w * xtab[j, 8, i]
                            nxs[2, j] = xtab[j, 2, i] + w * xtab[j, 9, i]
                            nxs[5, j] = xtab[j, 3, i] + w * xtab[j, 10, i]
                            nxs[3, j] = xtab[j, 4, i] + w * xtab[j, 11, i]
                            nxs[4, j] = xtab[j, 5, i] + w * xtab[j, 12, i]
                        else:
                            j0 = 0 if t_new < xt0[j] else n_j - 1
                            nxs[0, j] = xtab[j, 0, j0]
                            nxs[1, j] = xtab[j, 1, j0]
                            nxs[2, j] = xtab[j, 2, j0]
                            nxs[3, j] = 0.0
                            nxs[4, j] = 0.0
                            nxs[5, j] = 0.0
                        nxb[0, j] = in_span
                        if xb[1, j] and not in_span:
                            nxb[2, j] = True
                        nxb[1, j] = xb[1, j] or in_span
                    else:
                        if xb[0, j]:
                            x0, y0, vx0, vy0, prog0 = (
                                xs[0, j],
                                xs[1, j],
                                xs[3, j],
                                xs[4, j],
                                xs[7, j],
                            )
                            xn_p = xpn[j]
                            i, w = idx(xps0[j], xpds[j], xn_p, prog0)
                            qx = xpath[j, 0, i] + w * xpath[j, 5, i]
                            qy = xpath[j, 1, i] + w * xpath[j, 6, i]
                            qc = xpath[j, 3, i] + w * xpath[j, 8, i]
                            qs = xpath[j, 4, i] + w * xpath[j, 9, i]
                            pr = max(prog0 + (x0 - qx) * qc + (y0 - qy) * qs, prog0)
                            i, w = idx(xps0[j], xpds[j], xn_p, min(pr + P[P_LOOK, b], xplen[j]))
                            gx = xpath[j, 0, i] + w * xpath[j, 5, i]
                            gy = xpath[j, 1, i] + w * xpath[j, 6, i]
                            dx, dy = gx - x0, gy - y0
                            q = dx * dx + dy * dy + P[P_SIGMA, b] ** 2
                            den = q if P[P_PAPERV, b] > 0.5 else math.sqrt(q)
                            f = xv0[j] / den
                            kd_ = P[P_KDES, b]
                            fx = kd_ * (f * dx - vx0)
                            fy = kd_ * (f * dy - vy0)
                            if P[P_USEVF, b] > 0.5:
                                c, sn = math.cos(eyaw), math.sin(eyaw)
                                hl, hw = 0.5 * Le, 0.5 * We
                                if P[P_FRONTB, b] > 0.5:
                                    bx = ex + hl * c
                                    by = ey + hl * sn
                                else:
                                    ddx, ddy = x0 - ex, y0 - ey
                                    lx = min(max(ddx * c + ddy * sn, -hl), hl)
                                    ly = min(max(-ddx * sn + ddy * c, -hw), hw)
                                    bx = ex + lx * c - ly * sn
                                    by = ey + lx * sn + ly * c
                                dx2, dy2 = x0 - bx, y0 - by
                                d = math.sqrt(dx2 * dx2 + dy2 * dy2)
                                mag = P[P_AVEH, b] * math.exp(-P[P_BVEH, b] * d)
                                if d < 1e-9:
                                    e2x, e2y = x0 - ex, y0 - ey
                                    de = math.sqrt(e2x * e2x + e2y * e2y)
                                    if de > 1e-9:
                                        nx_, ny_ = e2x / de, e2y / de
                                    else:
                                        nx_, ny_ = c, sn
                                else:
                                    nx_, ny_ = dx2 / d, dy2 / d
                                fx = fx + mag * nx_
                                fy = fy + mag * ny_
                            if use_rf:
                                sx = 0.0
                                sy = 0.0
                                if r_act:
                                    hx_, hy_ = rforce(x0, y0, rx, ry, xrad[j] + prad, a_rr, b_rr)
                                    sx += hx_
                                    sy += hy_
                                for mm in range(R):
                                    if mm != j and xb[0, mm]:
                                        hx_, hy_ = rforce(
                                            x0,
                                            y0,
                                            xs[0, mm],
                                            xs[1, mm],
                                            xrad[j] + xrad[mm],
                                            a_rr,
                                            b_rr,
                                        )
                                        sx += hx_
                                        sy += hy_
                                for qq in range(ped_idx.shape[0]):
                                    jj = ped_idx[qq]
                                    if oACT[k, jj]:
                                        hx_, hy_ = rforce(
                                            x0,
                                            y0,
                                            oX[k, jj],
                                            oY[k, jj],
                                            xrad[j] + ped_rad[qq],
                                            a_rr,
                                            b_rr,
                                        )
                                        sx += hx_
                                        sy += hy_
                                fx = fx + sx
                                fy = fy + sy
                            m = P[P_MASS, b]
                            fmag = math.sqrt(fx * fx + fy * fy)
                            fmax = P[P_AMAX_R, b] * m
                            if fmag > fmax:
                                sc = fmax / fmag if fmag > 0 else 1.0
                                fx, fy = fx * sc, fy * sc
                            inv_m = 1.0 / m
                            vx2 = vx0 + fx * inv_m * dt
                            vy2 = vy0 + fy * inv_m * dt
                            x2 = x0 + vx2 * dt
                            y2 = y0 + vy2 * dt
                            sp2 = math.sqrt(vx2 * vx2 + vy2 * vy2)
                            vmax = xvmax[j]
                            if sp2 > vmax:
                                sc = vmax / sp2 if sp2 > 0 else 1.0
                                vx2, vy2, sp2 = vx2 * sc, vy2 * sc, sp2 * sc
                                x2, y2 = x0 + vx2 * dt, y0 + vy2 * dt
                            yaw2 = math.atan2(vy2, vx2) if sp2 > 0.05 else xs[2, j]
                            arrived = (x2 - xpex[j]) ** 2 + (y2 - xpey[j]) ** 2 <= P[
                                P_ARRIVE, b
                            ] ** 2
                            leaving = arrived and t_new > xtend[j] + 1e-9
                            nxs[0, j] = x2
                            nxs[1, j] = y2
                            nxs[2, j] = yaw2
                            if leaving:
                                nxs[3, j] = 0.0
                                nxs[4, j] = 0.0
                                nxs[5, j] = 0.0
                                nxb[2, j] = True
                            else:
                                nxs[3, j] = vx2
                                nxs[4, j] = vy2
                                nxs[5, j] = sp2
                            nxs[7, j] = pr
                            nxb[0, j] = not leaving
                        if in_span and not xb[1, j]:
                            i, w = idx(xt0[j], xdt[j], n_j, t_new)
                            nxs[0, j] = xtab[j, 0, i] + w * xtab[j, 7, i]
                            nxs[1, j] = xtab[j, 1, i] + w * xtab[j, 8, i]
                            nxs[2, j] = xtab[j, 2, i] + w * xtab[j, 9, i]
                            nxs[5, j] = xtab[j, 3, i] + w * xtab[j, 10, i]
                            nxs[3, j] = xtab[j, 4, i] + w * xtab[j, 11, i]
                            nxs[4, j] = xtab[j, 5, i] + w * xtab[j, 12, i]
                            nxs[7, j] = xtab[j, 6, i] + w * xtab[j, 13, i]
                            nxb[0, j] = True
                            nxb[1, j] = True
                    if nxb[0, j] and xb[0, j]:
                        nxs[6, j] = (nxs[5, j] - xs[5, j]) / dt
                    else:
                        nxs[6, j] = 0.0
                    if nxb[0, j] and not xb[3, j]:
                        ddx, ddy = nxs[0, j] - ex_n, nxs[1, j] - ey_n
                        rr = 0.5 * (math.hypot(Le, We) + math.hypot(xL[j], xW[j]))
                        if ddx * ddx + ddy * ddy <= rr * rr:
                            if sat(
                                ex_n,
                                ey_n,
                                eyaw_n,
                                Le,
                                We,
                                nxs[0, j],
                                nxs[1, j],
                                nxs[2, j],
                                xL[j],
                                xW[j],
                            ):
                                nxb[3, j] = True
                for j in range(R):
                    for f in range(8):
                        xs[f, j] = nxs[f, j]
                    for f in range(4):
                        xb[f, j] = nxb[f, j]
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
                        if sat(
                            ex_n,
                            ey_n,
                            eyaw_n,
                            Le,
                            We,
                            oX[k + 1, j],
                            oY[k + 1, j],
                            oYAW[k + 1, j],
                            oL[j],
                            oW[j],
                        ):
                            hit[j] = True
            # ---------------- commit
            s, ex, ey, eyaw, v, a_act, a_rep = s_new, ex_n, ey_n, eyaw_n, v_new, a_act_n, a_rep_n
            rx, ry, ryaw, rvx, rvy, rsp, prog, r_act = (
                nrx,
                nry,
                nryaw,
                nrvx,
                nrvy,
                nrsp,
                nprog,
                n_act,
            )
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
                OUT[b, O_S, kk] = s
                OUT[b, O_X, kk] = ex
                OUT[b, O_Y, kk] = ey
                OUT[b, O_YAW, kk] = eyaw
                OUT[b, O_V, kk] = v
                OUT[b, O_A, kk] = a_rep
                OUT[b, O_U, kk] = u
                OUT[b, O_RX, kk] = rx
                OUT[b, O_RY, kk] = ry
                OUT[b, O_RYAW, kk] = ryaw
                OUT[b, O_RSP, kk] = rsp
                OUT[b, O_RVX, kk] = rvx
                OUT[b, O_RVY, kk] = rvy
                OUT[b, O_RA, kk] = r_acc
                OB[b, 0, kk] = cap
                OB[b, 1, kk] = 1 if r_act else 0
                OB[b, 2, kk] = 1 if collided else 0
                for j in range(no):
                    OH[b, kk, j] = 1 if hit[j] else 0
                for j in range(R):
                    OX[b, 0, kk, j] = xs[0, j]
                    OX[b, 1, kk, j] = xs[1, j]
                    OX[b, 2, kk, j] = xs[2, j]
                    OX[b, 3, kk, j] = xs[5, j]
                    OX[b, 4, kk, j] = xs[6, j]
                    OXB[b, 0, kk, j] = 1 if xb[0, j] else 0
                    OXB[b, 1, kk, j] = 1 if xb[3, j] else 0
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
        for j in range(R):
            for f in range(8):
                XFS[f, b, j] = xs[f, j]
            for f in range(4):
                XFB[f, b, j] = 1 if xb[f, j] else 0
