// Eight-lane vectors for the per-pixel kernels, and the run-time choice of instruction set.
//
// A kernel is written once, as an always-inline function over these GCC/Clang vector types, and
// instantiated per instruction set: on x86-64 inside a function compiled for AVX2 (one 256-bit
// instruction per operation) and inside a plain x86-64 function (two SSE2 instructions); on any
// other machine (aarch64: two NEON instructions) only the latter, for the build's own target.
// Every operation is an IEEE single operation per lane (no FMA contraction: the build passes
// -ffp-contract=off and the AVX2 target excludes FMA), so all produce identical bits; the test
// suite checks that. Only inlined code takes the target: nothing outside the kernel is compiled
// for AVX2, so no out-of-line copy of a shared inline function can leak AVX2 instructions into
// the generic path. x86-only code is guarded by SR_X86.
#pragma once

#include <cstdint>
#include <cstring>

#if defined(__x86_64__) || defined(__i386__)
#define SR_X86 1
#include <emmintrin.h>
#define SR_TARGET_AVX2 __attribute__((target("avx2")))
#else
#define SR_X86 0
#endif

#define SR_INLINE inline __attribute__((always_inline))

namespace sr {

enum class Isa : uint8_t { Generic, Avx2 };

// The best instruction set this CPU runs, and the best one the build has kernels for.
Isa best_isa();
#if SR_X86
constexpr Isa kBestIsa = Isa::Avx2;
#else
constexpr Isa kBestIsa = Isa::Generic;
#endif
const char* isa_name(Isa isa);

namespace simd {

constexpr int kLanes = 8;
typedef float f8 __attribute__((vector_size(32)));
typedef int32_t i8 __attribute__((vector_size(32)));
typedef double d4 __attribute__((vector_size(32)));
typedef float f4 __attribute__((vector_size(16)));
typedef int32_t i4 __attribute__((vector_size(16)));

template <typename V, typename T>
SR_INLINE V load(const T* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <typename V, typename T>
SR_INLINE void store(T* p, V v) {
  std::memcpy(p, &v, sizeof v);
}
// Four values at p and four at p + stride as one vector (lanes 0-3, 4-7), and back.
template <typename V, typename T>
SR_INLINE V load_pair(const T* p, int stride) {
  typedef T half __attribute__((vector_size(sizeof(V) / 2)));
  const half lo = load<half>(p), hi = load<half>(p + stride);
  return V(__builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7));
}
template <typename V, typename T>
SR_INLINE void store_pair(T* p, int stride, V v) {
  store(p, __builtin_shufflevector(v, v, 0, 1, 2, 3));
  store(p + stride, __builtin_shufflevector(v, v, 4, 5, 6, 7));
}
// Broadcasts written as loops: GCC turns them into one vpbroadcast (an initializer list or
// `f8{} + v` became a chain of inserts).
template <typename V, typename T>
SR_INLINE V broadcast(T v) {
  V r;
  for (int k = 0; k < int(sizeof(V) / sizeof(T)); ++k) r[k] = v;
  return r;
}
SR_INLINE f8 splat(float v) { return broadcast<f8>(v); }
SR_INLINE i8 splat(int32_t v) { return broadcast<i8>(v); }
SR_INLINE f8 to_float(i8 v) { return __builtin_convertvector(v, f8); }
SR_INLINE i8 lane_index() { return i8{0, 1, 2, 3, 4, 5, 6, 7}; }

// Eight xyz triples (24 floats from p) as the vectors of their x, y and z: contiguous loads and
// shuffles (gathers are slow here).
SR_INLINE void load_xyz8(const float* p, f8& x, f8& y, f8& z) {
  const f8 a = load<f8>(p), b = load<f8>(p + 8), c = load<f8>(p + 16);
  const f8 ab_x = __builtin_shufflevector(a, b, 0, 3, 6, 9, 12, 15, 0, 0);
  const f8 ab_y = __builtin_shufflevector(a, b, 1, 4, 7, 10, 13, 0, 0, 0);
  const f8 ab_z = __builtin_shufflevector(a, b, 2, 5, 8, 11, 14, 0, 0, 0);
  x = __builtin_shufflevector(ab_x, c, 0, 1, 2, 3, 4, 5, 10, 13);
  y = __builtin_shufflevector(ab_y, c, 0, 1, 2, 3, 4, 8, 11, 14);
  z = __builtin_shufflevector(ab_z, c, 0, 1, 2, 3, 4, 9, 12, 15);
}

// True if any lane of the mask (all-ones or zero per lane) is set.
SR_INLINE bool any(i8 mask) {
  const i4 lo = __builtin_shufflevector(mask, mask, 0, 1, 2, 3);
  const i4 hi = __builtin_shufflevector(mask, mask, 4, 5, 6, 7);
#if SR_X86
  return _mm_movemask_epi8(__m128i(lo | hi)) != 0;
#else
  const i4 v = lo | hi;
  return (v[0] | v[1] | v[2] | v[3]) != 0;
#endif
}

// True if every lane of the mask is set.
SR_INLINE bool all(i8 mask) {
  const i4 lo = __builtin_shufflevector(mask, mask, 0, 1, 2, 3);
  const i4 hi = __builtin_shufflevector(mask, mask, 4, 5, 6, 7);
#if SR_X86
  return _mm_movemask_epi8(__m128i(lo & hi)) == 0xffff;
#else
  const i4 v = lo & hi;
  return (v[0] & v[1] & v[2] & v[3]) == -1;
#endif
}

// Correctly rounded square root per lane (as std::sqrt). Lane by lane, so that the compiler picks
// the widest instruction the function's target has (one vsqrtps ymm for AVX2, two sqrtps for
// SSE2); needs -fno-math-errno, else each lane may call sqrtf.
SR_INLINE f8 sqrt(f8 v) {
  f8 r;
  for (int i = 0; i < 8; ++i) r[i] = __builtin_sqrtf(v[i]);
  return r;
}

SR_INLINE d4 sqrt(d4 v) {
  d4 r;
  for (int i = 0; i < 4; ++i) r[i] = __builtin_sqrt(v[i]);
  return r;
}

// Two times four integer-valued doubles to eight floats (each rounded once, to nearest).
SR_INLINE f8 to_float(d4 lo, d4 hi) {
  const f4 a = __builtin_convertvector(lo, f4), b = __builtin_convertvector(hi, f4);
  return __builtin_shufflevector(a, b, 0, 1, 2, 3, 4, 5, 6, 7);
}

}  // namespace simd
}  // namespace sr
