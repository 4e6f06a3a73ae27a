// Rasterize stage: the tile entry point for deferred shading (the kernels are in rasterize.hpp).
#include "rasterize.hpp"

#include <algorithm>
#include <limits>

namespace sr {

namespace {

template <bool kCoverage>
SR_TARGET_AVX2 void rasterize_all_avx2(const TileRect& rect, int tile,
                                       const std::vector<SetupChunk>& chunks,
                                       std::size_t num_chunks, TileScratch& s) {
  NoShading hook;
  raster::rasterize_all<kCoverage>(rect, tile, chunks, num_chunks, s, hook);
}

template <bool kCoverage>
void rasterize_all_generic(const TileRect& rect, int tile, const std::vector<SetupChunk>& chunks,
                           std::size_t num_chunks, TileScratch& s) {
  NoShading hook;
  raster::rasterize_all<kCoverage>(rect, tile, chunks, num_chunks, s, hook);
}

}  // namespace

void rasterize_tile(const Viewport& viewport, int tile, const std::vector<SetupChunk>& chunks,
                    std::size_t num_chunks, bool want_coverage, Isa isa, TileScratch& s) {
  const TileRect rect = tile_rect(viewport, tile);
  s.clear(want_coverage);
  const bool avx2 = isa == Isa::Avx2;
  if (want_coverage)
    (avx2 ? rasterize_all_avx2<true> : rasterize_all_generic<true>)(rect, tile, chunks, num_chunks, s);
  else
    (avx2 ? rasterize_all_avx2<false> : rasterize_all_generic<false>)(rect, tile, chunks, num_chunks, s);
}

void TileScratch::clear(bool want_coverage) {
  std::fill(std::begin(key), std::end(key), -std::numeric_limits<float>::infinity());
  std::fill(std::begin(visible), std::end(visible), kNoTriangle);
  if (want_coverage) std::fill(std::begin(coverage), std::end(coverage), 0u);
  triangles.clear();
}

}  // namespace sr
