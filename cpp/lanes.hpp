// Lane helpers of the vertex and setup passes (eight records at a time): lane masks as bits,
// an 8x8 transpose between records and fields, selects, and widening to double.
#pragma once

#include "simd.hpp"

#if SR_X86
#include <immintrin.h>
#endif

namespace sr {
namespace simd {

typedef int64_t l4 __attribute__((vector_size(32)));
typedef uint32_t u8 __attribute__((vector_size(32)));

SR_INLINE i8 float_bits(f8 v) { return i8(v); }
SR_INLINE f4 low_half(f8 v) { return __builtin_shufflevector(v, v, 0, 1, 2, 3); }
SR_INLINE f4 high_half(f8 v) { return __builtin_shufflevector(v, v, 4, 5, 6, 7); }
// A lane mask (all-ones or zero per lane) as one bit per lane.
#if SR_X86
SR_INLINE unsigned mask_bits(i8 mask) {
  const i4 lo = __builtin_shufflevector(mask, mask, 0, 1, 2, 3);
  const i4 hi = __builtin_shufflevector(mask, mask, 4, 5, 6, 7);
  return unsigned(_mm_movemask_ps(__m128(lo)) | _mm_movemask_ps(__m128(hi)) << 4);
}
SR_INLINE unsigned mask_bits(l4 mask) {
  const __m128d lo = __m128d(__builtin_shufflevector(mask, mask, 0, 1));
  const __m128d hi = __m128d(__builtin_shufflevector(mask, mask, 2, 3));
  return unsigned(_mm_movemask_pd(lo) | _mm_movemask_pd(hi) << 2);
}
#else  // each lane's sign bit, as movemask gives it
SR_INLINE unsigned mask_bits(i8 mask) {
  unsigned bits = 0;
  for (int i = 0; i < 8; ++i) bits |= unsigned(mask[i] < 0) << i;
  return bits;
}
SR_INLINE unsigned mask_bits(l4 mask) {
  unsigned bits = 0;
  for (int i = 0; i < 4; ++i) bits |= unsigned(mask[i] < 0) << i;
  return bits;
}
#endif

// Eight rows of eight 32-bit words become eight columns (records <-> fields).
SR_INLINE void transpose8(i8 (&r)[8]) {
  const i8 t0 = __builtin_shufflevector(r[0], r[1], 0, 8, 1, 9, 4, 12, 5, 13);
  const i8 t1 = __builtin_shufflevector(r[0], r[1], 2, 10, 3, 11, 6, 14, 7, 15);
  const i8 t2 = __builtin_shufflevector(r[2], r[3], 0, 8, 1, 9, 4, 12, 5, 13);
  const i8 t3 = __builtin_shufflevector(r[2], r[3], 2, 10, 3, 11, 6, 14, 7, 15);
  const i8 t4 = __builtin_shufflevector(r[4], r[5], 0, 8, 1, 9, 4, 12, 5, 13);
  const i8 t5 = __builtin_shufflevector(r[4], r[5], 2, 10, 3, 11, 6, 14, 7, 15);
  const i8 t6 = __builtin_shufflevector(r[6], r[7], 0, 8, 1, 9, 4, 12, 5, 13);
  const i8 t7 = __builtin_shufflevector(r[6], r[7], 2, 10, 3, 11, 6, 14, 7, 15);
  const i8 s0 = __builtin_shufflevector(t0, t2, 0, 1, 8, 9, 4, 5, 12, 13);
  const i8 s1 = __builtin_shufflevector(t0, t2, 2, 3, 10, 11, 6, 7, 14, 15);
  const i8 s2 = __builtin_shufflevector(t1, t3, 0, 1, 8, 9, 4, 5, 12, 13);
  const i8 s3 = __builtin_shufflevector(t1, t3, 2, 3, 10, 11, 6, 7, 14, 15);
  const i8 s4 = __builtin_shufflevector(t4, t6, 0, 1, 8, 9, 4, 5, 12, 13);
  const i8 s5 = __builtin_shufflevector(t4, t6, 2, 3, 10, 11, 6, 7, 14, 15);
  const i8 s6 = __builtin_shufflevector(t5, t7, 0, 1, 8, 9, 4, 5, 12, 13);
  const i8 s7 = __builtin_shufflevector(t5, t7, 2, 3, 10, 11, 6, 7, 14, 15);
  r[0] = __builtin_shufflevector(s0, s4, 0, 1, 2, 3, 8, 9, 10, 11);
  r[1] = __builtin_shufflevector(s1, s5, 0, 1, 2, 3, 8, 9, 10, 11);
  r[2] = __builtin_shufflevector(s2, s6, 0, 1, 2, 3, 8, 9, 10, 11);
  r[3] = __builtin_shufflevector(s3, s7, 0, 1, 2, 3, 8, 9, 10, 11);
  r[4] = __builtin_shufflevector(s0, s4, 4, 5, 6, 7, 12, 13, 14, 15);
  r[5] = __builtin_shufflevector(s1, s5, 4, 5, 6, 7, 12, 13, 14, 15);
  r[6] = __builtin_shufflevector(s2, s6, 4, 5, 6, 7, 12, 13, 14, 15);
  r[7] = __builtin_shufflevector(s3, s7, 4, 5, 6, 7, 12, 13, 14, 15);
}

SR_INLINE i8 select(i8 mask, i8 a, i8 b) { return (a & mask) | (b & ~mask); }
SR_INLINE f8 select(i8 mask, f8 a, f8 b) { return f8(select(mask, i8(a), i8(b))); }
SR_INLINE d4 select(l4 mask, d4 a, d4 b) { return d4((l4(a) & mask) | (l4(b) & ~mask)); }
SR_INLINE i8 min(i8 a, i8 b) { return a < b ? a : b; }
SR_INLINE i8 max(i8 a, i8 b) { return a < b ? b : a; }
SR_INLINE d4 max(d4 a, d4 b) { return select(l4(a < b), b, a); }  // as std::max
SR_INLINE d4 min(d4 a, d4 b) { return select(l4(b < a), b, a); }  // as std::min
SR_INLINE d4 abs(d4 v) { return d4(l4(v) & ~broadcast<l4>(int64_t(0x8000000000000000ull))); }
// Half h (lanes 4h .. 4h + 3) of eight lanes, widened to double (exactly).
SR_INLINE d4 wide(i8 v, int h) {
  return __builtin_convertvector(h == 0 ? __builtin_shufflevector(v, v, 0, 1, 2, 3)
                                        : __builtin_shufflevector(v, v, 4, 5, 6, 7), d4);
}
SR_INLINE d4 wide(f8 v, int h) {
  return __builtin_convertvector(h == 0 ? low_half(v) : high_half(v), d4);
}

}  // namespace simd
}  // namespace sr
