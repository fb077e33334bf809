// The soil arcs' node loop (rover_env.soil.stress_integrals), included by tire_plugin.c once
// per vector width: SOIL_VL lanes of doubles, names suffixed with SOIL_SUFFIX. Each lane
// rounds exactly as numpy does (+, -, *, /, comparisons and bit operations only; the
// -ffp-contract=off of the build forbids fused multiply-adds), so every width gives the same
// numbers. An arc's 8 nodes sit in NQ vectors: vector q < NQ/2 holds the upper nodes
// 4 + q VL + lane, vector NQ/2 + q their mirrors 3 - q VL - lane (x_{7-k} = -x_k, so the
// sign flips are exact and one polynomial serves a node and its mirror).

#define SN_CAT2(a, b) a##b
#define SN_CAT(a, b) SN_CAT2(a, b)
#define SN(name) SN_CAT(name, SOIL_SUFFIX)
#define VL SOIL_VL
#define NQ (SOIL_NODES/VL)
#define MAXV (3*NQ)
#define vd SN(vd)
#define vm SN(vm)
#define vu SN(vu)

typedef double vd __attribute__((vector_size(8*VL)));
typedef int64_t vm __attribute__((vector_size(8*VL)));   // comparison masks (0 or -1)
typedef uint64_t vu __attribute__((vector_size(8*VL)));

static inline __attribute__((always_inline)) vd SN(splat)(double x) {
  vd v;
  for (int i = 0; i < VL; i++) v[i] = x;
  return v;
}

// a where m, else b
static inline __attribute__((always_inline)) vd SN(sel)(vm m, vd a, vd b) {
  return (vd)(((vu)m & (vu)a) | (~(vu)m & (vu)b));
}

// np.maximum(a, 0.0) (a NaN stays NaN)
static inline __attribute__((always_inline)) vd SN(max0)(vd a) {
  return SN(sel)((a >= 0.0) | (a != a), a, SN(splat)(0.0));
}

// np.abs
static inline __attribute__((always_inline)) vd SN(abs)(vd a) {
  return (vd)((vu)a & 0x7fffffffffffffffULL);
}

// np.sign
static inline __attribute__((always_inline)) vd SN(sign)(vd a) {
  vd one = SN(splat)(1.0), zero = SN(splat)(0.0);
  return SN(sel)(a > 0.0, one, SN(sel)(a < 0.0, -one, SN(sel)(a == 0.0, zero, a)));
}

// lanes q VL .. q VL + VL - 1 of a table of the upper nodes
static inline __attribute__((always_inline)) vd SN(upper)(const double* a, int q) {
  vd v;
  for (int i = 0; i < VL; i++) v[i] = a[q*VL + i];
  return v;
}

// soil._estrin: sum_k C[k] y^k over n = 8, 12 or 14 coefficients by Estrin's scheme: the
// pairs C[2k] + C[2k+1] y, then pairs of those with y^2, y^4, y^8 (an odd one out carried
// up): a short dependency chain. Written out per n so that it unrolls.
static inline __attribute__((always_inline)) vd SN(estrin)(vd y, const double* C, int n) {
  vd y2 = y*y;
  vd y4 = y2*y2;
  vd p0 = C[0] + C[1]*y, p1 = C[2] + C[3]*y, p2 = C[4] + C[5]*y, p3 = C[6] + C[7]*y;
  vd q0 = p0 + p1*y2, q1 = p2 + p3*y2;
  if (n == 8) return q0 + q1*y4;
  vd y8 = y4*y4;
  vd p4 = C[8] + C[9]*y, p5 = C[10] + C[11]*y;
  vd q2 = p4 + p5*y2;
  if (n == 12) return (q0 + q1*y4) + q2*y8;
  vd p6 = C[12] + C[13]*y;  // n == 14: q3 = p6
  return (q0 + q1*y4) + (q2 + p6*y4)*y8;
}

