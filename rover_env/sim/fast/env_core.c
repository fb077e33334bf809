// The environment's per-sample work in C: sensor model, kinematic slip estimator, step sums.
//
// Compiled twin of numpy reference code, as tire_plugin.c is of rover_env.sim.tire_layer:
//   * the estimator (est_*) repeats rover_env.envs.proto_explorer.BatchSlipEstimator, i.e.
//     SlipEstimator with rate_method="lsq" (windowed least-squares rates, dead reckoning)
//     and rover_env.estimation.estimator._kinematic_part (rover_env.kinematics.chain_motion,
//     nominal rates, slip ratio, reliability flags); the sums are taken in another order
//     than numpy's, so results agree to rounding (tests: 1e-12), not bit for bit;
//   * env_step_samples repeats the sample loop of ProtoExplorerEnv.step with the plugin
//     backend: mj_step, SensorModel.read, the estimator's push, the middle segment's
//     velocity, the driven wheels' true slip and StepSums.add, operation by operation (the
//     vector env does the same arithmetic in numpy, and its tests compare bits).
// Why: at 50 Hz estimation and 10 Hz control, the numpy version of this loop cost twice the
// physics it samples (docs/speed.md).

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <mujoco/mujoco.h>

#define NY 11  // wheel angles 1L..3R, then joint angles theta_1..theta_5

enum { FLAG_WARMUP = 1, FLAG_STANDSTILL = 2, FLAG_FREE_WHEELS = 4, FLAG_SLOW_WHEEL = 8 };

typedef struct {
  // configuration
  int n, cap;
  double limit;        // rate_window * (1 + slack): the streaming window
  double rate_window;  // for the warm-up flag
  double radii[6], half_track, link_a[3], anchor[3];
  double v_eps, min_speed, max_free_ratio, max_side_slip;
  // state per rover: ring buffer of the window (oldest at head), dead-reckoned pose
  double* t;  // n * cap
  double* y;  // n * cap * NY
  int* head;
  int* count;
  int* started;
  double* t0;
  double* pose;  // n * 3
} Estimator;

Estimator* est_new(int n, const double* cfg) {
  // cfg: limit, rate_window, radii[6], half_track, link_a[3], anchor[3], v_eps, min_speed,
  //      max_free_ratio, max_side_slip (19 numbers)
  Estimator* e = calloc(1, sizeof(Estimator));
  if (!e) return NULL;
  e->n = n;
  e->cap = 64;
  e->limit = cfg[0];
  e->rate_window = cfg[1];
  memcpy(e->radii, cfg + 2, 6 * sizeof(double));
  e->half_track = cfg[8];
  memcpy(e->link_a, cfg + 9, 3 * sizeof(double));
  memcpy(e->anchor, cfg + 12, 3 * sizeof(double));
  e->v_eps = cfg[15];
  e->min_speed = cfg[16];
  e->max_free_ratio = cfg[17];
  e->max_side_slip = cfg[18];
  e->t = calloc((size_t)n * e->cap, sizeof(double));
  e->y = calloc((size_t)n * e->cap * NY, sizeof(double));
  e->head = calloc(n, sizeof(int));
  e->count = calloc(n, sizeof(int));
  e->started = calloc(n, sizeof(int));
  e->t0 = calloc(n, sizeof(double));
  e->pose = calloc((size_t)n * 3, sizeof(double));
  if (!e->t || !e->y || !e->head || !e->count || !e->started || !e->t0 || !e->pose) {
    free(e->t), free(e->y), free(e->head), free(e->count), free(e->started), free(e->t0);
    free(e->pose), free(e);
    return NULL;
  }
  return e;
}

void est_free(Estimator* e) {
  if (!e) return;
  free(e->t), free(e->y), free(e->head), free(e->count), free(e->started), free(e->t0);
  free(e->pose), free(e);
}

void est_reset(Estimator* e, int i) {
  e->count[i] = 0;
  e->head[i] = 0;
  e->started[i] = 0;
  e->pose[3 * i] = e->pose[3 * i + 1] = e->pose[3 * i + 2] = 0.0;
}

