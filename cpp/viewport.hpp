// Viewport: the image's size, its tiling, and where each pixel is sampled.
#pragma once

#include "pipeline.hpp"

#include <algorithm>
#include <cstdint>

namespace sr {

// Screen tiles: each is rasterized and shaded by one thread at a time, in primitive order, so
// the result does not depend on the number of threads. The tile pass's scratch buffers are
// sized from it (rasterize.hpp, shade.hpp): a tile's buffers stay in L1/L2.
constexpr int kTileSizePx = 64;

// Samples per pixel the tile scratch holds. One sample at the pixel centre is the only pattern
// so far; multisampling raises this and adds patterns (ARCHITECTURE.md, "Add a sample pattern").
constexpr int kMaxSamples = 1;

// Where each pixel is sampled: offsets from its top-left corner in fixed-point units (1/256 px),
// in [0, kSubpixelOne). Setup (bounding-box culling, the one-or-two-sample coverage test) and
// binning read the run-time pattern; the raster kernels are compiled for a pattern type with the
// same positions (CentreSample, rasterize.hpp).
struct SamplePattern {
  int count = 1;
  int32_t x[kMaxSamples] = {kSubpixelHalf};
  int32_t y[kMaxSamples] = {kSubpixelHalf};
  int32_t min_x = kSubpixelHalf, max_x = kSubpixelHalf;  // over the samples
  int32_t min_y = kSubpixelHalf, max_y = kSubpixelHalf;

  // One sample at the pixel centre, (j + 1/2, i + 1/2): the only pattern for now.
  static SamplePattern centre() { return SamplePattern{}; }
};

// The sample patterns the tile kernels are compiled for (a dispatch axis: dispatch.hpp). Each
// gives its positions as constants, equal to a SamplePattern's.
struct CentreSample {
  static constexpr int kCount = 1;
  static constexpr int32_t kX = kSubpixelHalf, kY = kSubpixelHalf;  // sample 0
  static bool matches(const SamplePattern& p) {
    return p.count == kCount && p.x[0] == kX && p.y[0] == kY;
  }
};
template <typename... P>
struct PatternList {};
using SamplePatterns = PatternList<CentreSample>;

// Image size, tiling and sample pattern; the scissor is the whole image.
struct Viewport {
  int width = 0, height = 0;
  int tiles_x = 0, tiles_y = 0;
  SamplePattern samples;
  Viewport() = default;
  Viewport(int w, int h, const SamplePattern& pattern = SamplePattern::centre())
      : width(w), height(h),
        tiles_x((w + kTileSizePx - 1) / kTileSizePx),
        tiles_y((h + kTileSizePx - 1) / kTileSizePx),
        samples(pattern) {}
  int num_tiles() const { return tiles_x * tiles_y; }
};

// Pixel rectangle of one tile, [x0, x1) x [y0, y1).
struct TileRect {
  int x0, y0, x1, y1;
};
inline TileRect tile_rect(const Viewport& vp, int tile) {
  const int tx = tile % vp.tiles_x, ty = tile / vp.tiles_x;
  return {tx * kTileSizePx, ty * kTileSizePx, std::min((tx + 1) * kTileSizePx, vp.width),
          std::min((ty + 1) * kTileSizePx, vp.height)};
}

}  // namespace sr
