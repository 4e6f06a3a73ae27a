// Rasterize stage: the hot loop. No divisions, no feature branches but the template parameter.
#include "rasterize.hpp"

#include <algorithm>

namespace sr {

namespace {

using namespace simd;

// Any triangle, one pixel at a time, edge functions in int64.
template <bool kCoverage>
void rasterize_large(const TriangleSetup& t, int x0, int x1, int y0, int y1, const TileRect& rect,
                     uint32_t index, TileScratch& s) {
  const EdgeEquations eq = edge_equations(t, x0, y0);
  int64_t row[3];
  for (int k = 0; k < 3; ++k) row[k] = eq.origin[k] - t.bias[k];  // biased: inside <=> >= 0
  const float k0 = t.key_over_area[0], k1 = t.key_over_area[1], k2 = t.key_over_area[2];
  const int64_t b0 = t.bias[0], b1 = t.bias[1], b2 = t.bias[2];

  for (int y = y0; y <= y1; ++y) {
    int64_t e0 = row[0], e1 = row[1], e2 = row[2];
    const int line = (y - rect.y0) * kTileSizePx - rect.x0;
    for (int x = x0; x <= x1; ++x) {
      if ((e0 | e1 | e2) >= 0) {
        const int i = line + x;
        if constexpr (kCoverage) ++s.coverage[i];
        // key = sum_k E_k * key_k / area2: barycentric weights from the exact edge values.
        const float key = float(e0 + b0) * k0 + float(e1 + b1) * k1 + float(e2 + b2) * k2;
        if (key > s.key[i]) {  // strict: on a tie the earlier triangle stays
          s.key[i] = key;
          s.visible[i] = index;
        }
      }
      e0 += eq.step_x[0]; e1 += eq.step_x[1]; e2 += eq.step_x[2];
    }
    row[0] += eq.step_y[0]; row[1] += eq.step_y[1]; row[2] += eq.step_y[2];
  }
}

// A small triangle (is_small), eight pixels of a row at a time in int32: the same integer edge
// values and the same float operations per pixel as rasterize_large, so the same bits.
template <bool kCoverage>
SR_INLINE void rasterize_small(const TriangleSetup& t, int x0, int x1, int y0, int y1,
                               const TileRect& rect, uint32_t index, TileScratch& s) {
  SmallEdges edges(edge_equations(t, x0, y0));
  i8 bias[3];
  f8 key_k[3];
  for (int k = 0; k < 3; ++k) {
    bias[k] = splat(int32_t(t.bias[k]));
    key_k[k] = splat(t.key_over_area[k]);
  }
  const i8 lane = lane_index(), index_v = splat(int32_t(index));
  const int width = x1 - x0 + 1;

  for (int y = y0; y <= y1; ++y, edges.next_row()) {
    int i = (y - rect.y0) * kTileSizePx + (x0 - rect.x0);
    SmallEdges::Cursor c = edges.cursor();
    for (int dx = 0; dx < width; dx += kLanes, i += kLanes, c.next(edges)) {
      const i8 inside = (((c.e[0] - bias[0]) | (c.e[1] - bias[1]) | (c.e[2] - bias[2])) >= 0) &
                        (lane < width - dx);
      if (!any(inside)) continue;
      if constexpr (kCoverage) store(s.coverage + i, load<i8>(s.coverage + i) - inside);
      const f8 key = c.edge(0) * key_k[0] + c.edge(1) * key_k[1] + c.edge(2) * key_k[2];
      const f8 old = load<f8>(s.key + i);
      const i8 win = inside & (key > old);  // strict: on a tie the earlier triangle stays
      store(s.key + i, win ? key : old);
      store(s.visible + i, win ? index_v : load<i8>(s.visible + i));
    }
  }
}

// A small triangle whose box (within the tile) is at most four pixels wide and more than one
// row high: two rows of four pixels at a time (SmallEdgePairs), otherwise as rasterize_small.
template <bool kCoverage>
SR_INLINE void rasterize_pairs(const TriangleSetup& t, int x0, int x1, int y0, int y1,
                               const TileRect& rect, uint32_t index, TileScratch& s) {
  SmallEdgePairs edges(edge_equations(t, x0, y0));
  i8 bias[3];
  f8 key_k[3];
  for (int k = 0; k < 3; ++k) {
    bias[k] = splat(int32_t(t.bias[k]));
    key_k[k] = splat(t.key_over_area[k]);
  }
  const i8 lane = lane_index(), index_v = splat(int32_t(index));
  const i8 column = lane & 3, row = lane >> 2;
  const i8 in_box_x = column < x1 - x0 + 1;
  for (int y = y0; y <= y1; y += 2, edges.next_rows()) {
    const int i = (y - rect.y0) * kTileSizePx + (x0 - rect.x0);
    const i8 inside = (((edges.e[0] - bias[0]) | (edges.e[1] - bias[1]) | (edges.e[2] - bias[2])) >= 0) &
                      in_box_x & (row < y1 - y + 1);
    if (!any(inside)) continue;
    if constexpr (kCoverage)
      store_pair(s.coverage + i, kTileSizePx, load_pair<i8>(s.coverage + i, kTileSizePx) - inside);
    const f8 key = edges.edge(0) * key_k[0] + edges.edge(1) * key_k[1] + edges.edge(2) * key_k[2];
    const f8 old = load_pair<f8>(s.key + i, kTileSizePx);
    const i8 win = inside & (key > old);  // strict: on a tie the earlier triangle stays
    store_pair(s.key + i, kTileSizePx, win ? key : old);
    store_pair(s.visible + i, kTileSizePx, win ? index_v : load_pair<i8>(s.visible + i, kTileSizePx));
  }
}

template <bool kCoverage>
SR_INLINE void rasterize_all(const TileRect& rect, int tile, const std::vector<SetupChunk>& chunks,
                             std::size_t num_chunks, TileScratch& s) {
  for (std::size_t c = 0; c < num_chunks; ++c) {
    const SetupChunk& chunk = chunks[c];
    for (uint32_t r = chunk.tile_begin[tile]; r < chunk.tile_begin[tile + 1]; ++r) {
      const TriangleSetup& t = chunk.records[chunk.tile_records[r]];
      const uint32_t index = uint32_t(s.triangles.size());
      s.triangles.push_back({&t, &chunk});
      const int x0 = std::max(int(t.x0), rect.x0), x1 = std::min(int(t.x1), rect.x1 - 1);
      const int y0 = std::max(int(t.y0), rect.y0), y1 = std::min(int(t.y1), rect.y1 - 1);
      if (x0 > x1 || y0 > y1) continue;
      if (is_small(t)) {
        if (x1 - x0 < 4 && y1 > y0)
          rasterize_pairs<kCoverage>(t, x0, x1, y0, y1, rect, index, s);
        else
          rasterize_small<kCoverage>(t, x0, x1, y0, y1, rect, index, s);
      }
      else {
        rasterize_large<kCoverage>(t, x0, x1, y0, y1, rect, index, s);
      }
    }
  }
}

template <bool kCoverage>
SR_TARGET_AVX2 void rasterize_all_avx2(const TileRect& rect, int tile,
                                       const std::vector<SetupChunk>& chunks,
                                       std::size_t num_chunks, TileScratch& s) {
  rasterize_all<kCoverage>(rect, tile, chunks, num_chunks, s);
}

template <bool kCoverage>
void rasterize_all_generic(const TileRect& rect, int tile, const std::vector<SetupChunk>& chunks,
                           std::size_t num_chunks, TileScratch& s) {
  rasterize_all<kCoverage>(rect, tile, chunks, num_chunks, s);
}

}  // namespace

void rasterize_tile(const Viewport& viewport, int tile, const std::vector<SetupChunk>& chunks,
                    std::size_t num_chunks, bool want_coverage, Isa isa, TileScratch& s) {
  const TileRect rect = tile_rect(viewport, tile);
  std::fill(std::begin(s.key), std::end(s.key), -std::numeric_limits<float>::infinity());
  std::fill(std::begin(s.visible), std::end(s.visible), kNoTriangle);
  if (want_coverage) std::fill(std::begin(s.coverage), std::end(s.coverage), 0u);
  s.triangles.clear();
  const bool avx2 = isa == Isa::Avx2;
  if (want_coverage)
    (avx2 ? rasterize_all_avx2<true> : rasterize_all_generic<true>)(rect, tile, chunks, num_chunks, s);
  else
    (avx2 ? rasterize_all_avx2<false> : rasterize_all_generic<false>)(rect, tile, chunks, num_chunks, s);
}

}  // namespace sr