// Double the ring capacity of every rover, keeping each window in order from slot 0.
static int grow(Estimator* e) {
  int cap2 = 2 * e->cap;
  double* t2 = calloc((size_t)e->n * cap2, sizeof(double));
  double* y2 = calloc((size_t)e->n * cap2 * NY, sizeof(double));
  if (!t2 || !y2) {
    free(t2), free(y2);
    return -1;
  }
  for (int i = 0; i < e->n; i++) {
    for (int k = 0; k < e->count[i]; k++) {
      int s = (e->head[i] + k) % e->cap;
      t2[(size_t)i * cap2 + k] = e->t[(size_t)i * e->cap + s];
      memcpy(y2 + ((size_t)i * cap2 + k) * NY, e->y + ((size_t)i * e->cap + s) * NY,
             NY * sizeof(double));
    }
    e->head[i] = 0;
  }
  free(e->t), free(e->y);
  e->t = t2, e->y = y2, e->cap = cap2;
  return 0;
}

static const double* newest_y(const Estimator* e, int i) {
  int s = (e->head[i] + e->count[i] - 1) % e->cap;
  return e->y + ((size_t)i * e->cap + s) * NY;
}

static double newest_t(const Estimator* e, int i) {
  int s = (e->head[i] + e->count[i] - 1) % e->cap;
  return e->t[(size_t)i * e->cap + s];
}

// One sample of rover i (SlipEstimator.update's storing part). Returns 0, -1 if time does
// not increase, -2 on a non-finite value, -3 if out of memory.
int est_push(Estimator* e, int i, double t, const double* y) {
  if (!isfinite(t)) return -2;
  for (int c = 0; c < NY; c++)
    if (!isfinite(y[c])) return -2;
  int started = e->started[i];
  double prev_free[2] = {0.0, 0.0};
  if (started) {
    if (e->count[i] > 0 && t <= newest_t(e, i)) return -1;
    const double* p = newest_y(e, i);
    prev_free[0] = p[4];
    prev_free[1] = p[5];
  }
  if (e->count[i] + 1 > e->cap && grow(e)) return -3;
  int s = (e->head[i] + e->count[i]) % e->cap;
  e->t[(size_t)i * e->cap + s] = t;
  memcpy(e->y + ((size_t)i * e->cap + s) * NY, y, NY * sizeof(double));
  e->count[i]++;
  // The streaming window: drop samples older than the window (never the newest).
  while (e->count[i] > 1 && t - e->t[(size_t)i * e->cap + e->head[i]] > e->limit) {
    e->head[i] = (e->head[i] + 1) % e->cap;
    e->count[i]--;
  }
  if (started) {  // dead reckoning from the free wheels' angle increments
    double left = e->radii[4] * (y[4] - prev_free[0]);
    double right = e->radii[5] * (y[5] - prev_free[1]);
    double ds = (right + left) / 2.0, dpsi = (right - left) / (2.0 * e->half_track);
    double* pose = e->pose + 3 * i;
    double heading = pose[2] + dpsi / 2.0;
    pose[0] = pose[0] + ds * cos(heading);
    pose[1] = pose[1] + ds * sin(heading);
    pose[2] = pose[2] + dpsi;
  } else {
    e->t0[i] = t;
  }
  e->started[i] = 1;
  return 0;
}

// ------------------------------------------------------------------------------ kinematics

static void rot(int axis, double a, double r[9]) {
  double c = cos(a), s = sin(a);
  memset(r, 0, 9 * sizeof(double));
  r[4 * axis] = 1.0;
  int i = axis == 0 ? 1 : 0, j = axis == 2 ? 1 : 2;
  r[4 * i] = c;
  r[4 * j] = c;
  if (axis == 1) {  // the cyclic order (z, x) flips the off-diagonal signs
    r[3 * i + j] = s;
    r[3 * j + i] = -s;
  } else {
    r[3 * i + j] = -s;
    r[3 * j + i] = s;
  }
}

static void matmul(const double a[9], const double b[9], double out[9]) {
  double o[9];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) o[3 * r + c] = a[3 * r] * b[c] + a[3 * r + 1] * b[3 + c] + a[3 * r + 2] * b[6 + c];
  memcpy(out, o, sizeof(o));
}

static void transpose(const double a[9], double out[9]) {
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) out[3 * c + r] = a[3 * r + c];
}

