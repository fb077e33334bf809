// rover_env tire layer as a MuJoCo engine plugin (passive-force capability).
//
// The C twin of rover_env/sim/tire_layer.py + rover_env/tire.py (transient-slip
// Gim-Nikravesh form) + rover_env/soil.py (terramechanics stresses, arcs split at the
// sign changes of j_x) + rover_env/terrain.py (analytic ground): the numpy code is
// the reference, and this file follows it operation by operation (same formulas,
// same order of floating-point operations, numpy's pairwise summation for sums),
// so that results agree to the last bit or few. Compile with -ffp-contract=off:
// a fused multiply-add would change the rounding. The soil arcs' node loop lives in
// soil_nodes.h (vectorised; built for 2 and, on x86-64, 4 lanes: see there).
//
// It also integrates the driven wheels' dcmotor position setpoints (the speed
// loop's I-term) so that no Python runs per physics substep.
//
// Pipeline: compute() runs inside mj_passive (mj_fwdVelocity, i.e. in mj_forward
// before mj_fwdActuation). It is a pure function of (qpos, qvel, ctrl[vel],
// committed plugin state): it writes this substep's setpoints into ctrl[pos], and a
// queued command row, if any, into ctrl[vel] (both read by the actuators later in the
// same mj_forward), adds the tire forces to
// qfrc_passive, and stores everything it computed in a *pending* block of
// plugin_state. advance() (called by mj_advance after integration) commits the
// pending block. Repeated mj_forward calls are therefore idempotent, exactly as
// the numpy layer (which only runs inside RoverSim.step) leaves the state alone.
//
// plugin_state layout for nw wheels and nd driven wheels (offsets in mjtNum):
//   [0, nw)            u_x       committed tire deflections (m)
//   [nw, 2nw)          u_y
//   [2nw, 2nw+nd)      sp        committed position setpoints of the driven wheels (rad)
//   [2nw+nd]           nstep     number of committed substeps (0: no truth yet)
//   next 17 nw         truth     committed outputs of the last substep:
//                                v_x, v_y, v_w, F_x, F_y, F_z, delta (nw each),
//                                point (nw x 3), normal (nw x 3), patch (nw),
//                                sinkage, torque, soil (nw each)
//   next 2 nw + nd     pending   u_x, u_y, sp computed by the last compute()
//   next 17 nw         pending truth, same layout as truth
//   next nw            dig       committed depth each wheel has dug into the soil (m)
//   next nw            pending dig
//   next 6 nw          pending rut writes: the footprint's centre x, y, its across
//                                direction x, y, the depth (0: none) and the strip's
//                                length along the track, per wheel
//   next 2 + SCHED_ROWS nd  command schedule: rows queued, rows used, then the queued
//                                speed targets (a row of nd per substep). While rows used <
//                                rows queued, compute() takes the next row as ctrl[vel] (and
//                                writes it there, for the actuators) and advance() counts it
//                                used: a command effect's per-substep targets (lag, delay) run
//                                in one mj_step call (RoverSim._step_commanded)
//   next rut_state     rut       the rut map (rover_env/rut.py): tiles used, writes refused,
//                                the tile index (capacity rut_state - 2 - pool), the pool of
//                                RUT_POOL_TILES tiles of RUT_TILE^2 cells: compacted depth
//                                below the terrain surface (m), written by advance() from
//                                the pending writes
// rover_env.sim.fast.layout() mirrors this.
//
// Configuration (MJCF <config key=... value=...>, all strings):
//   wheels           body names of the wheels (nw)
//   joints           hinge joint names of the wheels (nw, same order)
//   motors           dcmotor actuator names (nd <= nw) with input="pos vel";
//                    the setpoint clamps to the angle of the joint each one drives
//   radius           nominal wheel radius (m)
//   tire             13 numbers in TireParams field order
//   max_angle_error  anti-windup bound of the setpoint around the wheel angle (rad)
//   anti_windup      optional, "clamp" (the default), "conditional" or "back_calculation":
//                    the speed loop's anti-windup form (MotorSpec.anti_windup,
//                    speed_loop.advance_setpoints); conditional freezes the integral
//                    (setpoint minus wheel angle: the setpoint advances by w dt instead of
//                    the target's) while the dcmotor's raw PI torque is outside what it
//                    delivers and the error drives it further; back_calculation bleeds it
//                    while the raw torque is beyond the voltage line alone
//   speed_loop       6 numbers, needed by both: integral_gain, speed_gain,
//                    torque_limit, stall_torque, no_load_speed (the physical motor's, as
//                    the <dcmotor> is built: saturation, and the voltage line
//                    stall_torque (1 -+ w / no_load_speed)), tracking_ratio
//   rut_state        size of the rut map's block in plugin_state (0 without soil); the
//                    terrain's tile index must fit in it
//   width            wheel width b (m), for the soil stresses and the rut width
//   effects          optional, 4 numbers (default "0 0 1 1"): the tire-layer model extensions
//                    of rover_env.effects: combined_slip's switch (friction ellipse on the
//                    forces), load_dependent_friction's fall, its static wheel load F_z0 (N)
//                    and the width of its load range 2 range F_z0 (N)
//   terrain          name of the <numeric> element holding the ground (read at every
//                    compute, so it may change at run time and per simulation):
//     [0] layout version (3)  [1] flat (0/1)  [2] contact iterations
//     [3] dh/dx slope  [4] dh/dy slope  [5] default mu_x  [6] default mu_y
//     [7] nwave  [8] npatch  [9] wave capacity W  [10] patch capacity P
//     [11] ground soil (0: hard ground)  [12] nsoil  [13] soil capacity S
//     [14] rut x0  [15] rut y0  [16] rut cell  [17] rut nx  [18] rut ny
//     then W x (amplitude, k_x, k_y, phase, start),
//     then P x (lo_x, lo_y, hi_x, hi_y, mu_x, mu_y, soil),
//     then S x the 16 numbers of rover_env.soil.SoilParams.numbers()

#define _GNU_SOURCE  // sincos
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <mujoco/mujoco.h>

#define PLUGIN_NAME "rover_env.tire"
#define NTIRE 14
#define LATERAL_FACTOR_MIN 0.2  // rover_env.tire.LATERAL_FACTOR_MIN
#define TERRAIN_VERSION 3
#define TERRAIN_HEADER 19
#define WAVE_STRIDE 5
#define PATCH_STRIDE 7
#define SOIL_STRIDE 16
#define NTRUTH 17
#define SOIL_NODES 8
#define SOIL_NEWTON_STEPS 2  // soil._NEWTON_STEPS
#define DEG_TO_RAD (3.141592653589793 / 180.0)  // math.radians
#define SOIL_V_EPS 1e-3
#define SOIL_V_BLEND 0.03
#define SOIL_MAX_TAN_BETA 20.0
#define X_FLOOR 1e-300
#define MAX_WAVES 4096
#define NAME_LEN 256
#define RUT_TILE 16          // rover_env.rut.RUT_TILE
#define RUT_POOL_TILES 2048  // rover_env.rut.RUT_POOL_TILES
#define RUT_HEAD 2           // tiles used, writes refused
#define RUT_WRITE_EVERY 4    // rover_env.rut.RUT_WRITE_EVERY
#define RUT_MAX_SAMPLES 512  // rover_env.rut.MAX_RUT_SAMPLES (RutGrid.samples refuses more)
#define RUT_POOL_SIZE (RUT_POOL_TILES*RUT_TILE*RUT_TILE)
#define SCHED_ROWS 64         // rover_env.sim.fast.plugin.SCHEDULE_ROWS

// tire parameter indices (TireParams field order)
enum { MU_X, MU_Y, C_S, C_ALPHA, C_Z, D_Z, V_EPS, SIGMA_X, SIGMA_Y, D_X, D_Y, K_RE, V_FLOOR,
       LAT_SPLIT };

// truth block field offsets, in units of nw
enum { T_VX = 0, T_VY = 1, T_VW = 2, T_FX = 3, T_FY = 4, T_FZ = 5, T_DELTA = 6,
       T_POINT = 7, T_NORMAL = 10, T_PATCH = 13, T_SINK = 14, T_TORQUE = 15, T_SOIL = 16 };

// soil parameter indices (rover_env.soil.SoilParams.numbers() order)
enum { S_C, S_PHI, S_KC, S_KPHI, S_N0, S_N1, S_KX, S_KY, S_A0, S_A1, S_LAM, S_DAMP, S_KDIG,
       S_CELL, S_MEMORY, S_SIGMA };

// What the arcs of one wheel share (soil.stress_integrals' per-wheel quantities)
typedef struct {
  double r, th_r, th_m, th_f, th_c, cos_f, sin_c, slope, one_s, n, ks, tan_phi, c, k_x, g, sgn_y;
} ArcShared;

// sums[4] += the four node sums (x, y, z stresses and the shear for the torque) of each
// arc [lo[a], hi[a]] of nonzero width
typedef void (*ArcsFn)(const ArcShared* A, const double lo[4], const double hi[4],
                       double sums[4]);

