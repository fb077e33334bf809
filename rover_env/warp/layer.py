"""The per-substep kernels of the Warp tire layer: speed loop, wheel forces, force application.

They run between ``mujoco_warp.step1`` and ``step2``, where the C plugin's ``compute`` runs
inside ``mj_step`` (after the velocity stage, before actuation), and do what it does in the
same order: integrate the driven wheels' angle setpoints into ``ctrl[pos]``, compute each
wheel's contact and forces (:func:`wheel_forces`, one thread per world and wheel), then, one
thread per world, apply them through ``qfrc_applied`` (the plugin adds to ``qfrc_passive``:
the same sum in another order) and commit the rut writes (the plugin's ``advance``).
"""

from __future__ import annotations

import warp as wp

from rover_env.warp.kernels import (
    C_ALPHA,
    C_S,
    C_Z,
    D_X,
    D_Y,
    D_Z,
    DEG_TO_RAD,
    K_RE,
    LAT_SPLIT,
    LATERAL_FACTOR_MIN,
    RUT_WRITE_EVERY,
    S_DAMP,
    S_KDIG,
    S_MEMORY,
    S_PHI,
    S_SIGMA,
    SIGMA_X,
    SIGMA_Y,
    SOIL_MAX_TAN_BETA,
    SOIL_V_BLEND,
    SOIL_V_EPS,
    V_EPS,
    V_FLOOR,
    X_FLOOR,
    expm1,
    friction_patch,
    gim_magnitude,
    np_sign,
    rut_across,
    rut_footprint,
    rut_write,
    soil_base,
    stress_integrals,
    wheel_contact,
)

# indices into the layer's parameter row after the 14 tire numbers
P_RADIUS, P_WIDTH, P_MAX_ERR, P_COND, P_KI, P_KD, P_TAU, P_STALL, P_W0, P_DT = range(14, 24)
NPAR = 24


@wp.kernel
def speed_loop(
    par: wp.array[float],
    driven_qpos: wp.array[int],
    driven_dof: wp.array[int],
    ctrl_pos: wp.array[int],
    ctrl_vel: wp.array[int],
    qpos: wp.array2d[float],
    qvel: wp.array2d[float],
    targets: wp.array2d[float],
    sp: wp.array2d[float],
    ctrl: wp.array2d[float],
):
    """simulator.advance_setpoints: the speed loop's integrated angle setpoints."""
    w, k = wp.tid()
    dt = par[P_DT]
    err = par[P_MAX_ERR]
    q = qpos[w, driven_qpos[k]]
    u = targets[w, k]
    v = wp.min(wp.max(sp[w, k] + u * dt, q - err), q + err)
    if par[P_COND] != 0.0:
        wv = qvel[w, driven_dof[k]]
        raw = par[P_KI] * (v - q) + par[P_KD] * (u - wv)
        hi = wp.min(par[P_TAU], par[P_STALL] * (1.0 - wv / par[P_W0]))
        lo = wp.max(-par[P_TAU], -par[P_STALL] * (1.0 + wv / par[P_W0]))
        tau = wp.min(wp.max(raw, lo), hi)
        if tau != raw and np_sign(u - wv) == np_sign(raw):  # saturated outward: frozen
            v = wp.min(wp.max(sp[w, k] + wv * dt, q - err), q + err)
    ctrl[w, ctrl_vel[k]] = u
    ctrl[w, ctrl_pos[k]] = v
    sp[w, k] = v


@wp.struct
class Truth:
    """Per-wheel outputs of the last substep (arrays (nworld, nwheel))."""

    v_x: wp.array2d[float]
    v_y: wp.array2d[float]
    v_w: wp.array2d[float]
    F_x: wp.array2d[float]
    F_y: wp.array2d[float]
    F_z: wp.array2d[float]
    delta: wp.array2d[float]
    sinkage: wp.array2d[float]
    torque: wp.array2d[float]
    patch: wp.array2d[int]
    soil: wp.array2d[int]
    point: wp.array2d[wp.vec3]
    normal: wp.array2d[wp.vec3]


