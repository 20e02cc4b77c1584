// linear_segment.cl — exact emission–absorption over one sub-segment on which extinction and colour
// vary linearly along the ray: the pre-integrated integrator's weights and their derivatives.
#ifndef IVR_LINEAR_SEGMENT_CL
#define IVR_LINEAR_SEGMENT_CL
#include "config.cl"
#include "rays.cl"

// A sub-segment of length L, extinction σ_s → σ_e and colour c_s → c_e linear along it, in
// optical-depth units a = σ_s·L ≥ 0, b = σ_e·L ≥ 0. E(x) = a·x + (b − a)·x²/2 is the depth from the
// start to fraction x, τ = E(1) = (a + b)/2; the transmittance is e^{−τ} and the emitted radiance
// (transmittance 1 at the start) c_s·P + c_e·Q, integrating ∫ e^{−E} σ c ds by parts:
//   P = ∫₀¹ (1 − e^{−E}) dx = ∫₀¹ y·E'·e^{−E} dx,
//   Q = ∫₀¹ (e^{−E} − e^{−τ}) dx = ∫₀¹ x·E'·e^{−E} dx,
// y = 1 − x, P + Q = 1 − e^{−τ}. As E' = a·y + b·x, both are sums of moments of e^{−E} with
// nonnegative weights, so no regime forms a difference of nearly equal numbers:
//   M_pq = ∫₀¹ x^p y^q e^{−E} dx,  P = a·M02 + b·M11,  Q = a·M11 + b·M20,
//   ∂P/∂a = ∫ e^{−E}(x − x²/2) = M11 + M20/2,  ∂P/∂b = ∫ e^{−E} x²/2 = M20/2,
//   ∂Q/∂a = e^{−τ}/2 − ∂P/∂a,  ∂Q/∂b = e^{−τ}/2 − ∂P/∂b.
// Nothing divides by (1 − α) or by anything that can be 0; every finite a, b ≥ 0 (subnormals and
// FLT_MAX included) gives finite P, Q ≥ 0 and finite partials.
//
// Regimes, by τ (f32 / f64). Transcendental calls: as listed, plus one exp for e^{−τ} in
// linear_segment outside the series regime. Cost per call, PoCL on a 2-core Xeon (AVX-512),
// scalar, median of 5 runs, against one decay_and_fraction (compositing.cl) at the same τ: that
// is ~1 ns below τ = 0.1 and ~9 ns above (one expf) in f32, ~55 ns (expm1 + exp) in f64.
//   τ ≤ 0.2 / 0.1   Taylor series of the three moments in (τ, d), d = (b − a)/2, to total degree
//                   5 / 8: 60 / 132 fused multiply-adds, no transcendental call.
//                   f32 12–15 ns (1.6x the exp branch, 13x the polynomial one); f64 23 ns (0.5x).
//   τ ≤ 24 / 13     one Gauss–Legendre rule over [0, 1] on the moments' integrands (entire
//                   functions), one exp per node, nodes by τ (ivr_gl_depth):
//                   f32 6 (τ ≤ 1) 86 ns 9x, 8 (≤ 2.8) 107 ns 12x, 12 (≤ 8.5) 146 ns 16x,
//                       16 (≤ 16) 189 ns 20x, 20 (≤ 24) 223 ns 25x;
//                   f64 8 (≤ 0.5) 110 ns 2.6x, 12 (≤ 2.9) 192 ns 3.8x, 16 (≤ 7) 258 ns 4.6x,
//                       20 (≤ 13) 297 ns 5.4x.
//   larger          20-node rules on [0, x(13)] (f64 only) and on to x(T), E(x(T)) = T = 24 / 42,
//                   x(·) by one sqrt each; beyond x(T) the integrand is below e^{−T} and every
//                   moment's rest below 1e-8 / 1e-14 of it (worst case τ just above T with b = 0,
//                   where E flattens). f32 20 exp, 250 ns 28x; f64 40 exp, 620 ns 11x.
// Each rule is used only up to a depth where its error is ~5e-8 (f32) / 3e-14 (f64) (the second
// f64 piece, depth ≤ 29, carries a weight below e^{−13}), so switching regime leaves no jump above
// that: tests/render/linear_segment_test.cpp checks values astride each switch, and f64 central
// differences across them.
// Accuracy, measured on PoCL against a long-double adaptive Gauss–Kronrod quadrature of the
// defining integrals on 26364 (a, b) from a log grid (16 per decade) over [1e-6, 1e4] with 0 and
// τ astride each switch, each relative to itself (∂Q/∂· relative to max(|∂Q/∂·|, e^{−τ}/2), as it
// crosses zero where e^{−τ}/2 and ∂P/∂· cancel):
//   f32: P 4.1e-7, Q 3.9e-7, ∂P/∂a 4.0e-7, ∂P/∂b 4.0e-7, ∂Q/∂a 4.1e-7, ∂Q/∂b 4.9e-7;
//   f64: P 6.2e-15, Q 1.1e-14, ∂P/∂a 6.1e-15, ∂P/∂b 1.7e-14, ∂Q/∂a 7.9e-15, ∂Q/∂b 1.7e-14.
// Rounding (e.g. of E ≤ T inside exp) dominates f32; the truncation of rules and series is below
// 5e-8 there.