static const char* kAttributes[] = {
  "wheels", "joints", "motors", "radius", "tire", "max_angle_error", "terrain", "effects",
  "rut_state", "width", "anti_windup", "speed_loop"
};

typedef struct {
  int nw, nd;
  int *body, *jnt, *dof, *carrier, *root;
  int *ctrl_pos, *ctrl_vel, *driven_qpos, *driven_dof;
  double radius, max_err, width;
  int conditional;                        // anti_windup "clamp" 0, "conditional" 1, "back_calculation" 2
  double ki, kd, tau_max, stall, w0;      // speed_loop (conditional, back_calculation)
  double tracking;                        // speed_loop: back-calculation's T_t / T_i
  int rut_state;
  double tire[NTIRE];
  double combined_on, load_fall, load_fz0, load_span;  // model extensions (config 'effects')
  // per-model constants of the hot path, each computed exactly as the numpy code does per call
  double three_over_cs, three_over_calpha, three_sy_over_calpha;
  ArcsFn arcs;  // the soil arcs' vector width for this CPU (choose_arcs)
  double last_phi, last_tan_phi;  // soil_tan_phi's memory
  int terrain;  // numeric id
  int capw;     // wave capacity the scratch is sized for
  // scratch of the MjData this configuration belongs to (one per thread in mujoco.batch)
  double* qfrc;  // nv
  double* buf;   // 3 x wave capacity
} Config;

typedef struct {
  int ux, uy, sp, nstep, truth, pux, puy, psp, ptruth, dig, pdig, pwrite, sched, rut, total;
} Layout;

static Layout layout_of(int nw, int nd, int rut_state) {
  Layout L;
  L.ux = 0;
  L.uy = nw;
  L.sp = 2*nw;
  L.nstep = 2*nw + nd;
  L.truth = L.nstep + 1;
  L.pux = L.truth + NTRUTH*nw;
  L.puy = L.pux + nw;
  L.psp = L.puy + nw;
  L.ptruth = L.psp + nd;
  L.dig = L.ptruth + NTRUTH*nw;
  L.pdig = L.dig + nw;
  L.pwrite = L.pdig + nw;
  L.sched = L.pwrite + 6*nw;
  L.rut = L.sched + 2 + SCHED_ROWS*nd;
  L.total = L.rut + rut_state;
  return L;
}

//---------------------------------------------------------------- numpy-compatible arithmetic

// np.maximum / np.minimum on finite values (NaN propagates as in numpy)
static inline double np_max(double a, double b) { return (a >= b || isnan(a)) ? a : b; }
static inline double np_min(double a, double b) { return (a <= b || isnan(a)) ? a : b; }
// np.sign on finite values
static inline int sign_of(double x) { return (x > 0) - (x < 0); }
static inline double np_sign(double a) {
  return a > 0.0 ? 1.0 : (a < 0.0 ? -1.0 : (a == 0.0 ? 0.0 : a));
}

// tire.slip_ratio: sign(v_x + v_w) (v_x - v_w) / max(|v_x|, |v_w|, v_eps) in [-1, 1]
static double slip_ratio(double vx, double vw, double v_eps) {
  double total = vx + vw;
  double dir = np_sign(total == 0.0 ? vx : total);
  double den = np_max(np_max(fabs(vx), fabs(vw)), v_eps);
  return np_min(np_max(dir*(vx - vw)/den, -1.0), 1.0);
}

// numpy's pairwise summation (add.reduce of a contiguous double array)
static double pairwise_sum(const double* a, int n) {
  if (n < 8) {
    double res = -0.0;
    for (int i = 0; i < n; i++) res += a[i];
    return res;
  } else if (n <= 128) {
    double r[8];
    int i;
    for (int j = 0; j < 8; j++) r[j] = a[j];
    for (i = 8; i < n - (n % 8); i += 8) {
      for (int j = 0; j < 8; j++) r[j] += a[i + j];
    }
    double res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
    for (; i < n; i++) res += a[i];
    return res;
  } else {
    int n2 = n / 2;
    n2 -= n2 % 8;
    return pairwise_sum(a, n2) + pairwise_sum(a + n2, n - n2);
  }
}

// np.sum(a * b) over 3 components: (a0 b0 + a1 b1) + a2 b2
static inline double dot3(const double a[3], const double b[3]) {
  return (a[0]*b[0] + a[1]*b[1]) + a[2]*b[2];
}

// np.cross
static inline void cross3(double r[3], const double a[3], const double b[3]) {
  r[0] = a[1]*b[2] - a[2]*b[1];
  r[1] = a[2]*b[0] - a[0]*b[2];
  r[2] = a[0]*b[1] - a[1]*b[0];
}

// np.linalg.norm of a 3-vector
static inline double norm3(const double a[3]) { return sqrt(dot3(a, a)); }

// mj_applyFT(m, d, f, t, point, body, qfrc) without building the dense Jacobians: the same
// arithmetic as mj_jac (dense) followed by mju_mulMatTVec (which skips zero entries of the
// vector), force part then torque part, but only over the dofs of the body's ancestor chain,
// the only non-zero columns. About three times faster; checked bit-exact against mj_applyFT
// (a zero torque adds nothing, as there).
static void apply_ft(const mjModel* m, const mjData* d, const double f[3], const double t[3],
                     const double point[3], int body, double* qfrc) {
  const double* com = d->subtree_com + 3*m->body_rootid[body];
  const double offset[3] = {point[0] - com[0], point[1] - com[1], point[2] - com[2]};
  while (body && !m->body_dofnum[body]) body = m->body_parentid[body];
  if (!body) return;
  int i = m->body_dofadr[body] + m->body_dofnum[body] - 1;
  while (i >= 0) {
    const double* cdof = d->cdof + 6*i;
    double tmp[3];
    cross3(tmp, cdof, offset);
    double r = 0.0, q = 0.0;
    if (f[0]) r += (cdof[3] + tmp[0])*f[0];
    if (f[1]) r += (cdof[4] + tmp[1])*f[1];
    if (f[2]) r += (cdof[5] + tmp[2])*f[2];
    if (t[0]) q += cdof[0]*t[0];
    if (t[1]) q += cdof[1]*t[1];
    if (t[2]) q += cdof[2]*t[2];
    qfrc[i] += r;
    if (q != 0.0) qfrc[i] += q;
    i = m->dof_parentid[i];
  }
}

//---------------------------------------------------------------- terrain

typedef struct {
  const double* p;   // numeric data
  int flat, iterations, nwave, npatch, capw, capp, ground_soil, nsoil, caps;
  const double* wave;
  const double* patch;
  const double* soil;
  double rut_x0, rut_y0, rut_cell, rut_inv;
  int rut_nx, rut_ny, rut_ntx, rut_nty;
} TerrainView;

// read the terrain block; 0 if it is malformed (then the plugin adds no force)
static int terrain_view(const mjModel* m, int id, TerrainView* t) {
  if (id < 0 || id >= m->nnumeric) return 0;
  int size = m->numeric_size[id];
  const double* p = m->numeric_data + m->numeric_adr[id];
  if (size < TERRAIN_HEADER || p[0] != TERRAIN_VERSION) return 0;
  int capw = (int)p[9], capp = (int)p[10], caps = (int)p[13];
  if (capw < 0 || capp < 0 || caps < 0 || capw > MAX_WAVES
      || size != TERRAIN_HEADER + WAVE_STRIDE*capw + PATCH_STRIDE*capp + SOIL_STRIDE*caps) {
    return 0;
  }
  int nwave = (int)p[7], npatch = (int)p[8], nsoil = (int)p[12], ground_soil = (int)p[11];
  if (nwave < 0 || nwave > capw || npatch < 0 || npatch > capp) return 0;
  if (nsoil < 0 || nsoil > caps || ground_soil < 0 || ground_soil > nsoil) return 0;
  int rut_nx = (int)p[17], rut_ny = (int)p[18];
  if (rut_nx < 0 || rut_ny < 0 || (nsoil > 0 && !(p[16] > 0.0))) return 0;
  t->ground_soil = ground_soil;
  t->nsoil = nsoil;
  t->caps = caps;
  t->rut_x0 = p[14];
  t->rut_y0 = p[15];
  t->rut_cell = p[16];
  t->rut_inv = 1.0/p[16];
  t->rut_nx = rut_nx;
  t->rut_ny = rut_ny;
  t->rut_ntx = (rut_nx + RUT_TILE - 1)/RUT_TILE;
  t->rut_nty = (rut_ny + RUT_TILE - 1)/RUT_TILE;
  t->soil = p + TERRAIN_HEADER + WAVE_STRIDE*capw + PATCH_STRIDE*capp;
  t->p = p;
  t->flat = p[1] != 0.0;
  t->iterations = (int)p[2];
  if (t->iterations < 1) t->iterations = 1;
  t->nwave = nwave;
  t->npatch = npatch;
  t->capw = capw;
  t->capp = capp;
  t->wave = p + TERRAIN_HEADER;
  t->patch = p + TERRAIN_HEADER + WAVE_STRIDE*capw;
  return 1;
}