static void mulv(const double a[9], const double v[3], double out[3]) {  // a @ v
  double o[3];
  for (int r = 0; r < 3; r++) o[r] = a[3 * r] * v[0] + a[3 * r + 1] * v[1] + a[3 * r + 2] * v[2];
  memcpy(out, o, sizeof(o));
}

static void mulvt(const double a[9], const double v[3], double out[3]) {  // a^T @ v
  double o[3];
  for (int c = 0; c < 3; c++) o[c] = a[c] * v[0] + a[3 + c] * v[1] + a[6 + c] * v[2];
  memcpy(out, o, sizeof(o));
}

static void cross(const double a[3], const double b[3], double out[3]) {
  double o[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  memcpy(out, o, sizeof(o));
}

// Joint axes of SPEC §1's table: theta_1 x, theta_2 z (1-2); theta_3 x, theta_4 y, theta_5 z.
static const int AXIS[5] = {0, 2, 0, 1, 2};

static double slip_of(double vx, double vw, double v_eps) {  // rover_env.tire.slip_ratio
  double total = vx + vw;
  double d = total == 0.0 ? vx : total;
  double dir = d > 0.0 ? 1.0 : (d < 0.0 ? -1.0 : d);
  double den = fmax(fmax(fabs(vx), fabs(vw)), v_eps);
  double s = dir * (vx - vw) / den;
  return s < -1.0 ? -1.0 : (s > 1.0 ? 1.0 : s);
}

// _kinematic_part for one sample: rates (11), theta (5) -> out (layout in fast.py)
static void kinematic_part(const Estimator* e, const double* rates, const double* th,
                           double* out) {
  const double* phi_rate = rates;
  const double* theta_rate = rates + 6;
  double r = e->half_track;
  // eq. (1): segment 3's twist from its free wheels
  double left = e->radii[4] * phi_rate[4], right = e->radii[5] * phi_rate[5];
  double w3[3] = {0.0, 0.0, (right - left) / (2.0 * r)};
  double v3[3] = {(right + left) / 2.0, 0.0, 0.0};
  // coupling rotations and segment orientations in segment 3's axes
  double ra[5][9];
  for (int k = 0; k < 5; k++) rot(AXIS[k], th[k], ra[k]);
  double r12[9], r23[9], tmp[9];
  matmul(ra[0], ra[1], r12);
  matmul(ra[2], ra[3], tmp);
  matmul(tmp, ra[4], r23);
  double q[3][9];
  double eye[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  memcpy(q[2], eye, sizeof(eye));
  transpose(r23, q[1]);
  double r12t[9];
  transpose(r12, r12t);
  matmul(q[1], r12t, q[0]);
  // joint axes in each child's axes: (A_{k+1} ... A_m)^T e_k
  double w_all[3][3], v_all[3][3];
  memcpy(w_all[2], w3, sizeof(w3));
  memcpy(v_all[2], v3, sizeof(v3));
  const int first[2] = {2, 0}, last[2] = {5, 2};  // joints of couplings 2-3 and 1-2
  for (int c = 0; c < 2; c++) {                     // child 3 then child 2
    int child = 3 - c;                              // 3, 2
    const double* qc = q[child - 1];
    const double* qp = q[child - 2];
    double w_rel[3] = {0.0, 0.0, 0.0};
    for (int k = first[c]; k < last[c]; k++) {
      double v[3] = {0.0, 0.0, 0.0};
      v[AXIS[k]] = 1.0;
      for (int l = k + 1; l < last[c]; l++) mulvt(ra[l], v, v);
      for (int x = 0; x < 3; x++) w_rel[x] = w_rel[x] + v[x] * theta_rate[k];
    }
    const double* w_c = w_all[child - 1];
    const double* v_c = v_all[child - 1];
    double qw[3], qj[3], qa[3], cr[3];
    mulv(qc, w_rel, qw);
    double* w_p = w_all[child - 2];
    double* v_p = v_all[child - 2];
    for (int x = 0; x < 3; x++) w_p[x] = w_c[x] - qw[x];
    mulv(qc, e->anchor, qj);
    cross(w_c, qj, cr);
    double v_anchor[3];
    for (int x = 0; x < 3; x++) v_anchor[x] = v_c[x] + cr[x];
    mulv(qp, e->link_a, qa);
    for (int x = 0; x < 3; x++) qa[x] = -qa[x];
    cross(w_p, qa, cr);
    for (int x = 0; x < 3; x++) v_p[x] = v_anchor[x] + cr[x];
  }
  double w_own[3][3], v_own[3][3];
  for (int s = 0; s < 3; s++) {
    mulvt(q[s], w_all[s], w_own[s]);
    mulvt(q[s], v_all[s], v_own[s]);
  }
  // eqs. (7)-(10)
  double nominal[4], actual[4], slip[4];
  for (int s = 0; s < 2; s++) {
    double vx = v_own[s][0], wz = w_own[s][2];
    nominal[2 * s] = (vx - r * wz) / e->radii[2 * s];
    nominal[2 * s + 1] = (vx + r * wz) / e->radii[2 * s + 1];
  }
  for (int k = 0; k < 4; k++) {
    actual[k] = phi_rate[k];
    slip[k] = slip_of(e->radii[k] * nominal[k], e->radii[k] * actual[k], e->v_eps);
  }
  // reliability flags
  double tread0 = phi_rate[4] * e->radii[4], tread1 = phi_rate[5] * e->radii[5];
  int standstill = fabs(v3[0]) < e->min_speed;
  double ratio = fabs(tread1 - tread0) / fmax(fabs(tread1 + tread0), 1e-12);
  int side = 0;
  for (int s = 0; s < 2; s++)
    if (atan2(fabs(v_own[s][1]), fabs(v_own[s][0])) > e->max_side_slip) side = 1;
  int free_bad = !standstill && (ratio > e->max_free_ratio || side);
  // out: phi_rate 6, theta_rate 5, nominal 4, actual 4, slippage 4, slip 4, seg_velocity 9,
  //      seg_omega 9, seg_yaw_rate 3, flags 4 (then t, pose 3 by est_estimate)
  memcpy(out, rates, NY * sizeof(double));
  for (int k = 0; k < 4; k++) {
    out[11 + k] = nominal[k];
    out[15 + k] = actual[k];
    out[19 + k] = actual[k] - nominal[k];
    out[23 + k] = slip[k];
    int slow = fmax(fabs(nominal[k]), fabs(actual[k])) * e->radii[k] < e->min_speed;
    int f = (standstill ? FLAG_STANDSTILL : 0) | (free_bad ? FLAG_FREE_WHEELS : 0) |
            (slow ? FLAG_SLOW_WHEEL : 0);
    out[48 + k] = (double)f;
  }
  for (int s = 0; s < 3; s++)
    for (int x = 0; x < 3; x++) {
      out[27 + 3 * s + x] = v_own[s][x];
      out[36 + 3 * s + x] = w_own[s][x];
    }
  for (int s = 0; s < 3; s++) out[45 + s] = w_own[s][2];
}

// The estimate at rover i's newest sample into out (56 numbers, layout in fast.py). Returns 0, or -1 if the
// rover has no sample since its reset.
int est_estimate(const Estimator* e, int i, double* out) {
  int cnt = e->count[i];
  if (!e->started[i] || cnt == 0) return -1;
  double tn = newest_t(e, i);
  const double* yn = newest_y(e, i);
  // least-squares slope through the window, times and values relative to the newest
  double n = (double)cnt, s_t = 0.0, s_tt = 0.0, s_z[NY] = {0}, s_tz[NY] = {0};
  for (int k = 0; k < cnt; k++) {
    int s = (e->head[i] + k) % e->cap;
    double tau = e->t[(size_t)i * e->cap + s] - tn;
    const double* y = e->y + ((size_t)i * e->cap + s) * NY;
    s_t += tau;
    s_tt += tau * tau;
    for (int c = 0; c < NY; c++) {
      double z = y[c] - yn[c];
      s_z[c] += z;
      s_tz[c] += tau * z;
    }
  }
  double den = n * s_tt - s_t * s_t;
  double rates[NY];
  for (int c = 0; c < NY; c++)
    rates[c] = (cnt >= 2 && den > 0) ? (n * s_tz[c] - s_t * s_z[c]) / den : 0.0;
  kinematic_part(e, rates, yn + 6, out);
  if (tn - e->t0[i] < e->rate_window)
    for (int k = 0; k < 4; k++) out[48 + k] = (double)((int)out[48 + k] | FLAG_WARMUP);
  out[52] = tn;
  memcpy(out + 53, e->pose + 3 * i, 3 * sizeof(double));
  return 0;
}

// --------------------------------------------------------------------------- sample loop

// volatile: keeps the compiler from turning pow(x, 2.0) into x * x, which differs by an ulp
// now and then from libm's pow, the one the numpy loop calls.
static volatile double TWO = 2.0;

static double quantize(double x, double res) { return res == 0 ? x : nearbyint(x / res) * res; }

// Indices and constants of one rover model (filled by fast.py from RoverIndex).
typedef struct {
  int substeps, samples;
  int phi_adr[6], theta_adr[5];
  int ctrl_vel[4], driven_dof[4];
  int seg2_body;
  int truth_vx, truth_vw;  // plugin_state addresses of v_x and v_w of wheel 1L
  int wheel_noisy, joint_noisy;  // SensorModel adds noise only where its rms is > 0
  double wheel_res, joint_res, copper, sample_dt, v_eps;
} StepSpec;

// SensorModel.read of one sample: wheel counters from their zero phi0, potentiometers;
// nz the sample's noise (11, used only where the sensor is noisy). y (11) out.
static void read_sensors(const double* sd, const double* nz, const double* phi0,
                         const StepSpec* sp, double* y) {
  for (int k = 0; k < 6; k++)
    y[k] = quantize((sp->wheel_noisy ? sd[sp->phi_adr[k]] + nz[k] : sd[sp->phi_adr[k]]) - phi0[k],
                    sp->wheel_res);
  for (int k = 0; k < 5; k++)
    y[6 + k] = quantize(sp->joint_noisy ? sd[sp->theta_adr[k]] + nz[6 + k] : sd[sp->theta_adr[k]],
                        sp->joint_res);
}

// True slip ratio of the driven wheels from the plugin's committed truth block.
static void driven_slip(const double* plugin_state, const StepSpec* sp, double* slip) {
  for (int k = 0; k < 4; k++)
    slip[k] = slip_of(plugin_state[sp->truth_vx + k], plugin_state[sp->truth_vw + k], sp->v_eps);
}

// StepSums.add for one rover and one sample, in the numpy loop's order of operations.
static void add_sample(double* sums, const double* command, double speed, double yaw_rate,
                       const double* force, const double* qvel, const StepSpec* sp,
                       const double* slip) {
  double dv = command[0] - speed, dw = command[1] - yaw_rate;
  sums[0] += pow(dv, TWO);  // libm pow, as numpy's scalar ** 2 (not always dv * dv)
  sums[1] += pow(dw, TWO);
  double power = 0.0;
  for (int k = 0; k < 4; k++) {
    double tau = force[k], omega = qvel[sp->driven_dof[k]];
    double p = tau * omega + sp->copper * (tau * tau);
    p = (p >= 0.0 || isnan(p)) ? p : 0.0;  // np.maximum(p, 0.0)
    power = k == 0 ? p : power + p;
  }
  sums[2] += power * sp->sample_dt;
  for (int k = 0; k < 4; k++) sums[3 + k] += fabs(slip[k]);
  sums[7] = speed;
  sums[8] = yaw_rate;
  for (int k = 0; k < 4; k++) sums[9 + k] = slip[k];
}

// ------------------------------------------------------------------- batch sample (vector env)

// Row-strided views (strides in doubles) of mujoco.batch's bound arrays.
typedef struct {
  const double *sensordata, *plugin_state, *cvel, *xipos, *ximat, *subtree_com, *force, *qvel,
      *time;
  long long s_sensordata, s_plugin_state, s_cvel, s_xipos, s_ximat, s_subtree_com, s_force,
      s_qvel, s_time;
  int seg2_root;
} BatchView;

// One 50 Hz sample of rovers rows[0..k) after their physics stepped: the sample loop's body,
// written once for both envs (ProtoExplorerVectorEnv.step calls it on mujoco.batch's rows,
// env_step_samples on one MjData as a row), as rover_env.sim.sample.run_samples does in
// numpy; the middle segment's velocity by RoverIndex.segment_velocity's arithmetic (equal to
// mj_objectVelocity's). noise (k * samples * 11), phi0 (k * 6), command (k * 2), theta_meas
// (k * 5), sums (k * 13; zeroed by the caller before the first sample).
int vec_sample(const StepSpec* sp, const BatchView* bv, Estimator* e, int k, const int* rows,
               int smp, const double* noise, const double* phi0, const double* command,
               double* theta_meas, double* sums) {
  for (int j = 0; j < k; j++) {
    int r = rows[j];
    double y[NY];
    read_sensors(bv->sensordata + r * bv->s_sensordata,
                 noise + ((size_t)j * sp->samples + smp) * 11, phi0 + 6 * j, sp, y);
    memcpy(theta_meas + 5 * j, y + 6, 5 * sizeof(double));
    int err = est_push(e, r, bv->time[r * bv->s_time], y);
    if (err) return err;
    // RoverIndex.segment_velocity: mju_transformSpatial, then into the body's axes
    int b = sp->seg2_body;
    const double* cv = bv->cvel + r * bv->s_cvel + 6 * b;
    const double* com = bv->subtree_com + r * bv->s_subtree_com + 3 * bv->seg2_root;
    const double* p = bv->xipos + r * bv->s_xipos + 3 * b;
    const double* rm = bv->ximat + r * bv->s_ximat + 9 * b;
    double w0 = cv[0], w1 = cv[1], w2 = cv[2];
    double d0 = p[0] - com[0], d1 = p[1] - com[1], d2 = p[2] - com[2];
    double t0 = cv[3] - (d1 * w2 - d2 * w1);
    double t1 = cv[4] - (d2 * w0 - d0 * w2);
    double t2 = cv[5] - (d0 * w1 - d1 * w0);
    double speed = rm[0] * t0 + rm[3] * t1 + rm[6] * t2;
    double yaw_rate = rm[2] * w0 + rm[5] * w1 + rm[8] * w2;
    double slip[4];
    driven_slip(bv->plugin_state + r * bv->s_plugin_state, sp, slip);
    add_sample(sums + 13 * j, command + 2 * j, speed, yaw_rate, bv->force + r * bv->s_force,
               bv->qvel + r * bv->s_qvel, sp, slip);
  }
  return 0;
}

// ProtoExplorerEnv.step's samples for one rover with the plugin backend: the physics of each
// sample, then vec_sample on the MjData as a batch of one row. targets (4): ctrl[vel]; noise
// (samples * 11, already scaled); phi0 (6): the wheel counters' zero; command (2). Outputs:
// theta_meas (5), sums (err_v2, err_w2, energy, slip[4], then the last sample's speed, yaw
// rate, slip[4]). Returns 0, 1 on a MuJoCo warning, 2 on a non-finite state (the caller
// raises), or the negative est_push error.
int env_step_samples(const mjModel* m, mjData* d, const StepSpec* sp, Estimator* e,
                     const double* targets, const double* noise, const double* phi0,
                     const double* command, double* theta_meas, double* sums) {
  // One row, stride 0: the pointers stay valid while mj_step runs (MjData never moves them).
  BatchView one = {d->sensordata, d->plugin_state, d->cvel, d->xipos, d->ximat, d->subtree_com,
                   d->actuator_force, d->qvel, &d->time, 0, 0, 0, 0, 0, 0, 0, 0, 0,
                   m->body_rootid[sp->seg2_body]};
  const int row = 0;
  for (int k = 0; k < 4; k++) d->ctrl[sp->ctrl_vel[k]] = targets[k];
  for (int k = 0; k < 13; k++) sums[k] = 0.0;
  for (int smp = 0; smp < sp->samples; smp++) {
    for (int k = 0; k < sp->substeps; k++) mj_step(m, d);
    for (int w = 0; w < mjNWARNING; w++)
      if (d->warning[w].number > 0) return 1;
    for (int k = 0; k < m->nq; k++)
      if (!isfinite(d->qpos[k])) return 2;
    for (int k = 0; k < m->nv; k++)
      if (!isfinite(d->qvel[k])) return 2;
    int err = vec_sample(sp, &one, e, 1, &row, smp, noise, phi0, command, theta_meas, sums);
    if (err) return err;
  }
  return 0;
}