// One ray's values, or a packet's (kernels/rays.cl): each lane takes its own regime, so a packet
// computes each regime some lane needs, and every lane gets what one ray gets.
typedef struct {
  vreal p, q;
  vreal dp_da, dp_db, dq_da, dq_db;
} LinearSegment;

#if IVR_F64
#define IVR_R(x) x
#define IVR_PI_SERIES 0.1  // series below this τ, to total degree IVR_PI_DEGREE
#define IVR_PI_DEGREE 8    // truncation < 1e-15 relative at τ = 0.1
#define IVR_PI_DECAY 11    // e^{−τ} by its Taylor polynomial of this degree in the series regime
#define IVR_PI_RULE0 1     // the smallest rule used: 8 nodes (6 are too few above τ = 0.1)
#define IVR_PI_TOP 13.0    // one rule up to this depth, then pieces
#define IVR_PI_CUT 42.0    // the depth T where the moments are cut
#else
#define IVR_R(x) x##f
#define IVR_PI_SERIES 0.2f
#define IVR_PI_DEGREE 5  // truncation < 1e-7 relative at τ = 0.2
#define IVR_PI_DECAY 7
#define IVR_PI_RULE0 0  // 6 nodes
#define IVR_PI_TOP 24.0f
#define IVR_PI_CUT 24.0f  // = IVR_PI_TOP: one piece
#endif

// Gauss–Legendre rules on [0, 1] with 6, 8, 12, 16 and 20 nodes, as mirrored pairs (s, 1 − s)
// with their weight; rule k is entries ivr_gl_first[k] .. ivr_gl_first[k + 1] − 1. A rule
// integrates depth ≤ ivr_gl_depth[k] to ~5e-8 (f32) / 3e-14 (f64) relative for every shape of
// E (measured; the worst shape is a = 2τ, b = 0).
__constant int ivr_gl_first[6] = {0, 3, 7, 13, 21, 31};
#if IVR_F64
__constant real ivr_gl_depth[5] = {0.08, 0.5, 2.9, 7.0, 13.0};
#else
__constant real ivr_gl_depth[5] = {1.0f, 2.8f, 8.5f, 16.0f, 24.0f};
#endif
__constant real ivr_gl_nodes[31] = {
    IVR_R(3.376524289842398608404e-02), IVR_R(1.693953067668677431562e-01),
    IVR_R(3.806904069584015456919e-01), IVR_R(1.985507175123188416954e-02),
    IVR_R(1.016667612931866301895e-01), IVR_R(2.372337950418355070848e-01),
    IVR_R(4.082826787521750975184e-01), IVR_R(9.219682876640374643955e-03),
    IVR_R(4.794137181476257165915e-02), IVR_R(1.150486629028476564705e-01),
    IVR_R(2.063410228566912763438e-01), IVR_R(3.160842505009099031080e-01),
    IVR_R(4.373832957442655422747e-01), IVR_R(5.299532504175033699326e-03),
    IVR_R(2.771248846338371195483e-02), IVR_R(6.718439880608412806688e-02),
    IVR_R(1.222977958224984830547e-01), IVR_R(1.910618777986781257738e-01),
    IVR_R(2.709916111713863068116e-01), IVR_R(3.591982246103705433710e-01),
    IVR_R(4.524937450811812799062e-01), IVR_R(3.435700407452537612045e-03),
    IVR_R(1.801403636104310435669e-02), IVR_R(4.388278587433704707138e-02),
    IVR_R(8.044151408889058829004e-02), IVR_R(1.268340467699246036832e-01),
    IVR_R(1.819731596367424872665e-01), IVR_R(2.445664990245864510074e-01),
    IVR_R(3.131469556422902196556e-01), IVR_R(3.861070744291774609687e-01),
    IVR_R(4.617367394332513331210e-01)};