// Terrain.height_and_gradient at one point; buf holds 3 nwave doubles. The contact search
// uses either the height or the gradient of each evaluation, never both, so the unused
// half (sines or cosines) is skipped: the values that are used are the same.
static void height_and_gradient(const TerrainView* t, double x, double y, int need_h,
                                double* h, double* hx, double* hy, double* buf) {
  double gx = t->p[3], gy = t->p[4];
  double hh = gx*x + gy*y, hhx = gx, hhy = gy;
  int K = t->nwave;
  if (K) {
    double *ts = buf, *tcx = buf + K, *tcy = buf + 2*K;
    for (int c = 0; c < K; c++) {
      const double* w = t->wave + WAVE_STRIDE*c;
      double amp = w[0], k0 = w[1], k1 = w[2], phase = w[3], start = w[4];
      double s = x*k0 + y*k1;
      int on = s >= start;
      double arg = s + phase;
      if (need_h) {
        ts[c] = on ? amp*sin(arg) : 0.0;
      } else {
        double cc = on ? amp*cos(arg) : 0.0;
        tcx[c] = cc*k0;
        tcy[c] = cc*k1;
      }
    }
    if (need_h) {
      hh = hh + pairwise_sum(ts, K);
    } else {
      hhx = hhx + pairwise_sum(tcx, K);
      hhy = hhy + pairwise_sum(tcy, K);
    }
  }
  *h = hh;
  *hx = hhx;
  *hy = hhy;
}

// terrain._normal
static void ground_normal(double n[3], double hx, double hy) {
  double v[3] = {-hx, -hy, 1.0};
  double len = norm3(v);
  n[0] = v[0] / len;
  n[1] = v[1] / len;
  n[2] = v[2] / len;
}

// Terrain.wheel_contact for one wheel
static void wheel_contact(const TerrainView* t, const double centre[3], const double axis[3],
                          double radius, double point[3], double n[3], double* delta,
                          double* buf) {
  double h = 0.0, hx, hy, q[3] = {0, 0, 0};
  if (t->flat) {
    n[0] = 0.0;
    n[1] = 0.0;
    n[2] = 1.0;
  } else {
    height_and_gradient(t, centre[0], centre[1], 0, &h, &hx, &hy, buf);
    ground_normal(n, hx, hy);
  }
  int iterations = t->flat ? 1 : t->iterations;
  for (int it = 0; it < iterations; it++) {
    double na = dot3(n, axis);
    double u[3];
    for (int k = 0; k < 3; k++) u[k] = -(n[k] - na*axis[k]);
    double len = norm3(u);
    for (int k = 0; k < 3; k++) u[k] /= len;
    for (int k = 0; k < 3; k++) q[k] = centre[k] + radius*u[k];
    if (t->flat) {
      h = 0.0;
      break;
    }
    int last = it == iterations - 1;
    height_and_gradient(t, q[0], q[1], last, &h, &hx, &hy, buf);
    if (!last) ground_normal(n, hx, hy);
  }
  double dl = (h - q[2])*n[2];
  for (int k = 0; k < 3; k++) point[k] = q[k] + dl*n[k];
  *delta = dl;
}

// Terrain.friction and Terrain.soil_index at one point
static void friction(const TerrainView* t, double x, double y,
                     double* mux, double* muy, int* patch, int* soil) {
  *mux = t->p[5];
  *muy = t->p[6];
  *patch = 0;
  *soil = t->ground_soil;
  for (int i = 0; i < t->npatch; i++) {
    const double* p = t->patch + PATCH_STRIDE*i;
    if (x >= p[0] && x <= p[2] && y >= p[1] && y <= p[3]) {
      *mux = p[4];
      *muy = p[5];
      *patch = i + 1;
      *soil = (int)p[6];
    }
  }
}

// floor(x) for |x| < 2^62 without a libm call (-O2 without SSE4.1 calls floor()): the same value
static inline double rut_floor(double x) {
  double i = (double)(long)x;
  return x < i ? i - 1.0 : i;
}

// the rut map (rover_env/rut.py): index capacity of a rut block of rut_state numbers
static inline int rut_index_capacity(int rut_state) {
  return rut_state > 0 ? rut_state - RUT_HEAD - RUT_POOL_SIZE : 0;
}

// RutGrid.cells: depth stored at cell (ix, iy); 0 outside the map and in tiles never written
// RutGrid._index_at: where the tile index entry of cell (ix, iy) (inside the map) lies
static inline long rut_index_at(const TerrainView* t, long ix, long iy) {
  return RUT_HEAD + (iy/RUT_TILE)*t->rut_ntx + ix/RUT_TILE;
}

// RutGrid._cell_at: where cell (ix, iy) of pool tile `tile` (1-based) lies
static inline long rut_cell_at(int icap, long tile, long ix, long iy) {
  return RUT_HEAD + icap + (tile - 1)*RUT_TILE*RUT_TILE + (iy % RUT_TILE)*RUT_TILE
         + ix % RUT_TILE;
}

static double rut_cell(const TerrainView* t, const double* rut, int icap, long ix, long iy) {
  if (ix < 0 || ix >= t->rut_nx || iy < 0 || iy >= t->rut_ny) return 0.0;
  long tile = (long)rut[rut_index_at(t, ix, iy)];
  return tile > 0 ? rut[rut_cell_at(icap, tile, ix, iy)] : 0.0;
}

// RutGrid.lookup: bilinear rut depth at (x, y), 0 outside the map (which is not empty)
static inline double rut_lookup(const TerrainView* t, const double* rut, int icap, double x,
                                double y) {
  double gx = (x - t->rut_x0)*t->rut_inv - 0.5;
  double gy = (y - t->rut_y0)*t->rut_inv - 0.5;
  if (!(fabs(gx) < 4e18 && fabs(gy) < 4e18)) return 0.0;  // far outside (or NaN): no rut
  double ix = rut_floor(gx), iy = rut_floor(gy);
  double fx = gx - ix, fy = gy - iy;
  const double w[4] = {(1 - fx)*(1 - fy), fx*(1 - fy), (1 - fx)*fy, fx*fy};
  long cx = (long)ix, cy = (long)iy;
  double v[4];
  if (cx >= 0 && cx + 1 < t->rut_nx && cy >= 0 && cy + 1 < t->rut_ny
      && (cx & (RUT_TILE - 1)) != RUT_TILE - 1 && (cy & (RUT_TILE - 1)) != RUT_TILE - 1) {
    // the four cells share one tile (the common case): one index read (cx, cy >= 0 here)
    unsigned long ux = (unsigned long)cx, uy = (unsigned long)cy;
    long tile = (long)rut[RUT_HEAD + (uy/RUT_TILE)*t->rut_ntx + ux/RUT_TILE];
    if (tile <= 0) return 0.0;  // 0 + w 0 + ...: the same +0.0
    const double* p = rut + RUT_HEAD + icap + (tile - 1)*RUT_TILE*RUT_TILE
                      + (uy % RUT_TILE)*RUT_TILE + ux % RUT_TILE;
    v[0] = p[0];
    v[1] = p[1];
    v[2] = p[RUT_TILE];
    v[3] = p[RUT_TILE + 1];
  } else {
    v[0] = rut_cell(t, rut, icap, cx, cy);
    v[1] = rut_cell(t, rut, icap, cx + 1, cy);
    v[2] = rut_cell(t, rut, icap, cx, cy + 1);
    v[3] = rut_cell(t, rut, icap, cx + 1, cy + 1);
  }
  double out = 0.0;
  for (int k = 0; k < 4; k++) out = out + w[k]*v[k];
  return out;
}

// rut.across_unit: the horizontal unit direction of a spin axis (x for a wheel on its side)
static void rut_across(const double* axis, double* ax, double* ay) {
  double h = hypot(axis[0], axis[1]);
  if (h > 1e-9) {
    *ax = axis[0]/h;
    *ay = axis[1]/h;
  } else {
    *ax = 1.0;
    *ay = 0.0;
  }
}

// RutGrid.samples
static int rut_samples(double cell, double width) {
  int k = (int)ceil(2.0*width/cell);
  return k > 2 ? k : 2;
}

