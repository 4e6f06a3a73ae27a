// Kernel dispatch: turns the run-time choices that reshape an inner loop (instruction set, which
// outputs, coverage counting) into template arguments, once per render.
//
//   const Fn fn = dispatch::select<Fn>(
//       [](auto color, auto normal) -> Fn { return Kernel<decltype(color)::value, ...>; },
//       color_requested, normal_requested);
//
// select() calls its function with one compile-time tag per choice (Bool<b>), so every
// combination is instantiated: keep the axes to what pays (benchmarks/RESULTS.md, "What each
// kernel axis is worth") and make everything else a per-draw or per-triangle branch.
// IsaKernel<K, Fn> compiles one kernel body (K::run, always inline) for one instruction set:
// AVX2 (x86 only) or the generic target of the build.
#pragma once

#include "simd.hpp"

#include <type_traits>

namespace sr {
namespace dispatch {

template <bool B>
using Bool = std::integral_constant<bool, B>;

template <typename R, typename F>
R select(F&& f) {
  return f();
}

template <typename R, typename F, typename... Rest>
R select(F&& f, bool b, Rest... rest) {
  if (b) return select<R>([&](auto... t) { return f(Bool<true>{}, t...); }, rest...);
  return select<R>([&](auto... t) { return f(Bool<false>{}, t...); }, rest...);
}

// One kernel body for each instruction set. K::run is always inline, so all of it takes the entry
// point's target (simd.hpp: nothing outside a kernel is compiled for AVX2). Only the entry points
// a file takes the address of are compiled in it.
template <typename K, typename Fn>
struct IsaKernel;
template <typename K, typename R, typename... A>
struct IsaKernel<K, R (*)(A...)> {
#if SR_X86
  SR_TARGET_AVX2 static R avx2(A... a) { return K::run(a...); }
#endif
  static R generic(A... a) { return K::run(a...); }
  template <Isa I>
  static constexpr R (*get())(A...) {
#if SR_X86
    if constexpr (I == Isa::Avx2) return avx2; else
#endif
    return generic;
  }
  static constexpr R (*get(Isa isa))(A...) {
#if SR_X86
    if (isa == Isa::Avx2) return avx2;
#endif
    (void)isa;
    return generic;
  }
};

}  // namespace dispatch
}  // namespace sr