__constant real ivr_gl_weights[31] = {
    IVR_R(8.566224618958517245354e-02), IVR_R(1.803807865240693037709e-01),
    IVR_R(2.339569672863455236943e-01), IVR_R(5.061426814518812961091e-02),
    IVR_R(1.111905172266872352999e-01), IVR_R(1.568533229389436436420e-01),
    IVR_R(1.813418916891809915014e-01), IVR_R(2.358766819325591360605e-02),
    IVR_R(5.346966299765921546284e-02), IVR_R(8.003916427167311312178e-02),
    IVR_R(1.015837133615329608647e-01), IVR_R(1.167462682691774043789e-01),
    IVR_R(1.245735229067013924962e-01), IVR_R(1.357622970587704740368e-02),
    IVR_R(3.112676196932394641783e-02), IVR_R(4.757925584124639241043e-02),
    IVR_R(6.231448562776693602449e-02), IVR_R(7.479799440828836604655e-02),
    IVR_R(8.457825969750126912563e-02), IVR_R(9.130170752246179443614e-02),
    IVR_R(9.472530522753424815050e-02), IVR_R(8.807003569576059160822e-03),
    IVR_R(2.030071490019347066093e-02), IVR_R(3.133602416705453175603e-02),
    IVR_R(4.163837078835237439706e-02), IVR_R(5.096505990862021753286e-02),
    IVR_R(5.909726598075920864486e-02), IVR_R(6.584431922458831345086e-02),
    IVR_R(7.104805465919102567678e-02), IVR_R(7.458649323630187338575e-02),
    IVR_R(7.637669356536292534929e-02)};

// The moments for small τ, m[p] = M_p(2−p). With E = τ·x − d·x·y (d = (b − a)/2, |d| ≤ τ),
// expanding e^{−E} = Σ (−τx)^i (d·xy)^j / (i! j!) and ∫₀¹ x^m y^n dx = m! n! / (m + n + 1)! gives
//   M_pq = Σ_{i,j} c_ij τ^i d^j,  c_ij = (−1)^i (i+j+p)! (j+q)! / (i! j! (i+2j+p+q+1)!),
// truncated at total degree i + j ≤ IVR_PI_DEGREE and evaluated by Horner in τ, then in d. All
// loops have constant trip counts (a condition cuts the triangle), so once unrolled the
// coefficients, built from c_00 = p! q! / 3! by ratios of small integers, fold into constants: one
// fused multiply-add per term, 3·(N + 1)(N + 2)/2 − 3 in all (PoCL's code has no division left;
// a compiler that did not unroll would compute the same values, only slower).
#define IVR_MOMENT_SERIES(NAME, N)                                                             \
  inline void NAME(vreal tau, vreal d, vreal* m) {                                             \
    _Pragma("unroll") for (int p = 0; p <= 2; ++p) {                                           \
      const int q = 2 - p;                                                                     \
      vreal g[N + 1];                                                                          \
      real c0 = p == 1 ? (real)1 / 6 : (real)1 / 3;                                            \
      _Pragma("unroll") for (int j = 0; j <= N; ++j) {                                         \
        real c[N + 1];                                                                         \
        c[0] = c0;                                                                             \
        _Pragma("unroll") for (int i = 1; i <= N; ++i) c[i] =                                  \
            c[i - 1] * (-(real)(i + j + p) / (real)(i * (i + 2 * j + 3)));                     \
        g[j] = (vreal)(c[N - j]);                                                              \
        _Pragma("unroll") for (int i = N - 1; i >= 0; --i) if (i < N - j) g[j] =               \
            g[j] * tau + c[i];                                                                 \
        c0 *= (real)((j + 1 + p) * (j + 1 + q)) / (real)((j + 1) * (2 * j + 4) * (2 * j + 5)); \
      }                                                                                        \
      m[p] = g[N];                                                                             \
      _Pragma("unroll") for (int j = N - 1; j >= 0; --j) m[p] = m[p] * d + g[j];               \
    }                                                                                          \
  }