// RutGrid.footprint_depth: mean rut depth across a wheel's width at its contact point
static double rut_footprint(const TerrainView* t, const double* rut, int icap,
                            const double* point, const double* axis, double width) {
  if (t->rut_nx*t->rut_ny == 0) return 0.0;
  int k = rut_samples(t->rut_cell, width);
  double ax, ay;
  rut_across(axis, &ax, &ay);
  {  // every tile the reads could touch never written (virgin soil): the mean is +0.0
    double hx = 0.5*width*fabs(ax), hy = 0.5*width*fabs(ay), c = t->rut_cell;
    double lx = (point[0] - hx - t->rut_x0)/c - 1.5, hxc = (point[0] + hx - t->rut_x0)/c + 1.5;
    double ly = (point[1] - hy - t->rut_y0)/c - 1.5, hyc = (point[1] + hy - t->rut_y0)/c + 1.5;
    if (lx > -1e9 && hxc < 1e9 && ly > -1e9 && hyc < 1e9) {
      long cx0 = (long)rut_floor(lx), cx1 = (long)rut_floor(hxc);
      long cy0 = (long)rut_floor(ly), cy1 = (long)rut_floor(hyc);
      if (cx1 < 0 || cx0 >= t->rut_nx || cy1 < 0 || cy0 >= t->rut_ny) return 0.0;  // off the map
      long tx0 = (cx0 < 0 ? 0 : cx0)/RUT_TILE, tx1 = (cx1 >= t->rut_nx ? t->rut_nx - 1 : cx1)/RUT_TILE;
      long ty0 = (cy0 < 0 ? 0 : cy0)/RUT_TILE, ty1 = (cy1 >= t->rut_ny ? t->rut_ny - 1 : cy1)/RUT_TILE;
      int any = 0;
      for (long ty = ty0; ty <= ty1 && !any; ty++) {
        for (long tx = tx0; tx <= tx1; tx++) {
          if (rut[RUT_HEAD + ty*t->rut_ntx + tx] != 0.0) {
            any = 1;
            break;
          }
        }
      }
      if (!any) return 0.0;
    }
  }
  double vals[RUT_MAX_SAMPLES];
  if (k > RUT_MAX_SAMPLES) return 0.0;  // never: inject_plugin checks RutGrid.samples
  for (int j = 0; j < k; j++) {
    double tt = ((double)j + 0.5)*(width/k) - 0.5*width;
    vals[j] = rut_lookup(t, rut, icap, point[0] + tt*ax, point[1] + tt*ay);
  }
  return pairwise_sum(vals, k)/k;
}

// rut.coverage_cdf
static double rut_cdf(double z, double w1, double w2) {
  double zp = z + 0.5*(w1 + w2);
  if (zp <= 0.0) return 0.0;
  if (zp >= w1 + w2) return 1.0;
  if (zp <= w2) return zp*zp/(2.0*w1*w2);
  if (zp <= w1) return (zp - 0.5*w2)/w1;
  double tail = w1 + w2 - zp;
  return 1.0 - tail*tail/(2.0*w1*w2);
}

// RutGrid.write_footprint: a strip `width` across (ax, ay), one cell along, centred at
// (qx, qy), compacted to `depth` (each cell keeps the deepest covered fraction)
static void rut_write(const TerrainView* t, double* rut, int icap, double qx, double qy,
                      double ax, double ay, double depth, double width, double length) {
  double c = t->rut_cell;
  double ux = -ay, uy = ax;
  double reach = 0.5*width + c;
  double hx = fabs(ux)*0.5*length + fabs(ax)*reach;
  double hy = fabs(uy)*0.5*length + fabs(ay)*reach;
  long ix0 = (long)floor((qx - hx - t->rut_x0)/c), ix1 = (long)floor((qx + hx - t->rut_x0)/c);
  long iy0 = (long)floor((qy - hy - t->rut_y0)/c), iy1 = (long)floor((qy + hy - t->rut_y0)/c);
  if (ix0 < 0) ix0 = 0;
  if (iy0 < 0) iy0 = 0;
  if (ix1 > t->rut_nx - 1) ix1 = t->rut_nx - 1;
  if (iy1 > t->rut_ny - 1) iy1 = t->rut_ny - 1;
  double w1 = c*np_max(fabs(ax), fabs(ay));
  double w2 = c*np_min(fabs(ax), fabs(ay));
  const long size = RUT_TILE*RUT_TILE;
  for (long iy = iy0; iy <= iy1; iy++) {
    for (long ix = ix0; ix <= ix1; ix++) {
      double px = (t->rut_x0 + ((double)ix + 0.5)*c) - qx;
      double py = (t->rut_y0 + ((double)iy + 0.5)*c) - qy;
      double s = px*ux + py*uy;
      if (!(fabs(s) <= 0.5*length)) continue;  // beyond the strip's length: nothing to do
      double tt = px*ax + py*ay;
      double f = rut_cdf(0.5*width - tt, w1, w2) - rut_cdf(-0.5*width - tt, w1, w2);
      double val = depth*f;
      // the cell is inside the map here: its index entry and its place in its tile
      long at = rut_index_at(t, ix, iy);
      long tile = (long)rut[at];
      if (!(val > (tile > 0 ? rut[rut_cell_at(icap, tile, ix, iy)] : 0.0))) continue;
      if (tile <= 0) {  // a new tile from the pool
        long used = (long)rut[0];
        if (used >= RUT_POOL_TILES) {
          rut[1] += 1.0;
          continue;
        }
        rut[0] = used + 1;
        rut[at] = used + 1;
        memset(rut + RUT_HEAD + icap + used*size, 0, sizeof(double)*size);
        tile = used + 1;
      }
      rut[rut_cell_at(icap, tile, ix, iy)] = val;
    }
  }
}

//---------------------------------------------------------------- soil (rover_env.soil)

//---------------------------------------------------------------- soil: the arcs' nodes
// The node loop (soil_nodes.h) runs on GCC/Clang vector extensions: only +, -, *, /,
// comparisons and integer bit operations, no libm call, so every lane rounds exactly as the
// numpy code does. Its exponential and logarithm are therefore our own (soil._exp,
// soil._log): Cody-Waite reduction with a Taylor polynomial, and fdlibm's log, bit for bit
// the same as their numpy twins. soil_nodes.h is compiled twice: 2 lanes (SSE2, the x86-64
// baseline; NEON on arm64) and, on x86-64, 4 lanes for CPUs with AVX2 (chosen at run time;
// AVX2 without FMA, so the roundings are the same). The constants are shared.

// soil._EXP_C: 1/k!, k = 0..13
static const double EXP_C[14] = {
  1.0, 1.0, 0.5, 0.16666666666666666, 0.041666666666666664, 0.008333333333333333,
  0.001388888888888889, 0.0001984126984126984, 2.48015873015873e-05, 2.7557319223985893e-06,
  2.755731922398589e-07, 2.505210838544172e-08, 2.08767569878681e-09, 1.6059043836821613e-10};
#define EXP_SHIFT 6755399441055744.0         // 0x1.8p52: x + it rounds x to an integer
#define EXP_SHIFT_BITS 0x4338000000000000ULL
#define INV_LN2 1.4426950408889634
#define LN2_HI 0.6931471803691238            // fdlibm's ln2_hi (k LN2_HI is exact)
#define LN2_LO 1.9082149292705877e-10

// fdlibm's log polynomial (e_log.c, Lg1..Lg7)
#define LG1 6.666666666666735130e-01
#define LG2 3.999999999940941908e-01
#define LG3 2.857142874366239149e-01
#define LG4 2.222219843214978396e-01
#define LG5 1.818357216161805012e-01
#define LG6 1.531383769920937332e-01
#define LG7 1.479819860511658591e-01
#define LOG_OFF 0x3fe6a09e667f3bcdULL  // bits of sqrt(1/2)
#define TOP12 0xfff0000000000000ULL
#define TWO52_BITS 0x4330000000000000ULL

// soil._COS and soil._SIN: Taylor coefficients of cos and sin/x in x^2
static const double SC_COS[12] = {
  1.0, -0.5, 0.041666666666666664, -0.001388888888888889, 2.48015873015873e-05,
  -2.755731922398589e-07, 2.08767569878681e-09, -1.1470745597729725e-11,
  4.779477332387385e-14, -1.5619206968586225e-16, 4.110317623312165e-19,
  -8.896791392450574e-22};
static const double SC_SIN[12] = {
  1.0, -0.16666666666666666, 0.008333333333333333, -0.0001984126984126984,
  2.7557319223985893e-06, -2.505210838544172e-08, 1.6059043836821613e-10,
  -7.647163731819816e-13, 2.8114572543455206e-15, -8.22063524662433e-18,
  1.9572941063391263e-20, -3.868170170630684e-23};

// Gauss-Legendre nodes and weights of the upper half (x_4..x_7; x_{7-k} = -x_k),
// numpy.polynomial.legendre.leggauss(8)
static const double GL_XU[SOIL_NODES/2] = {
  0.18343464249564978, 0.525532409916329, 0.7966664774136267, 0.9602898564975362};
static const double GL_WU[SOIL_NODES/2] = {
  0.36268378337836166, 0.3137066458778869, 0.22238103445337443, 0.10122853629037706};

