// Rasterize stage: the per-tile hot loop. Steps integer edge functions, depth-tests, and records
// which triangle is visible at each pixel (a tile-local visibility buffer, shaded afterwards).
#pragma once

#include "setup.hpp"

#include <limits>

namespace sr {

// Pixel rectangle of one tile, [x0, x1) x [y0, y1).
struct TileRect {
  int x0, y0, x1, y1;
};
inline TileRect tile_rect(const Viewport& vp, int tile) {
  const int tx = tile % vp.tiles_x, ty = tile / vp.tiles_x;
  return {tx * kTileSizePx, ty * kTileSizePx, std::min((tx + 1) * kTileSizePx, vp.width),
          std::min((ty + 1) * kTileSizePx, vp.height)};
}

struct VisibleTriangle {
  const TriangleSetup* tri;
  const SetupChunk* chunk;  // owns tri's clip table
};
constexpr uint32_t kNoTriangle = 0xffffffffu;
constexpr int kTilePixels = kTileSizePx * kTileSizePx;

// Per-thread scratch, reused from tile to tile (row stride kTileSizePx).
struct TileScratch {
  float key[kTilePixels];         // depth key of the nearest fragment so far (larger = closer)
  uint32_t visible[kTilePixels];  // index into `triangles`, or kNoTriangle
  uint32_t coverage[kTilePixels]; // fragments before the depth test
  std::vector<VisibleTriangle> triangles;  // binned triangles of this tile, in primitive order
};

// Rasterizes every triangle binned to `tile`, chunks in order, records in order: ties in depth
// keep the first triangle drawn, so the result is the same for any thread count.
void rasterize_tile(const Viewport& viewport, int tile, const std::vector<SetupChunk>& chunks,
                    std::size_t num_chunks, bool want_coverage, TileScratch& scratch);

}  // namespace sr
