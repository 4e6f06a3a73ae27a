// Rasterize stage: the tile entry point for deferred shading (the kernels are in rasterize.hpp).
#include "rasterize.hpp"

#include "dispatch.hpp"

#include <algorithm>
#include <limits>

namespace sr {

namespace {

template <bool kCoverage, bool kScanline>
struct RasterizeAll {
  SR_INLINE static void run(const TileRect& rect, int tile, const std::vector<SetupChunk>& chunks,
                            std::size_t num_chunks, TileScratch& s) {
    NoShading hook;
    raster::rasterize_all<kCoverage, kScanline>(rect, tile, chunks, num_chunks, s, hook);
  }
};

template <bool kCoverage, bool kScanline>
struct RasterizeAllSamples {
  SR_INLINE static void run(const TileRect& rect, int tile, const std::vector<SetupChunk>& chunks,
                            std::size_t num_chunks, TileScratch* const* samples, int count) {
    for (int s = 0; s < count; ++s) samples[s]->clear(kCoverage, rect.y1 - rect.y0);
    raster::rasterize_all_samples<kCoverage, kScanline>(rect, tile, chunks, num_chunks, samples, count);
  }
};

}  // namespace

RasterizeSamplesFn select_rasterize_samples(Isa isa, bool want_coverage, bool scanline) {
  using K00 = dispatch::IsaKernel<RasterizeAllSamples<false, false>, RasterizeSamplesFn>;
  using K10 = dispatch::IsaKernel<RasterizeAllSamples<true, false>, RasterizeSamplesFn>;
  using K01 = dispatch::IsaKernel<RasterizeAllSamples<false, true>, RasterizeSamplesFn>;
  using K11 = dispatch::IsaKernel<RasterizeAllSamples<true, true>, RasterizeSamplesFn>;
  return scanline ? (want_coverage ? K11::get(isa) : K01::get(isa))
                  : (want_coverage ? K10::get(isa) : K00::get(isa));
}

RasterizeFn select_rasterize(Isa isa, bool want_coverage, bool scanline) {
  using K00 = dispatch::IsaKernel<RasterizeAll<false, false>, RasterizeFn>;
  using K10 = dispatch::IsaKernel<RasterizeAll<true, false>, RasterizeFn>;
  using K01 = dispatch::IsaKernel<RasterizeAll<false, true>, RasterizeFn>;
  using K11 = dispatch::IsaKernel<RasterizeAll<true, true>, RasterizeFn>;
  return scanline ? (want_coverage ? K11::get(isa) : K01::get(isa))
                  : (want_coverage ? K10::get(isa) : K00::get(isa));
}

void rasterize_tile(RasterizeFn kernel, const Viewport& viewport, int tile,
                    const std::vector<SetupChunk>& chunks, std::size_t num_chunks,
                    bool want_coverage, TileScratch& s) {
  const TileRect rect = tile_rect(viewport, tile);
  s.clear(want_coverage, rect.y1 - rect.y0);
  kernel(rect, tile, chunks, num_chunks, s);
}

void TileScratch::clear(bool want_coverage, int rows) {
  const int n = std::min(kTileScratchPixels, (rows + 1) * kTileSizePx + simd::kLanes);
  std::fill(key, key + n, -std::numeric_limits<float>::infinity());
  std::fill(visible, visible + n, kNoTriangle);
  if (want_coverage) std::fill(coverage, coverage + n, 0u);
  triangles.clear();
  flags = 0;
}

}  // namespace sr
