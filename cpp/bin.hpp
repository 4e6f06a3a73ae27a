// Binning: which tiles each setup record overlaps, as per-tile lists of record indices that keep
// primitive order. Binning reads only a record's pixel box and area, never the record itself, so
// any record is binned the same way.
#pragma once

#include "alpha_mask.hpp"
#include "pipeline.hpp"
#include "scratch.hpp"
#include "viewport.hpp"

#include <vector>

namespace sr {

// The triangles one chunk of a draw produced, binned to tiles. Records keep primitive order.
// Cache-line aligned: neighbouring chunks are set up by different threads, and every push_back
// writes an array's end; chunks that shared a line kept the setup pass from scaling with threads
// (benchmarks/RESULTS.md, "Measurements behind the code").
struct alignas(64) SetupChunk {
  GrowingArray<TriangleSetup> records;   // (grown without copies: a first frame grows them all)
  GrowingArray<TriangleShading> shading; // records[i]'s in shading[i]; empty unless SetupParams::shade
  GrowingArray<ExactWeights> exact;      // records[i]'s in exact[i]; empty unless SetupParams::exact_weights
  std::vector<vec3> clip_bary;           // 3 per clipped record: source weights of its vertices
  std::vector<uint32_t> tile_begin;      // num_tiles + 1 offsets into tile_records
  std::vector<uint32_t> tile_records;    // record indices, grouped by tile, ascending
  GrowingArray<uint32_t> record_tiles;   // scratch: tiles each record overlaps (setup.cpp)
  std::vector<float> tile_area;          // per tile: records' area in it, px^2 (an estimate);
                                         // empty unless SetupParams::estimate_overdraw
  const AlphaTest* alpha = nullptr;      // a masked draw's alpha test (alpha_mask.hpp), or null
};

// The first pass of binning for the record just appended, with inclusive pixel box
// [x0, x1] x [y0, y1] and twice its area `area2` in fixed-point units^2 (bin.cpp).
void emit_spanning(int32_t x0, int32_t y0, int32_t x1, int32_t y1, float area, const Viewport& vp,
                   SetupChunk& out);
inline void emit(int32_t x0, int32_t y0, int32_t x1, int32_t y1, double area2, const Viewport& vp,
                 SetupChunk& out) {
  const uint32_t tx0 = uint32_t(x0) / kTileSizePx, tx1 = uint32_t(x1) / kTileSizePx;
  const uint32_t ty0 = uint32_t(y0) / kTileSizePx, ty1 = uint32_t(y1) / kTileSizePx;
  const float area = float(area2) * (0.5f / float(kSubpixelOne * kSubpixelOne));
  if (tx0 != tx1 || ty0 != ty1) return emit_spanning(x0, y0, x1, y1, area, vp, out);
  const uint32_t tile = ty0 * uint32_t(vp.tiles_x) + tx0;
  ++out.tile_begin.data()[2 + tile];
  if (!out.tile_area.empty()) out.tile_area[tile] += area;
  out.record_tiles.push_back(tile);
}

// Second pass of binning, after a chunk's last record (bin.cpp).
void bin_records(const Viewport& vp, SetupChunk& out);

}  // namespace sr