// soil._exp: e^x in place for m vectors, relative error ~2e-16; 0 below -708, inf above 709.
// The vectors go side by side (loops over i innermost): a polynomial's dependency chain is
// long, independent ones interleave.
static inline __attribute__((always_inline)) void SN(exp_n)(vd* x, int m) {
  _Pragma("GCC unroll 12") for (int i = 0; i < m; i++) {
    vd kd = x[i]*INV_LN2 + EXP_SHIFT;
    vd k = kd - EXP_SHIFT;
    vd r = (x[i] - k*LN2_HI) - k*LN2_LO;  // |r| <= ln2/2
    vd p = SN(estrin)(r, EXP_C, 14);
    vu e = ((vu)kd - EXP_SHIFT_BITS + 1023) << 52;  // 2^k
    vd y = SN(sel)(x[i] < -708.0, SN(splat)(0.0), p*(vd)e);
    x[i] = SN(sel)(x[i] > 709.0, SN(splat)(INFINITY), y);
  }
}

// soil._log: natural log of a normal x > 0 (fdlibm's e_log.c without its special cases):
// x = 2^k z, z in [sqrt(1/2), sqrt(2)), log z from s = (z - 1)/(z + 1)
static inline __attribute__((always_inline)) vd SN(log)(vd x) {
  vu ix = (vu)x;
  vu tmp = ix - LOG_OFF;
  vu ku = (tmp + (1024ULL << 52)) >> 52;  // k + 1024
  vd kd = (vd)(ku | TWO52_BITS) - (4503599627370496.0 + 1024.0);
  vd f = (vd)(ix - (tmp & TOP12)) - 1.0;
  vd s = f/(2.0 + f);
  vd z = s*s;
  vd w = z*z;
  vd t1 = w*(LG2 + w*(LG4 + w*LG6));
  vd t2 = z*(LG1 + w*(LG3 + w*(LG5 + w*LG7)));
  vd rr = t2 + t1;
  vd hfsq = 0.5*f*f;
  return kd*LN2_HI - ((hfsq - (s*(hfsq + rr) + kd*LN2_LO)) - f);
}

// soil._sincos_nodes: sin (if sn) and cos at mid + half x_k
static inline __attribute__((always_inline)) void SN(sincos_nodes)(double mid, double half,
                                                                   vd* sn, vd* cs) {
  double sm, cm;
  sincos(mid, &sm, &cm);
  int terms = fabs(half) <= 0.6 ? 8 : 12;  // soil._SHORT_HALF
  _Pragma("GCC unroll 2") for (int q = 0; q < NQ/2; q++) {
    vd a = half*SN(upper)(GL_XU, q);
    vd a2 = a*a;
    vd c, s;  // cos(mid + a) needs sin a too
    if (terms == 8) {
      c = SN(estrin)(a2, SC_COS, 8);
      s = SN(estrin)(a2, SC_SIN, 8);
    } else {
      c = SN(estrin)(a2, SC_COS, 12);
      s = SN(estrin)(a2, SC_SIN, 12);
    }
    vd sa = a*s;
    cs[q] = cm*c - sm*sa;
    cs[NQ/2 + q] = cm*c + sm*sa;
    if (sn) {
      sn[q] = sm*c + cm*sa;
      sn[NQ/2 + q] = sm*c - cm*sa;
    }
  }
}

// numpy's pairwise sum of an arc's 8 node values: ((n0 + n1) + (n2 + n3)) + ((n4 + n5) + (n6 + n7))
static inline __attribute__((always_inline)) double SN(node_sum)(const vd* v) {
  double n[SOIL_NODES];
  for (int q = 0; q < NQ/2; q++) {
    for (int i = 0; i < VL; i++) {
      n[SOIL_NODES/2 + q*VL + i] = v[q][i];
      n[SOIL_NODES/2 - 1 - q*VL - i] = v[NQ/2 + q][i];
    }
  }
  return ((n[0] + n[1]) + (n[2] + n[3])) + ((n[4] + n[5]) + (n[6] + n[7]));
}