@wp.struct
class Rut:
    """The rut map of every world and the wheels' pending writes."""

    index: wp.array2d[wp.int32]
    pool: wp.array2d[float]
    count: wp.array2d[wp.int32]
    pending: wp.array2d[wp.spatial_vector]


@wp.func
def hard_ground(
    par: wp.array[float],
    v_x: float,
    v_y: float,
    v_w: float,
    F_z: float,
    mu_x: float,
    mu_y: float,
    ux: float,
    uy: float,
) -> wp.vec4:
    """tire.transient_step + transient_forces: (u_x, u_y, F_x, F_y) after the substep."""
    dt = par[P_DT]
    sx = par[SIGMA_X]
    sy = par[SIGMA_Y]
    speed = wp.max(wp.max(wp.abs(v_x), wp.abs(v_w)), par[V_FLOOR])
    split = par[LAT_SPLIT] != 0.0  # TireParams.lateral_split
    speed_y = speed
    lat = float(1.0)  # tire.lateral_factor
    if split:
        speed_y = wp.max(wp.abs(v_x), par[V_FLOOR])
        total = v_x + v_w
        direction = np_sign(total)
        if total == 0.0:
            direction = np_sign(v_x)
        den = wp.max(wp.max(wp.abs(v_x), wp.abs(v_w)), par[V_EPS])
        s_r = wp.min(wp.max(direction * (v_x - v_w) / den, -1.0), 1.0)
        if s_r < 0.0:
            lat = 1.0 - wp.abs(s_r)
    x = wp.max(speed * (dt / sx), X_FLOOR)
    y = wp.max(speed_y * (dt / sy), X_FLOOR)
    em_x = expm1(-x)
    em_y = expm1(-y)
    ux_new = ux * (em_x + 1.0) - (v_x - v_w) * (dt * em_x / x)
    uy_new = uy * (em_y + 1.0) - v_y * (dt * em_y / y)
    fz = wp.max(F_z, 0.0)
    three_over_cs = 3.0 / par[C_S]
    three_over_ca = 3.0 / par[C_ALPHA]
    lim_x = sx * wp.min((fz * mu_x) * three_over_cs, 1.0)
    lim_y = (fz * mu_y) * (3.0 * sy / par[C_ALPHA])
    if split:
        lim_y = lim_y / wp.max(lat, LATERAL_FACTOR_MIN)
    ux_new = wp.min(wp.max(ux_new, -lim_x), lim_x)
    uy_new = wp.min(wp.max(uy_new, -lim_y), lim_y)
    ux_dot = (ux_new - ux) / dt
    uy_dot = (uy_new - uy) / dt
    mag_x = gim_magnitude(wp.abs(ux_new) / sx, fz, mu_x, three_over_cs)
    uy_seen = uy_new * lat
    mag_y = gim_magnitude(wp.abs(uy_seen) / sy, fz, mu_y, three_over_ca)
    f_x = -np_sign(ux_new) * mag_x - par[D_X] * ux_dot
    f_y = -np_sign(uy_seen) * mag_y - par[D_Y] * (uy_dot * lat)
    bx = mu_x * fz
    by = mu_y * fz
    return wp.vec4(ux_new, uy_new, wp.min(wp.max(f_x, -bx), bx), wp.min(wp.max(f_y, -by), by))


@wp.func
def soil_forces(
    ter: wp.array2d[float],
    w: int,
    sb: int,
    s_fwd: float,
    tan_b: float,
    h: float,
    h_c: float,
    r: float,
    width: float,
    v_x: float,
    v_w: float,
) -> wp.vec4:
    """The soil's (F_x, F_y, F_z, T): forward and reverse stresses blended by the leading
    speed's smoothstep (soil.V_BLEND)."""
    lead = v_x
    if wp.abs(v_w) >= wp.abs(v_x):
        lead = v_w
    z = wp.min(wp.max(lead / SOIL_V_BLEND, -1.0), 1.0)
    wt = 0.5 + z * (0.75 - 0.25 * z * z)
    tan_phi = wp.tan(ter[w, sb + S_PHI] * DEG_TO_RAD)
    f = wp.vec4(0.0)
    g = wp.vec4(0.0)
    if wt != 0.0:
        f = stress_integrals(ter, w, sb, s_fwd, tan_b, 1.0, h, h_c, r, tan_phi, width)
    if wt != 1.0:
        g = stress_integrals(ter, w, sb, -s_fwd, tan_b, -1.0, h, h_c, r, tan_phi, width)
    return wt * f + (1.0 - wt) * g


