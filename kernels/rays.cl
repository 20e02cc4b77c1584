// rays.cl — IVR_RAYS rays marched together in vector lanes: the types and operations the marches
// are written in, so that one march serves one ray per work-item (IVR_RAYS 1: GPUs, where
// work-items are SIMD lanes already, and every gradient kernel) and a packet of neighbouring rays
// per work-item (IVR_RAYS 8 or 16: CPUs, where PoCL runs a work-item's loop as scalar code and
// cannot vectorise across work-items whose loops differ in length).
//
// vreal and vint hold one value per ray; a mask is a vint, nonzero where true (1 for one ray, −1
// for vectors, as OpenCL C's comparisons give): combine masks with && || ! (defined on vectors
// too, without short-circuit) and choose with vsel/vseli. Every operation is the scalar one lane
// by lane — +, −, ×, ÷, fma, fmin, fmax, conversions, and an exp of fused multiply-adds
// (kernels/exp.cl; float64: the scalar builtin lane by lane) — so a packet's image is the one-ray
// kernel's bit for bit.
#ifndef IVR_RAYS_CL
#define IVR_RAYS_CL
#include "config.cl"
#include "exp.cl"

#ifndef IVR_RAYS
#define IVR_RAYS 1
#endif

#if IVR_RAYS == 1
#define IVR_PERMUTE_ENTRIES 0
typedef real vreal;
typedef int vint;
#define vany(m) ((m) != 0)
#define vall(m) ((m) != 0)
#define vsel(a, b, m) ((m) ? (b) : (a))
#define vseli(a, b, m) ((m) ? (b) : (a))
#define vmask_of(c) ((vint)((c) ? 1 : 0))  // a comparison of vreal as a mask
#define vto_int(x) ((int)(x))              // truncation (x >= 0 where used: floor)
#define vto_real(i) ((real)(i))
typedef long vlong;
#define vto_long_rte(x) convert_long_rte(x)  // to the nearest integer, ties to even
#define vgather(p, i) ((p)[i])
#define vgather_off(p, base, off) (((p) + (base))[off])  // one base address, as a scalar loop has
#define vgather_flag(p, i) ((vint)((p)[i] ? 1 : 0))
#if IVR_F64
#define vexp(x) exp(x)
#else
#define vexp(x) ivr_expf(x)  // the packets' exp (kernels/exp.cl), so that both render alike
#endif
#define vexpm1(x) expm1(x)
#else

#if IVR_RAYS == 16
#define IVR_VN(t) t##16
#define IVR_VLOAD vload16
#define IVR_VSTORE vstore16
#define vto_int(x) convert_int16_rtz(x)
#define vto_long_rte(x) convert_long16_rte(x)
#elif IVR_RAYS == 8
#define IVR_VN(t) t##8
#define IVR_VLOAD vload8
#define IVR_VSTORE vstore8
#define vto_int(x) convert_int8_rtz(x)
#define vto_long_rte(x) convert_long8_rte(x)
#else
#error "IVR_RAYS must be 1, 8 or 16"
#endif

#if IVR_F64
typedef IVR_VN(double) vreal;
#define IVR_TO_INT(x) IVR_VN(convert_int)(x)
#define vmask_of(c) IVR_TO_INT(c)
#define vsel(a, b, m) select(a, b, IVR_VN(convert_long)(m))
#define vto_real(i) IVR_VN(convert_double)(i)
#else
typedef IVR_VN(float) vreal;
#define vmask_of(c) (c)
#define vsel(a, b, m) select(a, b, m)
#define vto_real(i) IVR_VN(convert_float)(i)
#endif
typedef IVR_VN(int) vint;
typedef IVR_VN(long) vlong;
// any() and all() as trees of lane-wise ORs and ANDs: PoCL's builtins test the lanes one after
// another with a branch each (16 compare-and-branch pairs per call, several calls per sample),
// where these are a few vector operations and one test of the sign bit.
inline int ivr_any8(int8 m) {
  const int4 b = m.lo | m.hi;
  const int2 c = b.lo | b.hi;
  return (c.x | c.y) < 0;
}
inline int ivr_all8(int8 m) {
  const int4 b = m.lo & m.hi;
  const int2 c = b.lo & b.hi;
  return (c.x & c.y) < 0;
}
#if IVR_RAYS == 16
inline int vany(vint m) {
  return ivr_any8(m.lo | m.hi);
}
inline int vall(vint m) {
  return ivr_all8(m.lo & m.hi);
}
#else
inline int vany(vint m) {
  return ivr_any8(m);
}
inline int vall(vint m) {
  return ivr_all8(m);
}
#endif
#define vseli(a, b, m) select(a, b, m)