#define SOIL_VL 2
#define SOIL_SUFFIX _v2
#include "soil_nodes.h"
#undef SOIL_VL
#undef SOIL_SUFFIX

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define SOIL_HAVE_V4 1
#if defined(__clang__)
#pragma clang attribute push(__attribute__((target("avx2"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx2")
#endif
#define SOIL_VL 4
#define SOIL_SUFFIX _v4
#include "soil_nodes.h"
#undef SOIL_VL
#undef SOIL_SUFFIX
#if defined(__clang__)
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif
#endif

// The arcs' implementation for this CPU: 4 lanes where AVX2 runs, unless the environment
// variable ROVER_ENV_SOIL_LANES=2 asks for the baseline (tests run both; same results)
static ArcsFn choose_arcs(void) {
#ifdef SOIL_HAVE_V4
  const char* lanes = getenv("ROVER_ENV_SOIL_LANES");
  __builtin_cpu_init();
  if (!(lanes && strcmp(lanes, "2") == 0) && __builtin_cpu_supports("avx2")) return arcs_v4;
#endif
  return arcs_v2;
}

// soil._kink_points for one wheel with s < 0 and q cos(th_c) < 1 (the caller's cheap test):
// the sign changes rho_b <= rho_a of j_x inside (th_r, th_c), th_r standing for a missing one
static double kink_newton(double x, double lo, double hi, double sg, double one_s, double th_c,
                          double sin_c) {
  for (int it = 0; it < SOIL_NEWTON_STEPS; it++) {
    double sx, cx;
    sincos(x, &sx, &cx);
    double g = (th_c - x) - one_s*(sin_c - sx);
    double dg = one_s*cx - 1.0;
    if (sg*g < 0.0) lo = x; else hi = x;
    double xn = x - g/dg;
    x = (xn >= lo && xn <= hi) ? xn : 0.5*(lo + hi);
  }
  return x;
}

static void kink_points(double s, double one_s, double th_r, double th_c, double sin_c,
                        double* rho_b, double* rho_a) {
  double ci = 1.0/one_s;
  double t_s = acos(ci);
  double sin_s = sqrt((1.0 - ci)*(1.0 + ci));
  double g_r = (th_c - th_r) - one_s*(sin_c - sin(th_r));
  double g_m = (th_c + t_s) - one_s*(sin_c + sin_s);  // g(-theta*)
  int deep = th_r < -t_s;
  if (!(deep ? g_m < 0.0 : g_r < 0.0)) return;  // no root A, hence no root B
  double g_p = (th_c - t_s) - one_s*(sin_c - sin_s);  // g(theta*)
  double g_0 = th_c - one_s*sin_c;  // g(0)
  double a = one_s*sin_s;
  double u_m = sqrt(fmax(-2.0*g_m/a, 0.0));  // fmax == np.fmax (a NaN gives 0)
  double u_p = sqrt(fmax(2.0*g_p/a, 0.0));
  int right = g_0 < 0.0;
  double lo = right ? 0.0 : np_max(th_r, -t_s);
  double hi = right ? t_s : 0.0;
  double u_a = right ? u_p : u_m;
  double x_lin = g_0/s;
  double x = fabs(x_lin) < u_a ? x_lin : (right ? t_s - u_a : u_a - t_s);
  *rho_a = kink_newton(np_min(np_max(x, lo), hi), lo, hi, 1.0, one_s, th_c, sin_c);
  if (deep && g_r > 0.0) {
    x = np_min(np_max(-t_s - u_m, th_r), -t_s);
    *rho_b = kink_newton(x, th_r, -t_s, -1.0, one_s, th_c, sin_c);
  }
}

// soil.stress_integrals for one wheel: out = F_x, F_y, F_z, T. The four arcs lie between
// th_r, the sorted break points (th_m and the sign changes of j_x) and th_c; numpy gives a
// zero-width arc exactly zero terms, here it is skipped (a wheel with s >= 0 has two).
static void stress_integrals(ArcsFn arcs, double s, double tb, double d, double h, double hc,
                             double r, double tan_phi, double b, const double* sp,
                             double out[4]) {
  double hh = np_min(np_max(h, 0.0), r);
  hc = np_min(np_max(np_min(hc, hh), 0.0), r);
  if (!(hc > 0.0)) {
    out[0] = out[1] = out[2] = out[3] = 0.0;
    return;
  }
  double cos_f = 1.0 - hh/r;  // soil.py: cos θ_f and sin θ_c without a round trip through acos
  double th_f = acos(cos_f);
  double cos_c = 1.0 - hc/r;
  double th_c = hc == hh ? th_f : acos(cos_c);  // no rut: the same number, one call
  double th_r = -acos(1.0 - sp[S_LAM]*hc/r);
  double th_m = np_min(np_max((sp[S_A0] + sp[S_A1]*s)*th_f, th_r), th_c);
  double n = sp[S_N0] + sp[S_N1]*fabs(s);
  double ks = sp[S_KC]/b + sp[S_KPHI];
  double sin_c = sqrt((1.0 - cos_c)*(1.0 + cos_c));
  double one_s = 1.0 - s;
  double rho_a = th_r, rho_b = th_r;
  if (s < 0.0 && one_s*cos_c < 1.0) kink_points(s, one_s, th_r, th_c, sin_c, &rho_b, &rho_a);
  double b_1 = np_min(rho_b, th_m);
  double b_2 = np_max(rho_b, np_min(rho_a, th_m));
  double b_3 = np_max(rho_a, th_m);
  const double lo[4] = {th_r, b_1, b_2, b_3};
  const double hi[4] = {b_1, b_2, b_3, th_c};
  double span = th_m > th_r ? th_m - th_r : 1.0;
  double slope = (th_f - th_m)/span;
  double sums[4] = {0.0, 0.0, 0.0, 0.0};
  const ArcShared A = {
    .r = r, .th_r = th_r, .th_m = th_m, .th_f = th_f, .th_c = th_c, .cos_f = cos_f,
    .sin_c = sin_c, .slope = slope, .one_s = one_s, .n = n, .ks = ks, .tan_phi = tan_phi,
    .c = sp[S_C], .k_x = sp[S_KX],
    .g = fabs(r*one_s*tb)/sp[S_KY],  // |j_y|/k_y = g (th_c - th)
    .sgn_y = np_sign(tb)*(one_s > 0.0 ? 1.0 : 0.0)};  // soil._lateral_sign
  arcs(&A, lo, hi, sums);
  double rb = r*b;
  out[0] = d*rb*sums[0];
  out[1] = -rb*sums[1];
  out[2] = rb*sums[2];
  out[3] = d*r*rb*sums[3];
}

// math.tan(math.radians(phi_deg)) of a soil, remembered from the last call (one soil is the
// common case; the same number either way)
static inline double soil_tan_phi(Config* c, double phi_deg) {
  if (phi_deg != c->last_phi) {
    c->last_tan_phi = tan(phi_deg*DEG_TO_RAD);
    c->last_phi = phi_deg;
  }
  return c->last_tan_phi;
}

//---------------------------------------------------------------- tire (rover_env.tire)

// _gim_magnitude: returns |F|, sets the bound mu F_z; three_over_k = 3.0 / stiffness
static inline double gim_magnitude(double slip, double fz, double mu, double three_over_k,
                                   double* bound) {
  double mu_fz = mu*fz;
  double slip_c = mu_fz*three_over_k;
  double q = np_min(slip, slip_c) / np_max(slip_c, X_FLOOR);
  *bound = mu_fz;
  return mu_fz*q*(3.0 + q*(q - 3.0));
}

//---------------------------------------------------------------- config parsing

static int count_tokens(const char* s) {
  int n = 0;
  while (s && *s) {
    while (*s == ' ' || *s == '\t' || *s == '\n' || *s == '\r') s++;
    if (!*s) break;
    n++;
    while (*s && *s != ' ' && *s != '\t' && *s != '\n' && *s != '\r') s++;
  }
  return n;
}

// copy the next whitespace-separated token into buf; returns the rest or NULL
static const char* next_token(const char* s, char* buf, int size) {
  while (*s == ' ' || *s == '\t' || *s == '\n' || *s == '\r') s++;
  if (!*s) return NULL;
  int n = 0;
  while (*s && *s != ' ' && *s != '\t' && *s != '\n' && *s != '\r') {
    if (n < size - 1) buf[n++] = *s;
    s++;
  }
  buf[n] = 0;
  return s;
}

// parse exactly n numbers; 0 on failure
static int parse_numbers(const char* s, double* out, int n) {
  if (!s || count_tokens(s) != n) return 0;
  char buf[NAME_LEN];
  for (int i = 0; i < n; i++) {
    s = next_token(s, buf, NAME_LEN);
    if (!s) return 0;
    char* end;
    out[i] = strtod(buf, &end);
    if (*end || !isfinite(out[i])) return 0;
  }
  return 1;
}

static const char* config(const mjModel* m, int instance, const char* key) {
  const char* s = mj_getPluginConfig(m, instance, key);
  return s ? s : "";
}