@wp.func
def rut_pending(
    ter: wp.array2d[float],
    w: int,
    point: wp.vec3,
    xc: wp.vec3,
    axis: wp.vec3,
    v_x: float,
    sink: float,
    r: float,
    dt: float,
    depth: float,
) -> wp.spatial_vector:
    """TireLayer's rut_writes for one wheel: a strip behind it, across its width."""
    cell = ter[w, 16]
    hw = wp.min(sink, r)
    e = 1.0 - hw / r
    length = wp.max(cell, 2.0 * wp.abs(v_x) * (float(RUT_WRITE_EVERY) * dt))
    back = (r * wp.sqrt(wp.max(0.0, 1.0 - e * e)) + 0.5 * length) + 1.5 * cell
    sgn = float(-1.0)
    if v_x > 0.0:
        sgn = 1.0
    a = rut_across(axis)
    return wp.spatial_vector(
        point[0] - sgn * back * xc[0], point[1] - sgn * back * xc[1], a[0], a[1], depth, length
    )


@wp.func
def soil_slip(
    par: wp.array[float],
    ter: wp.array2d[float],
    w: int,
    sb: int,
    v_x: float,
    v_y: float,
    v_w: float,
    ux: float,
    uy: float,
) -> wp.vec4:
    """soil.soil_step's relaxed slip: (u_x, u_y, slip s, tan beta) after the substep."""
    dt = par[P_DT]
    ssx = par[SIGMA_X]
    ssy = par[SIGMA_Y]
    if ter[w, sb + S_SIGMA] > 0.0:  # the soil's own relaxation length
        ssx = ter[w, sb + S_SIGMA]
        ssy = ter[w, sb + S_SIGMA]
    rho_x = wp.max(wp.max(wp.abs(v_x), wp.abs(v_w)), SOIL_V_EPS) / ssx
    rho_y = wp.max(wp.abs(v_x), SOIL_V_EPS) / ssy
    emx = expm1(-rho_x * dt)
    emy = expm1(-rho_y * dt)
    ux_new = ux * (emx + 1.0) + (v_x - v_w) * (-emx / rho_x)
    uy_new = uy * (emy + 1.0) + v_y * (-emy / rho_y)
    ux_new = wp.min(wp.max(ux_new, -ssx), ssx)
    uy_new = wp.min(wp.max(uy_new, -SOIL_MAX_TAN_BETA * ssy), SOIL_MAX_TAN_BETA * ssy)
    return wp.vec4(ux_new, uy_new, -ux_new / ssx, uy_new / ssy)


@wp.func
def dig_update(
    ter: wp.array2d[float],
    w: int,
    sb: int,
    dig: float,
    delta: float,
    depth: float,
    v_x: float,
    v_w: float,
    r: float,
    dt: float,
) -> float:
    """The depth a spinning wheel has dug (decays as it rolls on)."""
    rate = float(0.0)
    if delta - wp.max(depth, dig) > 0.0:
        rate = ter[w, sb + S_KDIG] * ter[w, sb + S_MEMORY] * wp.max(wp.abs(v_w) - wp.abs(v_x), 0.0)
    return wp.min(dig * wp.exp(-wp.abs(v_x) * dt / r) + rate * dt, r)


