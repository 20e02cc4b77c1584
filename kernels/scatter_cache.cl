// scatter_cache.cl — a work-group's local table that sums the scatter kernels' adds per voxel.
//
// Why: the scatter kernels (the adjoint's density gradient, kernels/adjoint.cl; the back-projector,
// kernels/project.cl) run one work-item per ray, and a work-group is a tile of neighbouring pixels
// of one view, whose rays cross largely the same voxels. Each ray already adds to a voxel once
// (its cell cache), but a tile still makes several global atomic adds to most voxels it touches
// (7 on average for 8x8 rays at 256² from 128³) where one would do; on a GPU those contend in
// L2, while local atomics stay in the multiprocessor. Here the tile's adds meet in an
// open-addressing table in local memory (key: the voxel index, value: the sum so far), and what it
// holds goes to global memory when the group ends, one add per voxel.
//
// The table is far smaller than the voxels a tile crosses (~5,000 at 128³ → 256², against 1,024
// slots), so what happens when it is full decides what it saves. Two layouts:
// - packed (float32, where the compiler has cl_khr_int64_base_atomics): a slot is one 64-bit
//   word, the key in its high half and the float sum's bits in its low half, so one
//   compare-and-swap changes both. A voxel that finds the slots near its hash taken by others
//   takes its home slot, and the sum that slot held goes to global memory (eviction): the table
//   follows the rays, holding the voxels they are at rather than the first they met.
// - keyed (float64; float32 without 64-bit atomics): a key array, claimed by compare-and-swap,
//   beside a value array. A key and a double cannot change in one atomic, so nothing is evicted:
//   once the slots near a voxel's hash are taken, its adds go to global memory directly.
// Either way every add reaches global memory exactly once, through the table or not. A simulation
// of 8x8 rays in lockstep (one add each per step; 128³ → 256² from a corner) leaves 0.20 of the
// global adds with the packed table, 0.78 with the keyed one, 0.135 the floor (one per voxel).
//
// IVR_SCATTER_CACHE (the host's, lib/adjoint/scatter_cache.hpp; $IVR_SCATTER_CACHE forces it) turns
// the table on; off, scatter_add() is the plain global atomic add and nothing here takes memory or
// a barrier. Float sums in the table change the order of the additions (results agree to rounding);
// the deterministic fixed-point gradient does not use the table (its integer adds are
// kernels/adjoint_scatter.cl's).
#ifndef IVR_SCATTER_CACHE_CL
#define IVR_SCATTER_CACHE_CL
#include "atomics.cl"
#include "config.cl"

#ifndef IVR_SCATTER_CACHE
#define IVR_SCATTER_CACHE 0
#endif
#ifndef IVR_SCATTER_SLOTS  // lib/adjoint/scatter_cache.cpp's kScatterSlots
#define IVR_SCATTER_SLOTS 1024
#endif
#if IVR_SCATTER_CACHE && (IVR_SCATTER_SLOTS < 1 || (IVR_SCATTER_SLOTS & (IVR_SCATTER_SLOTS - 1)))
#error IVR_SCATTER_SLOTS must be a power of two
#endif
// Slots looked at from a voxel's hash on: enough to get past a few collisions in a table that is
// filling, few enough that a full table costs a voxel only a handful of local reads.
#ifndef IVR_SCATTER_PROBES
#define IVR_SCATTER_PROBES 8
#endif
#define IVR_SCATTER_EMPTY (-1)

// -DIVR_SCATTER_KEYED (IVR_BUILD_OPTIONS) takes the keyed layout in float32 too: to compare them.
#if IVR_SCATTER_CACHE && !IVR_F64 && defined(cl_khr_int64_base_atomics) && \
    !defined(IVR_SCATTER_KEYED)
#pragma OPENCL EXTENSION cl_khr_int64_base_atomics : enable
#define IVR_SCATTER_PACKED 1
#else
#define IVR_SCATTER_PACKED 0
#endif
// The layout follows the compiler's extension macro, which no label shows: building with
// -DIVR_SCATTER_REQUIRE_PACKED (IVR_BUILD_OPTIONS) makes a float32 table that is not packed an
// error, to check a device before timing it.
#if defined(IVR_SCATTER_REQUIRE_PACKED) && IVR_SCATTER_CACHE && !IVR_F64 && !IVR_SCATTER_PACKED
#error the scatter cache's table is not packed: no cl_khr_int64_base_atomics in this compiler
#endif

// Where a scatter kernel's adds go: the global array and, with the cache, the group's table.
typedef struct {
  __global real* out;
#if IVR_SCATTER_PACKED
  volatile __local ulong* slots;  // (key << 32) | sum's bits; key IVR_SCATTER_EMPTY where free
#elif IVR_SCATTER_CACHE
  volatile __local int* keys;     // voxel index, IVR_SCATTER_EMPTY where free
  volatile __local real* values;  // the sum of the group's adds to it
#endif
} ScatterSink;

inline int scatter_local_id(void) {
  return (get_local_id(2) * get_local_size(1) + get_local_id(1)) * get_local_size(0) +
         get_local_id(0);
}
inline int scatter_local_size(void) {
  return get_local_size(0) * get_local_size(1) * get_local_size(2);
}

// A voxel's home slot. Fibonacci hashing, the product's high bits: neighbouring voxels (index ±
// 1, ± nx, ± nx·ny) land far apart, whatever the grid (the low bits of an index repeat by row).
inline uint scatter_home(const int index) {
  return mul_hi((uint)index * 0x9E3779B1u, (uint)IVR_SCATTER_SLOTS);
}

