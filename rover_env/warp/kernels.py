"""The tire layer as Warp kernels over N worlds: Gim tire forces, loose-soil stresses, rut map.

A line-by-line port of the C plugin (``rover_env/sim/fast/tire_plugin.c`` and
``soil_nodes.h``), which follows the numpy reference (``rover_env/tire.py``, ``soil.py``,
``rut.py``, ``sim/tire_layer.py``). What differs, all from running in float32 as MuJoCo Warp
does:

* plain ``sin``/``cos``/``exp``/``log``/``pow`` instead of the C plugin's numpy-twin
  polynomials (those exist to match numpy to the bit in float64);
* sums in loop order instead of numpy's pairwise order;
* ``expm1`` by its Taylor series below 0.1 (float32 ``exp(x) - 1`` loses ~1e-4 there);
* the floor 1e-300 is 1e-30 (1e-300 is 0 in float32);
* the footprint read does not skip a never-written neighbourhood (it reads the zeros).

Layouts: the terrain block is ``rover_env.sim.fast.plugin.terrain_block``'s, one row per
world (so each world may have its own ground). The rut map keeps the plugin's tiles: a tile
index (int32, 0: no tile, k: pool tile k - 1) and a pool of ``RUT_TILE``^2-cell tiles per
world, plus two counters (tiles used, writes refused).
"""

from __future__ import annotations

import warp as wp

# tire parameter indices (TireParams field order)
MU_X, MU_Y, C_S, C_ALPHA, C_Z, D_Z, V_EPS, SIGMA_X, SIGMA_Y, D_X, D_Y, K_RE, V_FLOOR = range(13)
LAT_SPLIT = 13
LATERAL_FACTOR_MIN = 0.2  # rover_env.tire.LATERAL_FACTOR_MIN
# soil parameter indices (SoilParams.numbers() order)
S_C, S_PHI, S_KC, S_KPHI, S_N0, S_N1, S_KX, S_KY, S_A0, S_A1, S_LAM, S_DAMP, S_KDIG = range(13)
S_MEMORY, S_SIGMA = 14, 15

HEADER = wp.constant(19)
WAVE_STRIDE = wp.constant(5)
PATCH_STRIDE = wp.constant(7)
SOIL_STRIDE = wp.constant(16)
RUT_TILE = wp.constant(16)
RUT_WRITE_EVERY = wp.constant(4)
X_FLOOR = wp.constant(1e-30)
SOIL_V_EPS = wp.constant(1e-3)
SOIL_V_BLEND = wp.constant(0.03)
SOIL_MAX_TAN_BETA = wp.constant(20.0)
DEG_TO_RAD = wp.constant(0.017453292519943295)

# Gauss-Legendre nodes and weights (numpy.polynomial.legendre.leggauss(8)), node k = 0..7
GL_X = wp.constant(
    wp.types.vector(length=8, dtype=float)(
        -0.9602898564975362,
        -0.7966664774136267,
        -0.525532409916329,
        -0.18343464249564978,
        0.18343464249564978,
        0.525532409916329,
        0.7966664774136267,
        0.9602898564975362,
    )
)
GL_W = wp.constant(
    wp.types.vector(length=8, dtype=float)(
        0.10122853629037706,
        0.22238103445337443,
        0.3137066458778869,
        0.36268378337836166,
        0.36268378337836166,
        0.3137066458778869,
        0.22238103445337443,
        0.10122853629037706,
    )
)


@wp.func
def np_sign(a: float) -> float:
    if a > 0.0:
        return 1.0
    if a < 0.0:
        return -1.0
    return 0.0


@wp.func
def expm1(x: float) -> float:
    """e^x - 1 to float32 precision near 0 as well."""
    if wp.abs(x) < 0.1:
        return x * (
            1.0
            + x * (0.5 + x * (1.0 / 6.0 + x * (1.0 / 24.0 + x * (1.0 / 120.0 + x * (1.0 / 720.0)))))
        )
    return wp.exp(x) - 1.0


# ------------------------------------------------------------------ terrain


@wp.func
def height_grad(ter: wp.array2d[float], w: int, x: float, y: float) -> wp.vec3:
    """Terrain.height_and_gradient: (h, dh/dx, dh/dy) at (x, y)."""
    gx = ter[w, 3]
    gy = ter[w, 4]
    h = gx * x + gy * y
    hx = gx
    hy = gy
    for c in range(int(ter[w, 7])):
        b = HEADER + WAVE_STRIDE * c
        amp = ter[w, b]
        k0 = ter[w, b + 1]
        k1 = ter[w, b + 2]
        s = x * k0 + y * k1
        if s >= ter[w, b + 4]:
            arg = s + ter[w, b + 3]
            h += amp * wp.sin(arg)
            cc = amp * wp.cos(arg)
            hx += cc * k0
            hy += cc * k1
    return wp.vec3(h, hx, hy)