// Lower degrees where τ is small enough for them (truncation below the stated accuracy).
#if IVR_F64
IVR_MOMENT_SERIES(ivr_moment_series_low, 4)
IVR_MOMENT_SERIES(ivr_moment_series_mid, 6)
#define IVR_PI_LOW 0.001
#define IVR_PI_MID 0.01
#else
IVR_MOMENT_SERIES(ivr_moment_series_low, 2)
IVR_MOMENT_SERIES(ivr_moment_series_mid, 3)
#define IVR_PI_LOW 0.008f
#define IVR_PI_MID 0.04f
#endif
IVR_MOMENT_SERIES(ivr_moment_series, IVR_PI_DEGREE)

// x in [0, 1] with E(x) = t, for 0 < t < τ: the root 2t / (a + √(a² + 2(b − a)t)), written without
// cancellation and scaled by max(a, b) (a² overflows float above 1.8e19). The radicand is ≥ b²
// for t ≤ τ; fmax and fmin keep its rounding from reaching a NaN or an x past 1.
inline vreal ivr_depth_to_x(vreal a, vreal b, real t) {
  const vreal m = fmax(a, b), as = a / m, ts = t / m;
  return fmin(2 * ts / (as + sqrt(fmax(as * as + 2 * (b / m - as) * ts, (real)0))), (real)1);
}

// One quadrature node: adds w·e^{−E(x)} times y², x·y, x² to the moment sums. E = x·(a·(1 + y)/2 +
// b·x/2) sums nonnegative terms that cannot overflow (a·(1 + y) can, near FLT_MAX). The exp is
// the marches' (kernels/rays.cl: float32's own, the same bits for one ray and a packet).
inline void ivr_gl_add(vreal a, vreal b, vreal x, vreal y, real w, vreal* m) {
  const vreal e = w * vexp(-x * (a * (IVR_R(0.5) + IVR_R(0.5) * y) + b * (IVR_R(0.5) * x)));
  m[0] += e * y * y;
  m[1] += e * x * y;
  m[2] += e * x * x;
}

// Adds the Gauss–Legendre rule k over [x0, x1] to P, Q, ∂P/∂a and ∂P/∂b. Nodes carry x and
// y = 1 − x, each formed without cancellation (y from the right end, 1 − x1 = 0 on the last
// piece). The moments are scaled by the piece length h only inside a·h, b·h: for a, b near
// FLT_MAX they lie near 1/a, a subnormal float, while a·h·M does not.
inline void ivr_gl_piece(vreal a, vreal b, vreal x0, vreal x1, int k, vreal* p, vreal* q,
                         vreal* dp_da, vreal* dp_db) {
  const vreal h = x1 - x0, y1 = 1 - x1;
  vreal m[3];  // M02, M11, M20 over the piece, in units of h
  m[0] = m[1] = m[2] = (vreal)(real)0;
  for (int i = ivr_gl_first[k]; i < ivr_gl_first[k + 1]; ++i) {
    const real s = ivr_gl_nodes[i], w = ivr_gl_weights[i];
    ivr_gl_add(a, b, x0 + h * s, y1 + h * (1 - s), w, m);
    ivr_gl_add(a, b, x0 + h * (1 - s), y1 + h * s, w, m);
  }
  *p += a * h * m[0] + b * h * m[1];
  *q += a * h * m[1] + b * h * m[2];
  *dp_da += h * (m[1] + IVR_R(0.5) * m[2]);
  *dp_db += h * (IVR_R(0.5) * m[2]);
}

// *to = from where m is true, for the four outputs.
#define IVR_PI_TAKE(m, p, q, dp_da, dp_db, tp, tq, ta, tb) \
  (*(p) = vsel(*(p), tp, m), *(q) = vsel(*(q), tq, m), *(dp_da) = vsel(*(dp_da), ta, m), \
   *(dp_db) = vsel(*(dp_db), tb, m))

