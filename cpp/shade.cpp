// Shade stage: picks the shading kernels for a render (shade_kernels.hpp, compiled per instruction
// set in shade_avx2.cpp and shade_generic.cpp) and runs them over a tile, deferred (each
// triangle that owns pixels, once) or forward (the raster kernels' hook); then writes the tile.
#include "shade.hpp"

#include "outputs.hpp"
#include "shade_kernels.hpp"

#include <stdexcept>

namespace sr {

TileKernels select_tile_kernels(const RenderPlan& plan, const Viewport& viewport, Isa isa) {
  const SamplePattern& pattern = viewport.samples;
  TileKernels k;
  k.raster = select_rasterize(isa, pattern, plan.coverage, plan.scanline);
  if (pattern.count > 1)
    k.raster_samples = select_rasterize_samples(isa, plan.coverage, plan.scanline);
  const bool avx2 = isa == Isa::Avx2;
  k.deferred = (avx2 ? shading::select_deferred<Isa::Avx2> : shading::select_deferred<Isa::Generic>)(
      pattern, plan.shading, plan.color, plan.normal);
  if (plan.forward_allowed)  // (never with coverage counting: make_plan)
    k.forward = (avx2 ? shading::select_forward<Isa::Avx2> : shading::select_forward<Isa::Generic>)(
        pattern, plan.shading, plan.color, plan.normal);
  k.isa = isa;
  k.coverage = plan.coverage;
  return k;
}

void rasterize_and_shade_tile(const ShadeParams& params, const TileKernels& kernels,
                              const Viewport& viewport, int tile,
                              const std::vector<SetupChunk>& chunks, std::size_t num_chunks,
                              TileScratch& raster, ShadeScratch& scratch) {
  const TileRect rect = tile_rect(viewport, tile);
  if (!kernels.forward) throw std::logic_error("rasterize_and_shade_tile: nothing to shade");
  raster.clear(kernels.coverage);
  kernels.forward(params, rect, tile, chunks, num_chunks, raster, scratch);
  write_tile(params, rect, raster, scratch, kernels.isa);
}

void shade_tile(const ShadeParams& params, const TileKernels& kernels, const Viewport& viewport,
                int tile, const TileScratch& raster, ShadeScratch& scratch) {
  const TileRect rect = tile_rect(viewport, tile);
  if (kernels.deferred) shade_deferred(kernels, params, rect, raster, scratch);
  write_tile(params, rect, raster, scratch, kernels.isa);
}

}  // namespace sr
