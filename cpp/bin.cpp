// Binning: counts per tile while records are made (emit), then a counting sort (bin_records).
#include "bin.hpp"

#include <algorithm>

namespace sr {

// The first pass of binning, done while a just-appended record is at hand: counts it in
// every tile it overlaps (at tile_begin[tile + 2], see bin_records) and notes those tiles as
// first tile | (columns - 1) << 16 | (rows - 1) << 24 (num_tiles <= 2^16, tiles_x, tiles_y <= 2^8).
// Also adds its area to tile_area, split between tiles as its box is (for the choice of shading
// path: the sum estimates a tile's overdraw). `area2` is the record's, in fixed-point units^2.
// The common case, a record inside one tile, inline; one spanning tiles calls emit_spanning.
void emit_spanning(int32_t x0, int32_t y0, int32_t x1, int32_t y1, float area, const Viewport& vp,
                   SetupChunk& out) {
  const uint32_t tx0 = uint32_t(x0) / kTileSizePx, tx1 = uint32_t(x1) / kTileSizePx;
  const uint32_t ty0 = uint32_t(y0) / kTileSizePx, ty1 = uint32_t(y1) / kTileSizePx;
  uint32_t* count = out.tile_begin.data() + 2;
  const bool estimate = !out.tile_area.empty();
  const float per_pixel = area / (float(x1 - x0 + 1) * float(y1 - y0 + 1));
  for (uint32_t ty = ty0; ty <= ty1; ++ty) {
    const int rows = std::min(y1, int32_t(ty + 1) * kTileSizePx - 1) -
                     std::max(y0, int32_t(ty) * kTileSizePx) + 1;
    for (uint32_t tx = tx0; tx <= tx1; ++tx) {
      const int columns = std::min(x1, int32_t(tx + 1) * kTileSizePx - 1) -
                          std::max(x0, int32_t(tx) * kTileSizePx) + 1;
      ++count[ty * uint32_t(vp.tiles_x) + tx];
      if (estimate) out.tile_area[ty * uint32_t(vp.tiles_x) + tx] += per_pixel * float(rows * columns);
    }
  }
  out.record_tiles.push_back((ty0 * uint32_t(vp.tiles_x) + tx0) | (tx1 - tx0) << 16 | (ty1 - ty0) << 24);
}

// Second pass of binning: a counting sort of (tile, record) pairs, which keeps records in
// primitive order within a tile. After the prefix sum tile_begin[tile + 1] is the tile's start;
// used as its cursor it ends as the tile's end, which is the next tile's begin.
void bin_records(const Viewport& vp, SetupChunk& out) {
  const uint32_t num_tiles = uint32_t(vp.num_tiles()), tiles_x = uint32_t(vp.tiles_x);
  uint32_t* begin = out.tile_begin.data();
  for (uint32_t i = 2; i < num_tiles + 2; ++i) begin[i] += begin[i - 1];
  out.tile_records.resize(begin[num_tiles + 1]);
  uint32_t* cursor = begin + 1;
  uint32_t* records = out.tile_records.data();
  const uint32_t* tiles = out.record_tiles.data();
  for (uint32_t r = 0; r < uint32_t(out.record_tiles.size()); ++r) {
    const uint32_t first = tiles[r] & 0xffffu, columns = (tiles[r] >> 16) & 0xffu,
                   rows = tiles[r] >> 24;
    if ((tiles[r] >> 16) == 0) {
      records[cursor[first]++] = r;
    } else {
      for (uint32_t j = 0; j <= rows; ++j)
        for (uint32_t i = 0; i <= columns; ++i) records[cursor[first + j * tiles_x + i]++] = r;
    }
  }
  out.tile_begin.pop_back();
}

}  // namespace sr