// The lanes' values of p[i] (OpenCL C has no gather): one vector built from the lanes' loads, as
// the compiler turns into inserts (through a private array it would go through the stack).
#if IVR_RAYS == 16
#define IVR_GATHER_LANES(p, i, f)                                                                 \
  f(p[i.s0]), f(p[i.s1]), f(p[i.s2]), f(p[i.s3]), f(p[i.s4]), f(p[i.s5]), f(p[i.s6]), f(p[i.s7]), \
      f(p[i.s8]), f(p[i.s9]), f(p[i.sa]), f(p[i.sb]), f(p[i.sc]), f(p[i.sd]), f(p[i.se]),         \
      f(p[i.sf])
#else
#define IVR_GATHER_LANES(p, i, f) \
  f(p[i.s0]), f(p[i.s1]), f(p[i.s2]), f(p[i.s3]), f(p[i.s4]), f(p[i.s5]), f(p[i.s6]), f(p[i.s7])
#endif
#define IVR_AS_IS(x) (x)
#define IVR_AS_FLAG(x) ((x) ? -1 : 0)
inline vreal vgather(__global const real* restrict p, vint i) {
  return (vreal)(IVR_GATHER_LANES(p, i, IVR_AS_IS));
}
#define vgather_off(p, base, off) vgather(p, (base) + (off))
#if !IVR_F64 && defined(__ENDIAN_LITTLE__)
// Two neighbours of every lane, lo = p[i] and hi = p[i + 1], from one 64-bit load per lane where
// `edge` is false (a float32 gather loads each lane's element through the load ports one by one:
// the pairs halve them, and the trilinear samples' 8 gathers of 16 become 8 of 8); where `edge`
// is true (the clamped upper edge, where a cell's +x corner is the voxel itself) from p[i − 1]
// and p[i], both p[i]. The caller keeps i − 1 inside the array where `edge` holds. (The first of
// a pair is the low half of its 64 bits: little-endian devices only.)
#define IVR_PAIR(k) as_ulong(vload2(0, p + b.s##k))
inline void vgather_pair(__global const real* restrict p, vint i, vint edge, vreal* lo, vreal* hi) {
  const vint b = i + edge;  // −1 where `edge` holds
#if IVR_RAYS == 16
  const ulong16 w =
      (ulong16)(IVR_PAIR(0), IVR_PAIR(1), IVR_PAIR(2), IVR_PAIR(3), IVR_PAIR(4), IVR_PAIR(5),
                IVR_PAIR(6), IVR_PAIR(7), IVR_PAIR(8), IVR_PAIR(9), IVR_PAIR(a), IVR_PAIR(b),
                IVR_PAIR(c), IVR_PAIR(d), IVR_PAIR(e), IVR_PAIR(f));
  const vreal first = as_float16(convert_uint16(w)), second = as_float16(convert_uint16(w >> 32));
#else
  const ulong8 w = (ulong8)(IVR_PAIR(0), IVR_PAIR(1), IVR_PAIR(2), IVR_PAIR(3), IVR_PAIR(4),
                            IVR_PAIR(5), IVR_PAIR(6), IVR_PAIR(7));
  const vreal first = as_float8(convert_uint8(w)), second = as_float8(convert_uint8(w >> 32));
#endif
  *hi = second;
  *lo = vsel(first, second, edge);
}
#undef IVR_PAIR
#define IVR_GATHER_PAIRS 1
#endif
// vpermute(table, k): entry k of `table` (a vreal holding up to IVR_PERMUTE_ENTRIES values) in
// every lane, one instruction (vpermps, vpermpd) where the compiler targets AVX-512 or AVX2
// (Clang's x86 builtins, which PoCL's compiler has for such CPUs; OpenCL's shuffle() compiles to a
// loop through memory there). IVR_PERMUTE_ENTRIES is 0 where there is none: the callers then take
// another way (and so does -DIVR_NO_PERMUTE in IVR_BUILD_OPTIONS, to compare them).
#if defined(IVR_NO_PERMUTE)
#define IVR_PERMUTE_ENTRIES 0
#elif IVR_RAYS == 16 && !IVR_F64 && defined(__AVX512F__)
#define IVR_PERMUTE_ENTRIES 16
#define vpermute(t, k) __builtin_ia32_permvarsf512(t, k)
#elif IVR_RAYS == 8 && !IVR_F64 && defined(__AVX2__)
#define IVR_PERMUTE_ENTRIES 8
#define vpermute(t, k) __builtin_ia32_permvarsf256(t, k)
#elif IVR_RAYS == 8 && IVR_F64 && defined(__AVX512F__)
#define IVR_PERMUTE_ENTRIES 8
#define vpermute(t, k) __builtin_ia32_permvardf512(t, convert_long8(k))
#else
#define IVR_PERMUTE_ENTRIES 0
#endif