@wp.kernel
def wheel_forces(
    par: wp.array[float],
    ter: wp.array2d[float],
    wheel_body: wp.array[int],
    wheel_jnt: wp.array[int],
    wheel_dof: wp.array[int],
    carrier: wp.array[int],
    root: wp.array[int],
    xpos: wp.array2d[wp.vec3],
    xaxis: wp.array2d[wp.vec3],
    cvel: wp.array2d[wp.spatial_vector],
    subtree_com: wp.array2d[wp.vec3],
    qvel: wp.array2d[float],
    nstep: wp.array[int],
    u_x: wp.array2d[float],
    u_y: wp.array2d[float],
    dig_state: wp.array2d[float],
    rut: Rut,
    out: Truth,
    force: wp.array2d[wp.vec3],
    moment: wp.array2d[wp.vec3],
    at: wp.array2d[wp.vec3],
):
    """One wheel of one world: tire_plugin.c's compute loop body."""
    w, i = wp.tid()
    dt = par[P_DT]
    radius = par[P_RADIUS]
    centre = xpos[w, wheel_body[i]]
    axis = xaxis[w, wheel_jnt[i]]
    pn = wheel_contact(ter, w, centre, axis, radius)
    point = wp.vec3(pn[0], pn[1], pn[2])
    nrm = wp.vec3(pn[3], pn[4], pn[5])
    # the deflection (wheel_contact's dl): from the undeflected rim point q along the normal
    u = -(nrm - wp.dot(nrm, axis) * axis)
    q = centre + radius * wp.normalize(u)
    delta = wp.dot(point - q, nrm)
    xc = wp.normalize(wp.cross(axis, nrm))
    yc = wp.cross(nrm, xc)
    cv = cvel[w, carrier[i]]
    ref = subtree_com[w, root[i]]
    ang = wp.spatial_top(cv)
    lin = wp.spatial_bottom(cv)
    v_p = lin + wp.cross(ang, point - ref)
    v_c = lin + wp.cross(ang, centre - ref)
    v_x = wp.dot(v_p, xc)
    v_y = wp.dot(v_p, yc)
    omega = qvel[w, wheel_dof[i]]
    v_w = (radius - par[K_RE] * wp.max(delta, 0.0)) * omega
    delta_dot = -wp.dot(v_c, nrm)
    fzn = wp.max(par[C_Z] * delta + par[D_Z] * delta_dot, 0.0)
    F_z = wp.where(delta > 0.0, fzn, 0.0)
    fp = friction_patch(ter, w, point[0], point[1])
    soil = int(fp[3])
    ux = u_x[w, i]
    uy = u_y[w, i]
    ux_new = float(0.0)
    uy_new = float(0.0)
    F_x = float(0.0)
    F_y = float(0.0)
    if soil == 0:
        hg = hard_ground(par, v_x, v_y, v_w, F_z, fp[0], fp[1], ux, uy)
        ux_new = hg[0]
        uy_new = hg[1]
        F_x = hg[2]
        F_y = hg[3]
    sink = float(0.0)
    torque = float(0.0)
    dig = float(0.0)
    rut.pending[w, i] = wp.spatial_vector()
    if soil > 0:  # loose soil: soil.soil_step and TireLayer's soil branch
        sb = soil_base(ter, w, soil)
        r = radius
        v_w = r * omega
        depth = rut_footprint(ter, rut.index, rut.pool, w, point, axis, par[P_WIDTH])
        sl = soil_slip(par, ter, w, sb, v_x, v_y, v_w, ux, uy)
        ux_new = sl[0]
        uy_new = sl[1]
        s_fwd = sl[2]
        tan_b = sl[3]
        dig = dig_update(ter, w, sb, dig_state[w, i], delta, depth, v_x, v_w, r, dt)
        h = delta - dig
        h_c = delta - wp.max(depth, dig)
        sf = soil_forces(ter, w, sb, s_fwd, tan_b, h, h_c, r, par[P_WIDTH], v_x, v_w)
        F_x = sf[0]
        F_y = sf[1]
        F_z = sf[2]
        torque = sf[3]
        F_z = wp.where(h_c > 0.0, wp.max(F_z + ter[w, sb + S_DAMP] * delta_dot, 0.0), 0.0)
        sink = wp.max(h, 0.0)
        memory = ter[w, sb + S_MEMORY]
        if (
            wp.abs(v_x) > SOIL_V_BLEND
            and delta > 0.0
            and memory > 0.0
            and nstep[w] % RUT_WRITE_EVERY == 0
        ):  # rut_writes: behind a moving wheel, across its width
            rut.pending[w, i] = rut_pending(
                ter, w, point, xc, axis, v_x, sink, r, dt, memory * delta
            )
    force[w, i] = (F_x * xc + F_y * yc) + F_z * nrm
    moment[w, i] = -torque * axis
    at[w, i] = wp.where(soil > 0, centre, point)  # soil: at the hub; tire: at the contact
    dig_state[w, i] = dig
    u_x[w, i] = ux_new
    u_y[w, i] = uy_new
    out.v_x[w, i] = v_x
    out.v_y[w, i] = v_y
    out.v_w[w, i] = v_w
    out.F_x[w, i] = F_x
    out.F_y[w, i] = F_y
    out.F_z[w, i] = F_z
    out.delta[w, i] = delta
    out.point[w, i] = point
    out.normal[w, i] = nrm
    out.patch[w, i] = int(fp[2])
    out.sinkage[w, i] = sink
    out.torque[w, i] = torque
    out.soil[w, i] = soil