// P, Q, ∂P/∂a, ∂P/∂b where `live` is true (elsewhere 0). One function for the render and
// the gradients, so that both get the same P and Q bit for bit; what a caller does not use is
// dead code after inlining.
inline void ivr_linear_segment(vreal a, vreal b, vint live, vreal* p, vreal* q, vreal* dp_da,
                               vreal* dp_db) {
  const vreal tau = IVR_R(0.5) * a + IVR_R(0.5) * b;  // (a + b)/2 overflows at FLT_MAX
  const vreal zero = (vreal)(real)0;
  *p = *q = *dp_da = *dp_db = zero;
  const vint series = live && vmask_of(tau <= IVR_PI_SERIES);
  if (vany(series)) {
    const vreal d = IVR_R(0.5) * b - IVR_R(0.5) * a;
    const vint low = series && vmask_of(tau <= IVR_PI_LOW);
    const vint mid = series && !low && vmask_of(tau <= IVR_PI_MID);
    const vint high = series && !low && !mid;
    vreal m[3], t[3];  // M02, M11, M20
    m[0] = m[1] = m[2] = zero;
    if (vany(low)) {
      ivr_moment_series_low(tau, d, t);
      for (int k = 0; k < 3; ++k) m[k] = vsel(m[k], t[k], low);
    }
    if (vany(mid)) {
      ivr_moment_series_mid(tau, d, t);
      for (int k = 0; k < 3; ++k) m[k] = vsel(m[k], t[k], mid);
    }
    if (vany(high)) {
      ivr_moment_series(tau, d, t);
      for (int k = 0; k < 3; ++k) m[k] = vsel(m[k], t[k], high);
    }
    IVR_PI_TAKE(series, p, q, dp_da, dp_db, a * m[0] + b * m[1], a * m[1] + b * m[2],
                m[1] + IVR_R(0.5) * m[2], IVR_R(0.5) * m[2]);
  }
  // One rule over [0, 1]: the smallest whose depth covers τ.
  vint left = live && !series && vmask_of(tau <= IVR_PI_TOP);
  for (int k = IVR_PI_RULE0; k <= 4 && vany(left); ++k) {
    const vint here = left && vmask_of(tau <= ivr_gl_depth[k]);
    left = left && !here;
    if (!vany(here)) continue;
    vreal tp = zero, tq = zero, ta = zero, tb = zero;
    ivr_gl_piece(a, b, zero, (vreal)(real)1, k, &tp, &tq, &ta, &tb);
    IVR_PI_TAKE(here, p, q, dp_da, dp_db, tp, tq, ta, tb);
  }
  // Deeper: the moments beyond depth T are negligible, so stop there.
  const vint top = live && !series && !vmask_of(tau <= IVR_PI_TOP);
  if (vany(top)) {
    vreal tp = zero, tq = zero, ta = zero, tb = zero;
    const vreal x1 = ivr_depth_to_x(a, b, IVR_PI_TOP);
    ivr_gl_piece(a, b, zero, x1, 4, &tp, &tq, &ta, &tb);
#if IVR_F64  // a second 20-node piece from depth 13 to min(τ, 42)
    ivr_gl_piece(a, b, x1,
                 vsel(ivr_depth_to_x(a, b, IVR_PI_CUT), (vreal)(real)1,
                      vmask_of(tau <= IVR_PI_CUT)),
                 4, &tp, &tq, &ta, &tb);
#endif
    IVR_PI_TAKE(top, p, q, dp_da, dp_db, tp, tq, ta, tb);
  }
}
#undef IVR_PI_TAKE

// P and Q only (the render), where `live` is true.
inline void linear_segment_pq(vreal a, vreal b, vint live, vreal* p, vreal* q) {
  vreal dp_da, dp_db;
  ivr_linear_segment(a, b, live, p, q, &dp_da, &dp_db);
}

// P, Q and their partials in a and b (the gradients), where `live` is true.
inline LinearSegment linear_segment_where(vreal a, vreal b, vint live) {
  LinearSegment s;
  ivr_linear_segment(a, b, live, &s.p, &s.q, &s.dp_da, &s.dp_db);
  const vreal tau = IVR_R(0.5) * a + IVR_R(0.5) * b;
  // e^{−τ}: its Taylor polynomial in the series regime (truncation < 1e-10 / 1e-20 relative),
  // the exp above.
  const vint series = vmask_of(tau <= IVR_PI_SERIES) || !live;
  vreal decay = (vreal)(real)1;
  if (vany(series)) {
#pragma unroll
    for (int k = IVR_PI_DECAY; k >= 1; --k) decay = 1 - tau * ((real)1 / k) * decay;
  }
  if (!vall(series)) decay = vsel(vexp(-tau), decay, series);
  s.dq_da = IVR_R(0.5) * decay - s.dp_da;
  s.dq_db = IVR_R(0.5) * decay - s.dp_db;
  return s;
}

inline LinearSegment linear_segment(vreal a, vreal b) {
  return linear_segment_where(a, b, vtrue);
}

#endif