@wp.func
def ground_normal(hx: float, hy: float) -> wp.vec3:
    return wp.normalize(wp.vec3(-hx, -hy, 1.0))


@wp.func
def wheel_contact(
    ter: wp.array2d[float], w: int, centre: wp.vec3, axis: wp.vec3, radius: float
) -> wp.spatial_vector:
    """Terrain.wheel_contact: (contact point, normal) packed; the deflection is returned by
    ``contact_delta`` from the same numbers (Warp functions return one value)."""
    flat = ter[w, 1] != 0.0
    n = wp.vec3(0.0, 0.0, 1.0)
    hg = wp.vec3(0.0, 0.0, 0.0)
    iterations = 1
    if not flat:
        hg = height_grad(ter, w, centre[0], centre[1])
        n = ground_normal(hg[1], hg[2])
        iterations = wp.max(int(ter[w, 2]), 1)
    q = wp.vec3(0.0)
    for it in range(iterations):
        u = -(n - wp.dot(n, axis) * axis)
        u = u / wp.length(u)
        q = centre + radius * u
        if not flat:
            hg = height_grad(ter, w, q[0], q[1])
            if it < iterations - 1:
                n = ground_normal(hg[1], hg[2])
    dl = (hg[0] - q[2]) * n[2]
    p = q + dl * n
    return wp.spatial_vector(p[0], p[1], p[2], n[0], n[1], n[2])


@wp.func
def friction_patch(ter: wp.array2d[float], w: int, x: float, y: float) -> wp.vec4:
    """Terrain.friction and soil_index: (mu_x, mu_y, patch, soil)."""
    mux = ter[w, 5]
    muy = ter[w, 6]
    patch = float(0.0)
    soil = ter[w, 11]
    b0 = HEADER + WAVE_STRIDE * int(ter[w, 9])
    for i in range(int(ter[w, 8])):
        b = b0 + PATCH_STRIDE * i
        if x >= ter[w, b] and x <= ter[w, b + 2] and y >= ter[w, b + 1] and y <= ter[w, b + 3]:
            mux = ter[w, b + 4]
            muy = ter[w, b + 5]
            patch = float(i + 1)
            soil = ter[w, b + 6]
    return wp.vec4(mux, muy, patch, soil)


@wp.func
def soil_base(ter: wp.array2d[float], w: int, soil: int) -> int:
    """Column of soil ``soil`` (1-based) in the terrain row."""
    return (
        HEADER
        + WAVE_STRIDE * int(ter[w, 9])
        + PATCH_STRIDE * int(ter[w, 10])
        + SOIL_STRIDE * (soil - 1)
    )


# ------------------------------------------------------------------ rut map