#if IVR_SCATTER_PACKED
inline ulong scatter_word(const int key, const float sum) {
  return ((ulong)(uint)key << 32) | (ulong)as_uint(sum);
}
inline int scatter_key(const ulong word) {
  return (int)(uint)(word >> 32);
}
inline float scatter_sum(const ulong word) {
  return as_float((uint)word);
}
#endif

#if IVR_SCATTER_CACHE
// Empties the table; every work-item of the group calls it, before any adds (it ends in a
// barrier).
#if IVR_SCATTER_PACKED
inline ScatterSink scatter_begin(__global real* out, __local ulong* slots) {
  ScatterSink s;
  s.out = out;
  s.slots = slots;
  const int lsize = scatter_local_size();
  for (int i = scatter_local_id(); i < IVR_SCATTER_SLOTS; i += lsize)
    slots[i] = scatter_word(IVR_SCATTER_EMPTY, 0.0f);
  barrier(CLK_LOCAL_MEM_FENCE);
  return s;
}
#else
inline ScatterSink scatter_begin(__global real* out, __local int* keys, __local real* values) {
  ScatterSink s;
  s.out = out;
  s.keys = keys;
  s.values = values;
  const int lsize = scatter_local_size();
  for (int i = scatter_local_id(); i < IVR_SCATTER_SLOTS; i += lsize) {
    keys[i] = IVR_SCATTER_EMPTY;
    values[i] = (real)0;
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  return s;
}
#endif
#endif

// The table lives at the kernel's outermost scope (where OpenCL C allows __local variables); the
// sink `name` is declared with it. Every work-item must reach this line, padding items included.
#if IVR_SCATTER_PACKED
#define IVR_SCATTER_SINK(name, out)              \
  __local ulong name##_slots[IVR_SCATTER_SLOTS]; \
  const ScatterSink name = scatter_begin(out, name##_slots)
#elif IVR_SCATTER_CACHE
#define IVR_SCATTER_SINK(name, out)              \
  __local int name##_keys[IVR_SCATTER_SLOTS];    \
  __local real name##_values[IVR_SCATTER_SLOTS]; \
  const ScatterSink name = scatter_begin(out, name##_keys, name##_values)
#else
#define IVR_SCATTER_SINK(name, out) const ScatterSink name = {out}
#endif

// out[index] += v, through the table where the voxel has (or can get) a slot there; with
// IVR_PRIVATE_SUMS `out` is the work-group's own copy (kernels/private_sums.cl): a plain add.
inline void scatter_add(const ScatterSink s, const int index, const real v) {
#if defined(IVR_PRIVATE_SUMS) && IVR_PRIVATE_SUMS
  s.out[index] += v;
#elif IVR_SCATTER_PACKED
  const uint home = scatter_home(index);
  uint slot = home;
  for (int probe = 0; probe < IVR_SCATTER_PROBES; ++probe) {
    ulong word = s.slots[slot];
    for (;;) {
      const int key = scatter_key(word);
      if (key != index && key != IVR_SCATTER_EMPTY) break;  // another voxel's: the next slot
      const float sum = (key == index ? scatter_sum(word) : 0.0f) + v;
      const ulong seen = atom_cmpxchg(s.slots + slot, word, scatter_word(index, sum));
      if (seen == word) return;
      word = seen;  // changed meanwhile (an add, a claim, an eviction): look again
    }
    slot = (slot + 1) & (IVR_SCATTER_SLOTS - 1);
  }
  // Every slot looked at holds another voxel: this one takes its home slot, and what that slot
  // held goes to global memory. (Two items may so place one voxel in two slots: each sum still
  // reaches global memory once.)
  const ulong old = atom_xchg(s.slots + home, scatter_word(index, v));
  if (scatter_key(old) != IVR_SCATTER_EMPTY)
    atomic_add_global(s.out + scatter_key(old), scatter_sum(old));
#elif IVR_SCATTER_CACHE
  uint slot = scatter_home(index);
  for (int probe = 0; probe < IVR_SCATTER_PROBES; ++probe) {
    int key = s.keys[slot];
    // Claim a free slot; the old key comes back: EMPTY if this item claimed it, `index` if
    // another item claimed it for the same voxel meanwhile.
    if (key == IVR_SCATTER_EMPTY) key = atomic_cmpxchg(s.keys + slot, IVR_SCATTER_EMPTY, index);
    if (key == IVR_SCATTER_EMPTY || key == index) {
      atomic_add_local(s.values + slot, v);  // zeroed by scatter_begin(), before the barrier
      return;
    }
    slot = (slot + 1) & (IVR_SCATTER_SLOTS - 1);
  }
  atomic_add_global(s.out + index, v);  // the slots near its hash are taken: not aggregated
#else
  atomic_add_global(s.out + index, v);
#endif
}

// The group's sums to global memory, one add per slot, the work-items striding over the slots.
// Every work-item calls it once its adds are done (it begins with a barrier).
inline void scatter_flush(const ScatterSink s) {
#if IVR_SCATTER_CACHE
  barrier(CLK_LOCAL_MEM_FENCE);
  const int lsize = scatter_local_size();
  for (int i = scatter_local_id(); i < IVR_SCATTER_SLOTS; i += lsize) {
#if IVR_SCATTER_PACKED
    const ulong word = s.slots[i];
    const int key = scatter_key(word);
    const real v = scatter_sum(word);
#else
    const int key = s.keys[i];
    const real v = s.values[i];
#endif
    if (key != IVR_SCATTER_EMPTY && v != (real)0) atomic_add_global(s.out + key, v);
  }
#else
  (void)s;
#endif
}

#endif