static void free_config(Config* c) {
  if (!c) return;
  free(c->body);
  free(c->jnt);
  free(c->dof);
  free(c->carrier);
  free(c->root);
  free(c->ctrl_pos);
  free(c->ctrl_vel);
  free(c->driven_qpos);
  free(c->driven_dof);
  free(c->qfrc);
  free(c->buf);
  free(c);
}

static int fail(Config* c, const char* msg, const char* detail) {
  mju_warning("%s plugin: %s%s", PLUGIN_NAME, msg, detail ? detail : "");
  free_config(c);
  return -1;
}

// parse and check the configuration; 0 on success (*out set), -1 after a warning
static int parse_config(const mjModel* m, int instance, Config** out) {
  *out = NULL;
  Config* c = calloc(1, sizeof(Config));
  if (!c) return fail(NULL, "out of memory", NULL);
  const char* wheels = config(m, instance, "wheels");
  const char* joints = config(m, instance, "joints");
  const char* motors = config(m, instance, "motors");
  c->nw = count_tokens(wheels);
  c->nd = count_tokens(motors);
  int nw = c->nw, nd = c->nd;
  if (nw < 1) return fail(c, "config 'wheels' names no body", NULL);
  if (count_tokens(joints) != nw) {
    return fail(c, "config 'joints' must name one hinge per wheel", NULL);
  }
  if (nd > nw) return fail(c, "config 'motors' names more motors than wheels", NULL);
  c->body = calloc(nw, sizeof(int));
  c->jnt = calloc(nw, sizeof(int));
  c->dof = calloc(nw, sizeof(int));
  c->carrier = calloc(nw, sizeof(int));
  c->root = calloc(nw, sizeof(int));
  c->ctrl_pos = calloc(nd + 1, sizeof(int));
  c->ctrl_vel = calloc(nd + 1, sizeof(int));
  c->driven_qpos = calloc(nd + 1, sizeof(int));
  c->driven_dof = calloc(nd + 1, sizeof(int));
  if (!c->body || !c->jnt || !c->dof || !c->carrier || !c->root || !c->ctrl_pos
      || !c->ctrl_vel || !c->driven_qpos || !c->driven_dof) {
    return fail(c, "out of memory", NULL);
  }
  char name[NAME_LEN];
  const char* s = wheels;
  for (int i = 0; i < nw; i++) {
    s = next_token(s, name, NAME_LEN);
    int b = mj_name2id(m, mjOBJ_BODY, name);
    if (b <= 0) return fail(c, "config 'wheels': no such body: ", name);
    c->body[i] = b;
    c->carrier[i] = m->body_parentid[b];
    c->root[i] = m->body_rootid[c->carrier[i]];
  }
  s = joints;
  for (int i = 0; i < nw; i++) {
    s = next_token(s, name, NAME_LEN);
    int j = mj_name2id(m, mjOBJ_JOINT, name);
    if (j < 0) return fail(c, "config 'joints': no such joint: ", name);
    if (m->jnt_type[j] != mjJNT_HINGE || m->jnt_bodyid[j] != c->body[i]) {
      return fail(c, "config 'joints': not a hinge of its wheel body: ", name);
    }
    c->jnt[i] = j;
    c->dof[i] = m->jnt_dofadr[j];
  }
  s = motors;
  for (int i = 0; i < nd; i++) {
    s = next_token(s, name, NAME_LEN);
    int a = mj_name2id(m, mjOBJ_ACTUATOR, name);
    if (a < 0) return fail(c, "config 'motors': no such actuator: ", name);
    if (m->actuator_ctrlnum[a] != 2 || m->actuator_trntype[a] != mjTRN_JOINT) {
      return fail(c, "config 'motors': need a joint dcmotor with input=\"pos vel\": ", name);
    }
    c->ctrl_pos[i] = m->actuator_ctrladr[a];
    c->ctrl_vel[i] = m->actuator_ctrladr[a] + 1;
    c->driven_qpos[i] = m->jnt_qposadr[m->actuator_trnid[2*a]];
    c->driven_dof[i] = m->jnt_dofadr[m->actuator_trnid[2*a]];
  }
  if (!parse_numbers(config(m, instance, "radius"), &c->radius, 1) || c->radius <= 0) {
    return fail(c, "config 'radius' must be one positive number", NULL);
  }
  if (!parse_numbers(config(m, instance, "max_angle_error"), &c->max_err, 1)
      || c->max_err <= 0) {
    return fail(c, "config 'max_angle_error' must be one positive number", NULL);
  }
  const char* aw = config(m, instance, "anti_windup");
  if (!aw[0] || !strcmp(aw, "clamp")) {
    c->conditional = 0;
  } else if (!strcmp(aw, "conditional") || !strcmp(aw, "back_calculation")) {
    c->conditional = strcmp(aw, "conditional") ? 2 : 1;
    double sl[6];
    if (!parse_numbers(config(m, instance, "speed_loop"), sl, 6) || sl[0] <= 0 || sl[1] <= 0
        || sl[2] <= 0 || sl[3] <= 0 || sl[4] <= 0 || sl[5] <= 0) {
      return fail(c, "config 'speed_loop' must hold 6 positive numbers: integral_gain,"
                  " speed_gain, torque_limit, stall_torque, no_load_speed, tracking_ratio",
                  NULL);
    }
    c->ki = sl[0];
    c->kd = sl[1];
    c->tau_max = sl[2];
    c->stall = sl[3];
    c->w0 = sl[4];
    c->tracking = sl[5];
  } else {
    return fail(c, "config 'anti_windup' must be \"clamp\", \"conditional\" or"
                " \"back_calculation\", got: ", aw);
  }
  if (!parse_numbers(config(m, instance, "tire"), c->tire, NTIRE)) {
    return fail(c, "config 'tire' must hold the 14 TireParams numbers", NULL);
  }
  const char* eff = config(m, instance, "effects");
  double ev[4] = {0.0, 0.0, 1.0, 1.0};
  if (eff[0] && (!parse_numbers(eff, ev, 4) || ev[2] <= 0 || ev[3] <= 0)) {
    return fail(c, "config 'effects' must hold 4 numbers: combined_on, fall, F_z0 > 0, span > 0",
                NULL);
  }
  c->combined_on = ev[0];
  c->load_fall = ev[1];
  c->load_fz0 = ev[2];
  c->load_span = ev[3];
  double rc;
  if (!parse_numbers(config(m, instance, "rut_state"), &rc, 1) || rc < 0 || rc != floor(rc)
      || (rc > 0 && rc < RUT_HEAD + RUT_POOL_SIZE)) {
    return fail(c, "config 'rut_state' must be 0 or an integer >= the rut pool", NULL);
  }
  c->rut_state = (int)rc;
  if (!parse_numbers(config(m, instance, "width"), &c->width, 1) || c->width <= 0) {
    return fail(c, "config 'width' must be one positive number", NULL);
  }
  const char* tname = config(m, instance, "terrain");
  c->terrain = mj_name2id(m, mjOBJ_NUMERIC, tname);
  TerrainView tv;
  if (c->terrain < 0) return fail(c, "config 'terrain': no such numeric: ", tname);
  if (!terrain_view(m, c->terrain, &tv)) {
    return fail(c, "config 'terrain': malformed terrain numeric: ", tname);
  }
  c->qfrc = calloc(m->nv + 1, sizeof(double));
  c->capw = tv.capw;
  c->buf = calloc(3*tv.capw + 1, sizeof(double));
  if (!c->qfrc || !c->buf) return fail(c, "out of memory", NULL);
  c->three_over_cs = 3.0/c->tire[C_S];
  c->three_over_calpha = 3.0/c->tire[C_ALPHA];
  c->three_sy_over_calpha = 3.0*c->tire[SIGMA_Y]/c->tire[C_ALPHA];
  c->arcs = choose_arcs();
  c->last_phi = NAN;  // no tangent remembered yet
  if (m->opt.integrator == mjINT_RK4) {
    return fail(c, "the RK4 integrator is not supported (it evaluates forces at"
                " intermediate stages); use Euler, implicit or implicitfast", NULL);
  }
  if (tv.rut_nx*tv.rut_ny > 0 && tv.rut_ntx*tv.rut_nty > rut_index_capacity(c->rut_state)) {
    return fail(c, "config 'terrain': rut map larger than config 'rut_state'", NULL);
  }
  Layout L = layout_of(nw, nd, c->rut_state);
  if (m->plugin_statenum[instance] != L.total) {
    return fail(c, "plugin state size does not match the configuration", NULL);
  }
  *out = c;
  return 0;
}

//---------------------------------------------------------------- callbacks

static int tire_nstate(const mjModel* m, int instance) {
  int nw = count_tokens(config(m, instance, "wheels"));
  int nd = count_tokens(config(m, instance, "motors"));
  double rc = 0.0;
  if (!parse_numbers(config(m, instance, "rut_state"), &rc, 1) || rc < 0) rc = 0.0;
  return layout_of(nw, nd, (int)rc).total;
}