@wp.kernel
def apply_wheels(
    par: wp.array[float],
    ter: wp.array2d[float],
    wheel_body: wp.array[int],
    body_rootid: wp.array[int],
    body_dofnum: wp.array[int],
    body_dofadr: wp.array[int],
    body_parentid: wp.array[int],
    dof_parentid: wp.array[int],
    subtree_com: wp.array2d[wp.vec3],
    cdof: wp.array2d[wp.spatial_vector],
    force: wp.array2d[wp.vec3],
    moment: wp.array2d[wp.vec3],
    at: wp.array2d[wp.vec3],
    rut: Rut,
    nstep: wp.array[int],
    qfrc: wp.array2d[float],
):
    """One world: the wheels' wrenches into ``qfrc`` (mj_applyFT over each wheel's ancestor
    chain, wheels in order), then the rut writes in wheel order (the plugin's advance)."""
    w = wp.tid()
    for j in range(qfrc.shape[1]):
        qfrc[w, j] = 0.0
    nw = force.shape[1]
    for i in range(nw):
        body = wheel_body[i]
        offset = at[w, i] - subtree_com[w, body_rootid[body]]
        f = force[w, i]
        t = moment[w, i]
        while body > 0 and body_dofnum[body] == 0:
            body = body_parentid[body]
        if body > 0:
            k = body_dofadr[body] + body_dofnum[body] - 1
            while k >= 0:
                cd = cdof[w, k]
                ang = wp.spatial_top(cd)
                lin = wp.spatial_bottom(cd)
                qfrc[w, k] = qfrc[w, k] + (wp.dot(lin + wp.cross(ang, offset), f) + wp.dot(ang, t))
                k = dof_parentid[k]
    for i in range(nw):
        pw = rut.pending[w, i]
        if pw[4] > 0.0 and rut.index.shape[1] > 0:
            rut_write(
                ter,
                rut.index,
                rut.pool,
                rut.count,
                w,
                pw[0],
                pw[1],
                pw[2],
                pw[3],
                pw[4],
                par[P_WIDTH],
                pw[5],
            )
    nstep[w] = nstep[w] + 1


# small helpers of WarpRoverSim (speed targets, resets)


@wp.kernel
def clip_copy(src: wp.array2d[float], lim: float, dst: wp.array2d[float]):
    w, k = wp.tid()
    dst[w, k] = wp.clamp(src[w, k], -lim, lim)


@wp.kernel
def copy_rows(mask: wp.array[wp.int32], src: wp.array2d[float], dst: wp.array2d[float]):
    w, k = wp.tid()
    if mask[w] != 0:
        dst[w, k] = src[w, k]


@wp.kernel
def zero_rows_f(mask: wp.array[wp.int32], dst: wp.array2d[float]):
    w, k = wp.tid()
    if mask[w] != 0:
        dst[w, k] = 0.0


@wp.kernel
def zero_rows_i(mask: wp.array[wp.int32], dst: wp.array2d[wp.int32]):
    w, k = wp.tid()
    if mask[w] != 0:
        dst[w, k] = wp.int32(0)


@wp.kernel
def zero_time(mask: wp.array[wp.int32], time: wp.array[float], nstep: wp.array[int]):
    w = wp.tid()
    if mask[w] != 0:
        time[w] = 0.0
        nstep[w] = 0
