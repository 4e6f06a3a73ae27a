// Shade stage: picks the shading kernels for a render (shade_kernels.hpp, compiled per path and
// instruction set in the shade_kernels_*.cpp files) and runs them over a tile, deferred (each
// triangle that owns pixels, once) or forward (the raster kernels' hook); then writes the tile.
#include "shade.hpp"

#include "outputs.hpp"
#include "shade_kernels.hpp"

#include <stdexcept>

namespace sr {

TileKernels select_tile_kernels(const RenderPlan& plan, const Viewport& viewport, Isa isa,
                                KernelKind kind) {
  TileKernels k;
  k.raster = select_rasterize(isa, plan.coverage, plan.scanline);
  if (viewport.samples.count > 1)
    k.raster_samples = select_rasterize_samples(isa, plan.coverage, plan.scanline);
  if (plan.shade) {
    using shading::deferred_kernel;
    using shading::forward_kernel;
    k.deferred = dispatch::select<TileKernels::Deferred>(
        [&](auto avx2) {
          constexpr Isa I = decltype(avx2)::value ? kBestIsa : Isa::Generic;
          switch (kind) {
            case KernelKind::Headlight: return deferred_kernel<I, KernelKind::Headlight>();
            case KernelKind::Unlit: return deferred_kernel<I, KernelKind::Unlit>();
            case KernelKind::NormalColor: return deferred_kernel<I, KernelKind::NormalColor>();
            default: return deferred_kernel<I, KernelKind::Lit>();
          }
        },
        isa != Isa::Generic);
    if (plan.forward_allowed)  // (never with coverage counting: make_plan)
      k.forward = dispatch::select<TileKernels::Forward>(
          [&](auto avx2) {
            constexpr Isa I = decltype(avx2)::value ? kBestIsa : Isa::Generic;
            switch (kind) {
              case KernelKind::Headlight: return forward_kernel<I, KernelKind::Headlight>();
              case KernelKind::Unlit: return forward_kernel<I, KernelKind::Unlit>();
              case KernelKind::NormalColor: return forward_kernel<I, KernelKind::NormalColor>();
              default: return forward_kernel<I, KernelKind::Lit>();
            }
          },
          isa != Isa::Generic);
  }
  k.isa = isa;
  k.coverage = plan.coverage;
  return k;
}

}  // namespace sr