static int tire_init(const mjModel* m, mjData* d, int instance) {
  Config* c;
  if (parse_config(m, instance, &c)) return -1;
  d->plugin_data[instance] = (uintptr_t)c;
  return 0;
}

static void tire_destroy(mjData* d, int instance) {
  free_config((Config*)d->plugin_data[instance]);
  d->plugin_data[instance] = 0;
}

static void tire_copy(mjData* dest, const mjModel* m, const mjData* src, int instance) {
  // the destination normally keeps the configuration its own init parsed
  if (!dest->plugin_data[instance] || dest->plugin_data[instance] == src->plugin_data[instance]) {
    Config* c;
    dest->plugin_data[instance] = parse_config(m, instance, &c) ? 0 : (uintptr_t)c;
  }
}

static void tire_reset(const mjModel* m, mjtNum* plugin_state, void* plugin_data,
                       int instance) {
  (void)plugin_data;
  memset(plugin_state, 0, sizeof(mjtNum) * m->plugin_statenum[instance]);
}

static void tire_compute(const mjModel* m, mjData* d, int instance, int capability_bit) {
  (void)capability_bit;
  Config* c = (Config*)d->plugin_data[instance];  // this MjData's own (soil_tan_phi writes)
  if (!c) return;
  const int nw = c->nw, nd = c->nd, nv = m->nv;
  const Layout L = layout_of(nw, nd, c->rut_state);
  const int icap = rut_index_capacity(c->rut_state);
  mjtNum* st = d->plugin_state + m->plugin_stateadr[instance];
  const double dt = m->opt.timestep;
  const double* tp = c->tire;

  // a queued command row replaces ctrl[vel] for this substep (the actuators read it too)
  const double queued = st[L.sched], used = st[L.sched + 1];
  if (used < queued && used >= 0 && queued <= SCHED_ROWS) {
    const mjtNum* row = st + L.sched + 2 + nd*(int)used;
    for (int k = 0; k < nd; k++) d->ctrl[c->ctrl_vel[k]] = row[k];
  }

  // speed loop: integrate the angle setpoints with anti-windup (RoverSim.step,
  // simulator.advance_setpoints, operation by operation)
  for (int k = 0; k < nd; k++) {
    double q = d->qpos[c->driven_qpos[k]];
    double u = d->ctrl[c->ctrl_vel[k]];
    double sp = st[L.sp + k] + u*dt;
    double v = np_min(np_max(sp, q - c->max_err), q + c->max_err);
    if (c->conditional) {
      double w = d->qvel[c->driven_dof[k]];
      double raw = c->ki*(v - q) + c->kd*(u - w);
      double line_hi = c->stall*(1.0 - w/c->w0);
      double line_lo = -c->stall*(1.0 + w/c->w0);
      if (c->conditional == 2) {  // back-calculation on the voltage line alone
        double tau = np_min(np_max(raw, line_lo), line_hi);
        if (tau != raw) {
          double t_i = c->kd/c->ki;
          double t_t = c->tracking*t_i;
          double rest = tau/c->ki + (u - w)*(t_t - t_i);
          double a = exp(-dt/t_t);
          double dq = w*dt;
          double bled = q + (rest + (st[L.sp + k] - q + dq - rest)*a);
          v = np_min(np_max(bled, q - c->max_err), q + c->max_err);
        }
      } else {
        double hi = np_min(c->tau_max, line_hi);
        double lo = np_max(-c->tau_max, line_lo);
        double tau = np_min(np_max(raw, lo), hi);
        if (tau != raw && sign_of(u - w) == sign_of(raw)) {  // saturated outward: frozen
          v = np_min(np_max(st[L.sp + k] + w*dt, q - c->max_err), q + c->max_err);
        }
      }
    }
    d->ctrl[c->ctrl_pos[k]] = v;
    st[L.psp + k] = v;
  }

  TerrainView tv;
  if (!terrain_view(m, c->terrain, &tv)) {
    mju_warning("%s plugin: malformed terrain numeric; no tire forces", PLUGIN_NAME);
    return;
  }

  // the terrain's wave capacity may not exceed the one the scratch was sized for
  if (tv.capw > c->capw
      || (tv.rut_nx*tv.rut_ny > 0 && tv.rut_ntx*tv.rut_nty > icap)) {
    mju_warning("%s plugin: terrain numeric resized after compilation; no tire forces",
                PLUGIN_NAME);
    return;
  }
  mjtNum* qfrc = c->qfrc;
  mjtNum* buf = c->buf;
  mju_zero(qfrc, nv);
  mjtNum* out = st + L.ptruth;
  const double sx = tp[SIGMA_X], sy = tp[SIGMA_Y];
  const double dt_sx = dt/sx, dt_sy = dt/sy;

  for (int i = 0; i < nw; i++) {
    const double* centre = d->xpos + 3*c->body[i];
    const double* axis = d->xaxis + 3*c->jnt[i];
    double point[3], nrm[3], delta;
    wheel_contact(&tv, centre, axis, c->radius, point, nrm, &delta, buf);

    double xc[3], yc[3];
    cross3(xc, axis, nrm);
    double len = norm3(xc);
    for (int k = 0; k < 3; k++) xc[k] /= len;
    cross3(yc, nrm, xc);

    // velocity field of the carrier, at the contact point and at the hub
    const double* cv = d->cvel + 6*c->carrier[i];
    const double* ref = d->subtree_com + 3*c->root[i];
    double rp[3], rc[3], wp[3], wc[3], v_p[3], v_c[3];
    for (int k = 0; k < 3; k++) {
      rp[k] = point[k] - ref[k];
      rc[k] = centre[k] - ref[k];
    }
    cross3(wp, cv, rp);
    cross3(wc, cv, rc);
    for (int k = 0; k < 3; k++) {
      v_p[k] = cv[3 + k] + wp[k];
      v_c[k] = cv[3 + k] + wc[k];
    }
    double v_x = dot3(v_p, xc);
    double v_y = dot3(v_p, yc);
    // rolling radius r_e = d - k_re*delta (TireParams.k_re)
    double r_e = c->radius - tp[K_RE]*np_max(delta, 0.0);
    double v_w = r_e*d->qvel[c->dof[i]];
    double delta_dot = -dot3(v_c, nrm);

    // tire.normal_force
    double fzn = np_max(tp[C_Z]*delta + tp[D_Z]*delta_dot, 0.0);
    double F_z = delta > 0.0 ? fzn : 0.0;

    double mu_x, mu_y;
    int patch, soil;
    friction(&tv, point[0], point[1], &mu_x, &mu_y, &patch, &soil);
    if (c->load_fall != 0.0) {  // effects.LoadDependentFriction.friction
      double r = np_min(np_max((F_z - c->load_fz0)/c->load_span, -0.5), 0.5);
      double k = 1.0 - c->load_fall*r;
      mu_x = mu_x*k;
      mu_y = mu_y*k;
    }

    // tire.transient_step
    double ux = st[L.ux + i], uy = st[L.uy + i];
    double ux_new = 0.0, uy_new = 0.0, F_x = 0.0, F_y = 0.0;
    if (soil == 0) {  // hard ground (a soil wheel's Gim forces would be discarded)
    double speed = np_max(np_max(fabs(v_x), fabs(v_w)), tp[V_FLOOR]);  // TireParams.v_floor
    const int split = tp[LAT_SPLIT] != 0.0;  // TireParams.lateral_split: eq. (11) as SPEC
    double speed_y = split ? np_max(fabs(v_x), tp[V_FLOOR]) : speed;
    double x = np_max(speed*dt_sx, X_FLOOR);
    double y = np_max(speed_y*dt_sy, X_FLOOR);
    double em_x = expm1(-x);
    double em_y = y == x ? em_x : expm1(-y);  // sigma_x == sigma_y by default: one call
    ux_new = ux*(em_x + 1.0) - (v_x - v_w)*(dt*em_x/x);
    uy_new = uy*(em_y + 1.0) - v_y*(dt*em_y/y);
    double lat = 1.0;  // tire.lateral_factor
    if (split) {
      double s_r = slip_ratio(v_x, v_w, tp[V_EPS]);
      if (s_r < 0.0) lat = 1.0 - fabs(s_r);
    }
    double fz = np_max(F_z, 0.0);
    double lim_x = sx*np_min((fz*mu_x)*c->three_over_cs, 1.0);
    double lim_y = (fz*mu_y)*c->three_sy_over_calpha;
    if (split) lim_y = lim_y/np_max(lat, LATERAL_FACTOR_MIN);
    ux_new = np_min(np_max(ux_new, -lim_x), lim_x);
    uy_new = np_min(np_max(uy_new, -lim_y), lim_y);
    double ux_dot = (ux_new - ux)/dt;
    double uy_dot = (uy_new - uy)/dt;

    // tire.transient_forces
    double bound_x, bound_y;
    double mag_x = gim_magnitude(fabs(ux_new)/sx, fz, mu_x, c->three_over_cs, &bound_x);
    double uy_seen = uy_new*lat;
    double mag_y = gim_magnitude(fabs(uy_seen)/sy, fz, mu_y, c->three_over_calpha, &bound_y);
    double f_x = -np_sign(ux_new)*mag_x - tp[D_X]*ux_dot;
    double f_y = -np_sign(uy_seen)*mag_y - tp[D_Y]*(uy_dot*lat);
    F_x = np_min(np_max(f_x, -bound_x), bound_x);
    F_y = np_min(np_max(f_y, -bound_y), bound_y);
    if (c->combined_on != 0.0) {  // effects.CombinedSlip.forces: the friction ellipse
      double fzc = np_max(F_z, 1e-12);
      double n = hypot(F_x/(mu_x*fzc), F_y/(mu_y*fzc));
      double sc = 1.0/np_max(n, 1.0);
      F_x = F_x*sc;
      F_y = F_y*sc;
    }
    }  // hard ground

    double sink = 0.0, torque = 0.0, dig = 0.0;
    double* pw = st + L.pwrite + 6*i;
    pw[0] = pw[1] = pw[2] = pw[3] = pw[4] = pw[5] = 0.0;
    if (soil > 0) {  // loose soil: soil.soil_step and TireLayer's soil branch
      const double* sp = tv.soil + SOIL_STRIDE*(soil - 1);
      double r = c->radius;
      double ssx = sp[S_SIGMA] > 0.0 ? sp[S_SIGMA] : sx;  // the soil's relaxation length
      double ssy = sp[S_SIGMA] > 0.0 ? sp[S_SIGMA] : sy;
      v_w = r*d->qvel[c->dof[i]];
      double rut = rut_footprint(&tv, st + L.rut, icap, point, axis, c->width);
      double rho_x = np_max(np_max(fabs(v_x), fabs(v_w)), SOIL_V_EPS)/ssx;
      double rho_y = np_max(fabs(v_x), SOIL_V_EPS)/ssy;
      double emx = expm1(-rho_x*dt), emy = expm1(-rho_y*dt);
      ux_new = ux*(emx + 1.0) + (v_x - v_w)*(-emx/rho_x);
      uy_new = uy*(emy + 1.0) + v_y*(-emy/rho_y);
      ux_new = np_min(np_max(ux_new, -ssx), ssx);
      uy_new = np_min(np_max(uy_new, -SOIL_MAX_TAN_BETA*ssy), SOIL_MAX_TAN_BETA*ssy);
      double s_fwd = -ux_new/ssx;
      double tan_b = uy_new/ssy;
      dig = st[L.dig + i];
      int contact_prev = delta - np_max(rut, dig) > 0.0;
      double rate = contact_prev ? sp[S_KDIG]*sp[S_MEMORY]*np_max(fabs(v_w) - fabs(v_x), 0.0) : 0.0;
      dig = np_min(dig*exp(-fabs(v_x)*dt/r) + rate*dt, r);
      double h = delta - dig;
      double h_c = delta - np_max(rut, dig);
      double lead = fabs(v_w) >= fabs(v_x) ? v_w : v_x;
      double z = np_min(np_max(lead/SOIL_V_BLEND, -1.0), 1.0);  // soil.V_BLEND smoothstep
      double w = 0.5 + z*(0.75 - 0.25*z*z);
      double f[4] = {0, 0, 0, 0}, g[4] = {0, 0, 0, 0};
      double tan_phi = soil_tan_phi(c, sp[S_PHI]);
      if (w != 0.0) {
        stress_integrals(c->arcs, s_fwd, tan_b, 1.0, h, h_c, r, tan_phi, c->width, sp, f);
      }
      if (w != 1.0) {
        stress_integrals(c->arcs, -s_fwd, tan_b, -1.0, h, h_c, r, tan_phi, c->width, sp, g);
      }
      F_x = w*f[0] + (1.0 - w)*g[0];
      F_y = w*f[1] + (1.0 - w)*g[1];
      F_z = w*f[2] + (1.0 - w)*g[2];
      torque = w*f[3] + (1.0 - w)*g[3];
      int contact = h_c > 0.0;
      F_z = contact ? np_max(F_z + sp[S_DAMP]*delta_dot, 0.0) : 0.0;
      sink = np_max(h, 0.0);
      // rut_writes: behind a moving wheel, across its width
      if (fabs(v_x) > SOIL_V_BLEND && delta > 0.0 && sp[S_MEMORY] > 0.0
          && (long)st[L.nstep] % RUT_WRITE_EVERY == 0) {  // rut_writes
        double hw = np_min(sink, r);
        double e = 1.0 - hw/r;
        double length = np_max(tv.rut_cell, 2.0*fabs(v_x)*(RUT_WRITE_EVERY*dt));
        double back = (r*sqrt(np_max(0.0, 1.0 - e*e)) + 0.5*length) + 1.5*tv.rut_cell;
        double sgn = v_x > 0 ? 1.0 : -1.0;
        pw[0] = point[0] - sgn*back*xc[0];
        pw[1] = point[1] - sgn*back*xc[1];
        rut_across(axis, &pw[2], &pw[3]);
        pw[4] = sp[S_MEMORY]*delta;
        pw[5] = length;
      }
    }

    double force[3];
    for (int k = 0; k < 3; k++) force[k] = (F_x*xc[k] + F_y*yc[k]) + F_z*nrm[k];
    double tq[3] = {-torque*axis[0], -torque*axis[1], -torque*axis[2]};  // 0 off soil
    apply_ft(m, d, force, tq, soil > 0 ? centre : point, c->body[i], qfrc);
    st[L.pdig + i] = dig;

    st[L.pux + i] = ux_new;
    st[L.puy + i] = uy_new;
    out[T_VX*nw + i] = v_x;
    out[T_VY*nw + i] = v_y;
    out[T_VW*nw + i] = v_w;
    out[T_FX*nw + i] = F_x;
    out[T_FY*nw + i] = F_y;
    out[T_FZ*nw + i] = F_z;
    out[T_DELTA*nw + i] = delta;
    for (int k = 0; k < 3; k++) {
      out[T_POINT*nw + 3*i + k] = point[k];
      out[T_NORMAL*nw + 3*i + k] = nrm[k];
    }
    out[T_PATCH*nw + i] = patch;
    out[T_SINK*nw + i] = sink;
    out[T_TORQUE*nw + i] = torque;
    out[T_SOIL*nw + i] = soil;
  }
  mju_addTo(d->qfrc_passive, qfrc, nv);
}

