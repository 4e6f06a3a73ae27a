// Kernel dispatch: turns the run-time choices that reshape an inner loop (instruction set,
// shading model, sample pattern, which outputs, coverage counting) into template arguments,
// once per render or tile pass.
//
//   const ShadeFn fn = dispatch::select<ShadeFn>(
//       [](auto isa, auto model, auto color) -> ShadeFn { return ...<decltype(isa)::value, ...>; },
//       isa, shading, color_requested);
//
// select() calls its function with one compile-time tag per choice (Bool<b>, IsaTag<isa>,
// ModelTag<Model>, PatternTag<Pattern>), so every combination is instantiated: keep the axes to what changes the
// loop's code, and make everything else a per-triangle branch. IsaKernel<K, Fn> compiles one
// kernel body (K::run, always inline) twice, for AVX2 and for the generic x86-64 target.
#pragma once

#include "shade_models.hpp"
#include "simd.hpp"
#include "viewport.hpp"

#include <stdexcept>

#include <type_traits>

namespace sr {
namespace dispatch {

template <bool B>
using Bool = std::integral_constant<bool, B>;
template <Isa I>
using IsaTag = std::integral_constant<Isa, I>;
template <typename M>
struct ModelTag {
  using type = M;
};
template <typename P>
struct PatternTag {
  using type = P;
};

template <typename R, typename F>
R select(F&& f) {
  return f();
}

template <typename R, typename F, typename... Rest>
R select(F&& f, bool b, Rest... rest);
template <typename R, typename F, typename... Rest>
R select(F&& f, Isa isa, Rest... rest);
template <typename R, typename F, typename... Rest>
R select(F&& f, Shading shading, Rest... rest);
template <typename R, typename F, typename... Rest>
R select(F&& f, const SamplePattern& pattern, Rest... rest);

template <typename R, typename F, typename... Rest>
R select(F&& f, bool b, Rest... rest) {
  if (b) return select<R>([&](auto... t) { return f(Bool<true>{}, t...); }, rest...);
  return select<R>([&](auto... t) { return f(Bool<false>{}, t...); }, rest...);
}

template <typename R, typename F, typename... Rest>
R select(F&& f, Isa isa, Rest... rest) {
  if (isa == Isa::Avx2) return select<R>([&](auto... t) { return f(IsaTag<Isa::Avx2>{}, t...); }, rest...);
  return select<R>([&](auto... t) { return f(IsaTag<Isa::Generic>{}, t...); }, rest...);
}

template <typename R, typename F, typename... Rest, typename... M>
R select_model(F&& f, Shading shading, ModelList<M...>, Rest... rest) {
  R r{};
  (void)((M::kId == shading
              ? (r = select<R>([&](auto... t) { return f(ModelTag<M>{}, t...); }, rest...), true)
              : false) ||
         ...);
  return r;
}

template <typename R, typename F, typename... Rest>
R select(F&& f, Shading shading, Rest... rest) {
  return select_model<R>(f, shading, ShadingModels{}, rest...);
}

template <typename R, typename F, typename... Rest, typename... P>
R select_pattern(F&& f, const SamplePattern& pattern, PatternList<P...>, Rest... rest) {
  R r{};
  const bool found =
      ((P::matches(pattern)
            ? (r = select<R>([&](auto... t) { return f(PatternTag<P>{}, t...); }, rest...), true)
            : false) ||
       ...);
  if (!found) throw std::logic_error("no kernels are compiled for this sample pattern");
  return r;
}

template <typename R, typename F, typename... Rest>
R select(F&& f, const SamplePattern& pattern, Rest... rest) {
  return select_pattern<R>(f, pattern, SamplePatterns{}, rest...);
}

// One kernel body compiled for each instruction set. K::run is always inline, so all of it takes
// the entry point's target (simd.hpp: nothing outside a kernel is compiled for AVX2).
template <typename K, typename Fn>
struct IsaKernel;
template <typename K, typename R, typename... A>
struct IsaKernel<K, R (*)(A...)> {
  SR_TARGET_AVX2 static R avx2(A... a) { return K::run(a...); }
  static R generic(A... a) { return K::run(a...); }
  static constexpr R (*get(Isa isa))(A...) { return isa == Isa::Avx2 ? avx2 : generic; }
};

}  // namespace dispatch
}  // namespace sr