// one arc of nonzero width (ArcsFn); n1: the exponent n is 1 (pow(x, 1) == x exactly: no log)
static inline __attribute__((always_inline)) void SN(arc)(const ArcShared* A, double lo,
                                                          double hi, int n1, double sums[4]) {
  const double r = A->r;
  double mid = 0.5*(hi + lo);
  double half = 0.5*(hi - lo);
  int rear = hi <= A->th_m;
  vd sin_t[NQ], cos_t[NQ], cos_eq[NQ];
  SN(sincos_nodes)(mid, half, sin_t, cos_t);
  // behind th_m the normal stress is that at th_eq (its cosine)
  if (rear) {
    SN(sincos_nodes)(A->th_f - (mid - A->th_r)*A->slope, -(half*A->slope), NULL, cos_eq);
  } else {
    for (int q = 0; q < NQ; q++) cos_eq[q] = cos_t[q];  // ahead of th_m: at the node itself
  }
  // the exponentials' arguments: shear -|j_x|/k_x, lateral -|j_y|/k_y, then n log(base)
  vd base[NQ], j_x[NQ], ex[MAXV];
  _Pragma("GCC unroll 4") for (int q = 0; q < NQ; q++) {
    vd a = half*SN(upper)(GL_XU, q % (NQ/2));
    vd th = q >= NQ/2 ? mid - a : mid + a;  // mid + half x_k (x_{7-k} = -x_k exactly)
    base[q] = SN(max0)(r*(cos_eq[q] - A->cos_f));
    vd ahead = A->th_c - th;
    j_x[q] = r*(ahead - A->one_s*(A->sin_c - sin_t[q]));
    ex[q] = -SN(abs)(j_x[q])/A->k_x;
    ex[NQ + q] = -(A->g*ahead);
    if (!n1) ex[2*NQ + q] = A->n*SN(log)(base[q]);
  }
  if (n1) SN(exp_n)(ex, 2*NQ); else SN(exp_n)(ex, 3*NQ);  // constant counts: unrolled
  vd ax[NQ], ay[NQ], az[NQ], at[NQ];
  _Pragma("GCC unroll 4") for (int q = 0; q < NQ; q++) {
    vd w = half*SN(upper)(GL_WU, q % (NQ/2));
    // soil._pow_pos: 0 where base is not a normal positive number
    vd sigma = A->ks*(n1 ? base[q]
                         : SN(sel)(base[q] >= 0x1p-1022, ex[2*NQ + q], SN(splat)(0.0)));
    vd tau_max = A->c + sigma*A->tan_phi;
    vd tau_x = tau_max*SN(sign)(j_x[q])*(1.0 - ex[q]);
    vd tau_y = tau_max*A->sgn_y*(1.0 - ex[NQ + q]);
    ax[q] = w*(tau_x*cos_t[q] - sigma*sin_t[q]);
    ay[q] = w*tau_y;
    az[q] = w*(tau_x*sin_t[q] + sigma*cos_t[q]);
    at[q] = w*tau_x;
  }
  sums[0] += SN(node_sum)(ax);
  sums[1] += SN(node_sum)(ay);
  sums[2] += SN(node_sum)(az);
  sums[3] += SN(node_sum)(at);
}

static void SN(arcs)(const ArcShared* A, const double lo[4], const double hi[4],
                     double sums[4]) {
  int n1 = A->n == 1.0;
  for (int a = 0; a < 4; a++) {
    if (0.5*(hi[a] - lo[a]) == 0.0) continue;  // zero width: exactly zero terms in numpy
    if (n1) SN(arc)(A, lo[a], hi[a], 1, sums); else SN(arc)(A, lo[a], hi[a], 0, sums);
  }
}

#undef vd
#undef vm
#undef vu
#undef MAXV
#undef NQ
#undef VL
#undef SN
#undef SN_CAT
#undef SN_CAT2