static void tire_advance(const mjModel* m, mjData* d, int instance) {
  const Config* c = (const Config*)d->plugin_data[instance];
  if (!c) return;
  const Layout L = layout_of(c->nw, c->nd, c->rut_state);
  mjtNum* st = d->plugin_state + m->plugin_stateadr[instance];
  // pending u_x, u_y, sp -> committed, pending truth -> truth
  memcpy(st + L.ux, st + L.pux, sizeof(mjtNum) * (2*c->nw + c->nd));
  memcpy(st + L.truth, st + L.ptruth, sizeof(mjtNum) * NTRUTH*c->nw);
  memcpy(st + L.dig, st + L.pdig, sizeof(mjtNum) * c->nw);
  // the rut map remembers the deepest pass (TireLayer.apply: the wheels' writes in order)
  // (most substeps write nothing: rut writes come every RUT_WRITE_EVERY-th, on soil only)
  int pending = 0;
  for (int i = 0; i < c->nw && c->rut_state > 0; i++) pending |= st[L.pwrite + 6*i + 4] > 0.0;
  TerrainView tv;
  const int icap = rut_index_capacity(c->rut_state);
  if (pending && terrain_view(m, c->terrain, &tv) && tv.rut_nx*tv.rut_ny > 0
      && tv.rut_ntx*tv.rut_nty <= icap) {
    for (int i = 0; i < c->nw; i++) {
      const double* pw = st + L.pwrite + 6*i;
      if (pw[4] > 0.0) {
        rut_write(&tv, st + L.rut, icap, pw[0], pw[1], pw[2], pw[3], pw[4], c->width, pw[5]);
      }
    }
  }
  if (st[L.sched + 1] < st[L.sched]) st[L.sched + 1] += 1.0;  // the queued row is used
  st[L.nstep] += 1.0;
}

mjPLUGIN_LIB_INIT(rover_env_tire) {
  mjpPlugin plugin;
  mjp_defaultPlugin(&plugin);
  plugin.name = PLUGIN_NAME;
  plugin.capabilityflags = mjPLUGIN_PASSIVE;
  plugin.nattribute = sizeof(kAttributes) / sizeof(kAttributes[0]);
  plugin.attributes = kAttributes;
  plugin.nstate = tire_nstate;
  plugin.init = tire_init;
  plugin.destroy = tire_destroy;
  plugin.copy = tire_copy;
  plugin.reset = tire_reset;
  plugin.compute = tire_compute;
  plugin.advance = tire_advance;
  mjp_registerPlugin(&plugin);
}