@wp.func
def rut_cell(
    ter: wp.array2d[float],
    rut_index: wp.array2d[wp.int32],
    rut_pool: wp.array2d[float],
    w: int,
    ix: int,
    iy: int,
) -> float:
    nx = int(ter[w, 17])
    ny = int(ter[w, 18])
    if ix < 0 or ix >= nx or iy < 0 or iy >= ny:
        return 0.0
    ntx = (nx + RUT_TILE - 1) // RUT_TILE
    tile = int(rut_index[w, (iy // RUT_TILE) * ntx + ix // RUT_TILE])
    if tile <= 0:
        return 0.0
    return rut_pool[
        w, (tile - 1) * RUT_TILE * RUT_TILE + (iy % RUT_TILE) * RUT_TILE + ix % RUT_TILE
    ]


@wp.func
def rut_lookup(
    ter: wp.array2d[float],
    rut_index: wp.array2d[wp.int32],
    rut_pool: wp.array2d[float],
    w: int,
    x: float,
    y: float,
) -> float:
    """RutGrid.lookup: bilinear depth at (x, y), 0 outside the map."""
    cell = ter[w, 16]
    gx = (x - ter[w, 14]) / cell - 0.5
    gy = (y - ter[w, 15]) / cell - 0.5
    if not (wp.abs(gx) < 1.0e9 and wp.abs(gy) < 1.0e9):
        return 0.0
    fx0 = wp.floor(gx)
    fy0 = wp.floor(gy)
    fx = gx - fx0
    fy = gy - fy0
    cx = int(fx0)
    cy = int(fy0)
    v0 = rut_cell(ter, rut_index, rut_pool, w, cx, cy)
    v1 = rut_cell(ter, rut_index, rut_pool, w, cx + 1, cy)
    v2 = rut_cell(ter, rut_index, rut_pool, w, cx, cy + 1)
    v3 = rut_cell(ter, rut_index, rut_pool, w, cx + 1, cy + 1)
    return ((1.0 - fx) * (1.0 - fy) * v0 + fx * (1.0 - fy) * v1) + (
        (1.0 - fx) * fy * v2 + fx * fy * v3
    )


@wp.func
def rut_across(axis: wp.vec3) -> wp.vec2:
    """rut.across_unit: the horizontal unit direction of a spin axis."""
    h = wp.sqrt(axis[0] * axis[0] + axis[1] * axis[1])
    if h > 1.0e-9:
        return wp.vec2(axis[0] / h, axis[1] / h)
    return wp.vec2(1.0, 0.0)


@wp.func
def rut_footprint(
    ter: wp.array2d[float],
    rut_index: wp.array2d[wp.int32],
    rut_pool: wp.array2d[float],
    w: int,
    point: wp.vec3,
    axis: wp.vec3,
    width: float,
) -> float:
    """RutGrid.footprint_depth: mean depth across the wheel's width at its contact point."""
    if int(ter[w, 17]) * int(ter[w, 18]) == 0:
        return 0.0
    k = wp.max(int(wp.ceil(2.0 * width / ter[w, 16])), 2)
    a = rut_across(axis)
    total = float(0.0)
    for j in range(k):
        tt = (float(j) + 0.5) * (width / float(k)) - 0.5 * width
        total += rut_lookup(ter, rut_index, rut_pool, w, point[0] + tt * a[0], point[1] + tt * a[1])
    return total / float(k)


@wp.func
def rut_cdf(z: float, w1: float, w2: float) -> float:
    """rut.coverage_cdf."""
    zp = z + 0.5 * (w1 + w2)
    if zp <= 0.0:
        return 0.0
    if zp >= w1 + w2:
        return 1.0
    if zp <= w2:
        return zp * zp / (2.0 * w1 * w2)
    if zp <= w1:
        return (zp - 0.5 * w2) / w1
    tail = w1 + w2 - zp
    return 1.0 - tail * tail / (2.0 * w1 * w2)


@wp.func
def rut_write(
    ter: wp.array2d[float],
    rut_index: wp.array2d[wp.int32],
    rut_pool: wp.array2d[float],
    rut_count: wp.array2d[wp.int32],
    w: int,
    qx: float,
    qy: float,
    ax: float,
    ay: float,
    depth: float,
    width: float,
    length: float,
):
    """RutGrid.write_footprint: a strip ``width`` across (ax, ay), ``length`` along, each
    cell keeping the deepest covered fraction; new tiles come from the world's pool."""
    c = ter[w, 16]
    x0 = ter[w, 14]
    y0 = ter[w, 15]
    nx = int(ter[w, 17])
    ny = int(ter[w, 18])
    ntx = (nx + RUT_TILE - 1) // RUT_TILE
    ux = -ay
    uy = ax
    reach = 0.5 * width + c
    hx = wp.abs(ux) * 0.5 * length + wp.abs(ax) * reach
    hy = wp.abs(uy) * 0.5 * length + wp.abs(ay) * reach
    ix0 = wp.max(int(wp.floor((qx - hx - x0) / c)), 0)
    ix1 = wp.min(int(wp.floor((qx + hx - x0) / c)), nx - 1)
    iy0 = wp.max(int(wp.floor((qy - hy - y0) / c)), 0)
    iy1 = wp.min(int(wp.floor((qy + hy - y0) / c)), ny - 1)
    w1 = c * wp.max(wp.abs(ax), wp.abs(ay))
    w2 = c * wp.min(wp.abs(ax), wp.abs(ay))
    pool_tiles = rut_pool.shape[1] // (RUT_TILE * RUT_TILE)
    for iy in range(iy0, iy1 + 1):
        for ix in range(ix0, ix1 + 1):
            px = (x0 + (float(ix) + 0.5) * c) - qx
            py = (y0 + (float(iy) + 0.5) * c) - qy
            s = px * ux + py * uy
            if wp.abs(s) <= 0.5 * length:
                tt = px * ax + py * ay
                f = rut_cdf(0.5 * width - tt, w1, w2) - rut_cdf(-0.5 * width - tt, w1, w2)
                val = depth * f
                at = (iy // RUT_TILE) * ntx + ix // RUT_TILE
                tile = int(rut_index[w, at])
                cell = (iy % RUT_TILE) * RUT_TILE + ix % RUT_TILE
                old = float(0.0)
                if tile > 0:
                    old = rut_pool[w, (tile - 1) * RUT_TILE * RUT_TILE + cell]
                if val > old:
                    ok = bool(True)
                    if tile <= 0:
                        used = int(rut_count[w, 0])
                        if used >= pool_tiles:
                            rut_count[w, 1] = rut_count[w, 1] + 1
                            ok = False
                        else:
                            rut_count[w, 0] = used + 1
                            rut_index[w, at] = wp.int32(used + 1)
                            for z in range(RUT_TILE * RUT_TILE):
                                rut_pool[w, used * RUT_TILE * RUT_TILE + z] = 0.0
                            tile = used + 1
                    if ok:
                        rut_pool[w, (tile - 1) * RUT_TILE * RUT_TILE + cell] = val


# ------------------------------------------------------------------ soil stresses


@wp.func
def kink_newton(
    x0: float, lo0: float, hi0: float, sg: float, one_s: float, th_c: float, sin_c: float
) -> float:
    x = x0
    lo = lo0
    hi = hi0
    for _it in range(2):  # soil._NEWTON_STEPS
        g = (th_c - x) - one_s * (sin_c - wp.sin(x))
        dg = one_s * wp.cos(x) - 1.0
        if sg * g < 0.0:
            lo = x
        else:
            hi = x
        xn = x - g / dg
        if xn >= lo and xn <= hi:
            x = xn
        else:
            x = 0.5 * (lo + hi)
    return x


@wp.func
def kink_points(
    s: float, one_s: float, th_r: float, th_c: float, sin_c: float, rho0: wp.vec2
) -> wp.vec2:
    """soil._kink_points: (rho_b, rho_a), the sign changes of j_x (th_r for a missing one)."""
    rho_b = rho0[0]
    rho_a = rho0[1]
    ci = 1.0 / one_s
    t_s = wp.acos(ci)
    sin_s = wp.sqrt((1.0 - ci) * (1.0 + ci))
    g_r = (th_c - th_r) - one_s * (sin_c - wp.sin(th_r))
    g_m = (th_c + t_s) - one_s * (sin_c + sin_s)
    deep = th_r < -t_s
    root = g_r < 0.0
    if deep:
        root = g_m < 0.0
    if not root:
        return wp.vec2(rho_b, rho_a)
    g_p = (th_c - t_s) - one_s * (sin_c - sin_s)
    g_0 = th_c - one_s * sin_c
    a = one_s * sin_s
    u_m = wp.sqrt(wp.max(-2.0 * g_m / a, 0.0))
    u_p = wp.sqrt(wp.max(2.0 * g_p / a, 0.0))
    right = g_0 < 0.0
    lo = wp.max(th_r, -t_s)
    hi = float(0.0)
    u_a = u_m
    if right:
        lo = 0.0
        hi = t_s
        u_a = u_p
    x_lin = g_0 / s
    x = x_lin
    if not (wp.abs(x_lin) < u_a):
        if right:
            x = t_s - u_a
        else:
            x = u_a - t_s
    rho_a = kink_newton(wp.min(wp.max(x, lo), hi), lo, hi, 1.0, one_s, th_c, sin_c)
    if deep and g_r > 0.0:
        x = wp.min(wp.max(-t_s - u_m, th_r), -t_s)
        rho_b = kink_newton(x, th_r, -t_s, -1.0, one_s, th_c, sin_c)
    return wp.vec2(rho_b, rho_a)


@wp.func
def arc_sums(
    lo: float,
    hi: float,
    r: float,
    th_r: float,
    th_m: float,
    th_f: float,
    th_c: float,
    cos_f: float,
    sin_c: float,
    slope: float,
    one_s: float,
    n: float,
    ks: float,
    tan_phi: float,
    coh: float,
    k_x: float,
    g: float,
    sgn_y: float,
) -> wp.vec4:
    """One arc's Gauss-Legendre sums (x, y, z stresses and the shear for the torque)."""
    mid = 0.5 * (hi + lo)
    half = 0.5 * (hi - lo)
    rear = hi <= th_m
    out = wp.vec4(0.0)
    for k in range(8):
        th = mid + half * GL_X[k]
        sin_t = wp.sin(th)
        cos_t = wp.cos(th)
        cos_eq = cos_t
        if rear:  # behind th_m the normal stress is that at th_eq
            cos_eq = wp.cos(th_f - (th - th_r) * slope)
        base = wp.max(r * (cos_eq - cos_f), 0.0)
        ahead = th_c - th
        j_x = r * (ahead - one_s * (sin_c - sin_t))
        sigma = float(0.0)
        if base > 0.0:
            sigma = ks * wp.pow(base, n)
        tau_max = coh + sigma * tan_phi
        tau_x = tau_max * np_sign(j_x) * (1.0 - wp.exp(-wp.abs(j_x) / k_x))
        tau_y = tau_max * sgn_y * (1.0 - wp.exp(-(g * ahead)))
        wk = half * GL_W[k]
        out += wp.vec4(
            wk * (tau_x * cos_t - sigma * sin_t),
            wk * tau_y,
            wk * (tau_x * sin_t + sigma * cos_t),
            wk * tau_x,
        )
    return out


@wp.func
def stress_integrals(
    ter: wp.array2d[float],
    w: int,
    sb: int,
    s: float,
    tb: float,
    d: float,
    h: float,
    hc0: float,
    r: float,
    tan_phi: float,
    b: float,
) -> wp.vec4:
    """soil.stress_integrals for one wheel: (F_x, F_y, F_z, T); ``sb``: the soil's column."""
    hh = wp.min(wp.max(h, 0.0), r)
    hc = wp.min(wp.max(wp.min(hc0, hh), 0.0), r)
    if not (hc > 0.0):
        return wp.vec4(0.0)
    cos_f = 1.0 - hh / r
    th_f = wp.acos(cos_f)
    cos_c = 1.0 - hc / r
    th_c = th_f
    if hc != hh:
        th_c = wp.acos(cos_c)
    th_r = -wp.acos(1.0 - ter[w, sb + S_LAM] * hc / r)
    th_m = wp.min(wp.max((ter[w, sb + S_A0] + ter[w, sb + S_A1] * s) * th_f, th_r), th_c)
    n = ter[w, sb + S_N0] + ter[w, sb + S_N1] * wp.abs(s)
    ks = ter[w, sb + S_KC] / b + ter[w, sb + S_KPHI]
    sin_c = wp.sqrt((1.0 - cos_c) * (1.0 + cos_c))
    one_s = 1.0 - s
    rho = wp.vec2(th_r, th_r)
    if s < 0.0 and one_s * cos_c < 1.0:
        rho = kink_points(s, one_s, th_r, th_c, sin_c, rho)
    b_1 = wp.min(rho[0], th_m)
    b_2 = wp.max(rho[0], wp.min(rho[1], th_m))
    b_3 = wp.max(rho[1], th_m)
    span = float(1.0)
    if th_m > th_r:
        span = th_m - th_r
    slope = (th_f - th_m) / span
    g = wp.abs(r * one_s * tb) / ter[w, sb + S_KY]
    sgn_y = float(0.0)
    if one_s > 0.0:
        sgn_y = np_sign(tb)
    coh = ter[w, sb + S_C]
    k_x = ter[w, sb + S_KX]
    lo = wp.vec4(th_r, b_1, b_2, b_3)
    hi = wp.vec4(b_1, b_2, b_3, th_c)
    sums = wp.vec4(0.0)
    for a in range(4):
        if 0.5 * (hi[a] - lo[a]) != 0.0:
            sums += arc_sums(
                lo[a],
                hi[a],
                r,
                th_r,
                th_m,
                th_f,
                th_c,
                cos_f,
                sin_c,
                slope,
                one_s,
                n,
                ks,
                tan_phi,
                coh,
                k_x,
                g,
                sgn_y,
            )
    rb = r * b
    return wp.vec4(d * rb * sums[0], -rb * sums[1], rb * sums[2], d * r * rb * sums[3])


@wp.func
def gim_magnitude(slip: float, fz: float, mu: float, three_over_k: float) -> float:
    """tire._gim_magnitude (its bound is mu F_z)."""
    mu_fz = mu * fz
    slip_c = mu_fz * three_over_k
    q = wp.min(slip, slip_c) / wp.max(slip_c, X_FLOOR)
    return mu_fz * q * (3.0 + q * (q - 3.0))