// The same of a byte array, as a mask (the occupancy grid: nonzero where occupied).
inline vint vgather_flag(__global const uchar* restrict p, vint i) {
  return (vint)(IVR_GATHER_LANES(p, i, IVR_AS_FLAG));
}

// A scalar function of every lane: float64's exp and expm1 (the one-ray kernels' builtins, whose
// vector forms may round differently in the last bit; float64 packets are rare). float32's exp is
// kernels/exp.cl's, the same bits in every width.
#define IVR_PER_LANE(name, f)                          \
  inline vreal name(vreal x) {                         \
    real v[IVR_RAYS];                                  \
    IVR_VSTORE(x, 0, v);                               \
    for (int l = 0; l < IVR_RAYS; ++l) v[l] = f(v[l]); \
    return IVR_VLOAD(0, v);                            \
  }
#if IVR_F64
IVR_PER_LANE(vexp, exp)
#elif IVR_RAYS == 16
#define vexp(x) ivr_expf16(x)
#else
#define vexp(x) ivr_expf8(x)
#endif
IVR_PER_LANE(vexpm1, expm1)
#undef IVR_PER_LANE
#endif

// A packet's pixels: a tile of IVR_PACKET_W columns by IVR_PACKET_H rows of the image, lane l at
// column IVR_LANE_X(l), row IVR_LANE_Y(l) from the tile's corner. A square tile rather than a run
// of one row: its rays stay closer together, so a sample's gathers touch fewer cache lines and its
// rays' lengths differ less (fewer idle lanes); 7 % faster than 16×1 at 128³ → 256² on PoCL.
// The host launches one work-item per tile (lib/render/render.cpp, packet_shape).
// A ray list's "image" is one row (pixel x is ray x): its packets are runs of IVR_RAYS rays.
#if IVR_RAY_LIST
#define IVR_PACKET_W IVR_RAYS
#elif IVR_RAYS == 16
#define IVR_PACKET_W 4
#elif IVR_RAYS == 8
#define IVR_PACKET_W 4
#else
#define IVR_PACKET_W 1
#endif
#define IVR_PACKET_H (IVR_RAYS / IVR_PACKET_W)
#define IVR_LANE_X(l) ((l) % IVR_PACKET_W)
#define IVR_LANE_Y(l) ((l) / IVR_PACKET_W)

// A value per ray into the array v[0 .. IVR_RAYS), and one per ray from it.
#if IVR_RAYS == 1
#define IVR_STORE_RAYS(x, v) ((v)[0] = (x))
#define IVR_LOAD_RAYS(v) ((v)[0])
#else
#define IVR_STORE_RAYS(x, v) IVR_VSTORE(x, 0, v)
#define IVR_LOAD_RAYS(v) IVR_VLOAD(0, v)
#endif

// A mask true in every lane.
#if IVR_RAYS == 1
#define vtrue ((vint)1)
#else
#define vtrue ((vint)-1)
#endif

// 1 where a mask is true, else 0: what a lane adds to a count.
#define vcount(m) vseli((vint)0, (vint)1, (m))

// x clamped to [lo, hi] by two selects: fmin(fmax(…)) keeps IEEE's NaN rule (the other operand),
// which x86 compiles to a compare, a mask operation and a blend around each min and max; here NaN
// gives lo, as fmax(NaN, lo) does, and every number the same value.
inline vreal vclamp(vreal x, real lo, real hi) {
  const vreal above = vsel((vreal)lo, x, vmask_of(x > (vreal)lo));
  return vsel((vreal)hi, above, vmask_of(above < (vreal)hi));
}

// lerp() of config.cl in every lane.
inline vreal vlerp(vreal a, vreal b, vreal t) {
  return a + (b - a) * t;
}

#endif
