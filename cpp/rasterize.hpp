// Rasterize stage: the per-tile hot loop. Steps integer edge functions, depth-tests, and records
// which triangle is visible at each pixel (a tile-local visibility buffer, shaded afterwards).
#pragma once

#include "setup.hpp"
#include "simd.hpp"

#include <algorithm>
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

// Per-thread scratch, reused from tile to tile (row stride kTileSizePx). The kernels read and
// write eight pixels of a row, or four pixels of two rows, at a time from any pixel, so they may
// spill up to kLanes - 1 pixels into the next row or one row past the last (lanes masked off,
// values kept): the arrays have that much padding at the end.
constexpr int kTileScratchPixels = kTilePixels + kTileSizePx + simd::kLanes;
struct TileScratch {
  float key[kTileScratchPixels];         // depth key of the nearest fragment so far (larger = closer)
  uint32_t visible[kTileScratchPixels];  // index into `triangles`, or kNoTriangle
  uint32_t coverage[kTileScratchPixels]; // fragments before the depth test
  std::vector<VisibleTriangle> triangles;  // binned triangles of this tile, in primitive order
};

// Rasterizes every triangle binned to `tile`, chunks in order, records in order: ties in depth
// keep the first triangle drawn, so the result is the same for any thread count.
// `isa` picks the kernel's instruction set; the result is the same bits for either.
void rasterize_tile(const Viewport& viewport, int tile, const std::vector<SetupChunk>& chunks,
                    std::size_t num_chunks, bool want_coverage, Isa isa, TileScratch& scratch);

// Triangles whose snapped bounding box spans at most this many pixels per side take the
// eight-lane path: their edge functions, relative to a sample in the box, fit in int32.
constexpr int kSmallTrianglePx = 64;
inline bool is_small(const TriangleSetup& t) {
  const int32_t span_x = std::max({t.x[0], t.x[1], t.x[2]}) - std::min({t.x[0], t.x[1], t.x[2]});
  const int32_t span_y = std::max({t.y[0], t.y[1], t.y[2]}) - std::min({t.y[0], t.y[1], t.y[2]});
  return span_x <= kSmallTrianglePx * kSubpixelOne && span_y <= kSmallTrianglePx * kSubpixelOne;
}

// Unbiased edge functions E_k at the centre of pixel (x, y), and their change per pixel step.
// Exact: |E| < 2^51 in general (see kGuardBandPx). For a small triangle and a pixel within its
// bounding box widened by a vector (kLanes - 1 pixels), |E| < 2^14 * (2^14 + 2^11) * 2 < 2^30,
// so values and steps fit in int32 and may be stepped there.
struct EdgeEquations {
  int64_t origin[3];
  int64_t step_x[3], step_y[3];
};
inline EdgeEquations edge_equations(const TriangleSetup& t, int x, int y) {
  EdgeEquations e;
  const int64_t px = int64_t(x) * kSubpixelOne + kSubpixelHalf;
  const int64_t py = int64_t(y) * kSubpixelOne + kSubpixelHalf;
  for (int k = 0; k < 3; ++k) {
    const int a = kEdgeStart[k], b = kEdgeEnd[k];
    const int64_t dx = t.x[b] - t.x[a], dy = t.y[b] - t.y[a];
    e.origin[k] = dx * (py - t.y[a]) - dy * (px - t.x[a]);
    e.step_x[k] = -dy * kSubpixelOne;
    e.step_y[k] = dx * kSubpixelOne;
  }
  return e;
}

// A small triangle's edge functions for eight pixels of a row in exact int32 (see above), stepped
// eight pixels along a row (Cursor) and one row down (next_row); shared by raster and shading.
struct SmallEdges {
  simd::i8 row[3], step_x8[3], step_y[3];
  SR_INLINE explicit SmallEdges(const EdgeEquations& eq) {
    for (int k = 0; k < 3; ++k) {
      row[k] = simd::splat(int32_t(eq.origin[k])) + simd::lane_index() * int32_t(eq.step_x[k]);
      step_x8[k] = simd::splat(int32_t(eq.step_x[k] * simd::kLanes));
      step_y[k] = simd::splat(int32_t(eq.step_y[k]));
    }
  }
  struct Cursor {
    simd::i8 e[3];  // exact E_k at the eight pixels
    SR_INLINE simd::f8 edge(int k) const { return simd::to_float(e[k]); }
    SR_INLINE void next(const SmallEdges& s) { for (int k = 0; k < 3; ++k) e[k] += s.step_x8[k]; }
  };
  SR_INLINE Cursor cursor() const { return {{row[0], row[1], row[2]}}; }
  SR_INLINE void next_row() { for (int k = 0; k < 3; ++k) row[k] += step_y[k]; }
};

// The same for boxes at most four pixels wide: lanes 0-3 are pixels (x .. x + 3, y), lanes 4-7
// the pixels below them, so a tiny triangle takes half the iterations. The values are those of
// SmallEdges at the same pixels (the same exact integers).
struct SmallEdgePairs {
  simd::i8 e[3], step_y2[3];
  SR_INLINE explicit SmallEdgePairs(const EdgeEquations& eq) {
    const simd::i8 lane = simd::lane_index(), dx = lane & 3, dy = lane >> 2;
    for (int k = 0; k < 3; ++k) {
      e[k] = simd::splat(int32_t(eq.origin[k])) + dx * int32_t(eq.step_x[k]) +
             dy * int32_t(eq.step_y[k]);
      step_y2[k] = simd::splat(int32_t(eq.step_y[k] * 2));
    }
  }
  SR_INLINE simd::f8 edge(int k) const { return simd::to_float(e[k]); }
  SR_INLINE void next_rows() { for (int k = 0; k < 3; ++k) e[k] += step_y2[k]; }
};

}  // namespace sr
