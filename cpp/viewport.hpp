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

// Samples per pixel a pattern may hold: ssaa=8 is an 8x8 grid.
constexpr int kMaxSamples = 64;

// Where each pixel is sampled: offsets from its top-left corner in fixed-point units (1/256 px),
// in [0, kSubpixelOne). Setup (bounding-box culling, the small-triangle coverage test) and
// binning read the whole pattern. The tile pass rasterizes one sample per pass: its offset is
// TileScratch::sample_x / sample_y (rasterize.hpp), so one set of kernels serves every pattern;
// a pattern of several samples runs one pass per sample (multisample.cpp).
struct SamplePattern {
  int count = 1;
  int32_t x[kMaxSamples] = {kSubpixelHalf};
  int32_t y[kMaxSamples] = {kSubpixelHalf};
  int32_t min_x = kSubpixelHalf, max_x = kSubpixelHalf;  // over the samples
  int32_t min_y = kSubpixelHalf, max_y = kSubpixelHalf;

  // One sample at the pixel centre, (j + 1/2, i + 1/2): every render without anti-aliasing.
  static SamplePattern centre() { return SamplePattern{}; }
  // `count` samples at x[i], y[i] (fixed point), the extremes derived.
  static SamplePattern of(int count, const int32_t* xs, const int32_t* ys) {
    SamplePattern p;
    p.count = count;
    p.min_x = p.min_y = kSubpixelOne;
    p.max_x = p.max_y = -1;
    for (int i = 0; i < count; ++i) {
      p.x[i] = xs[i];
      p.y[i] = ys[i];
      p.min_x = std::min(p.min_x, xs[i]);
      p.max_x = std::max(p.max_x, xs[i]);
      p.min_y = std::min(p.min_y, ys[i]);
      p.max_y = std::max(p.max_y, ys[i]);
    }
    return p;
  }
};

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
