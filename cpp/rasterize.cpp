// Rasterize stage: the hot loop. No divisions, no feature branches but the template parameter.
#include "rasterize.hpp"

#include <algorithm>

namespace sr {

namespace {

template <bool kCoverage>
void rasterize_triangle(const TriangleSetup& t, const TileRect& rect, uint32_t index,
                        TileScratch& s) {
  const int x0 = std::max(t.x0, rect.x0), x1 = std::min(t.x1, rect.x1 - 1);
  const int y0 = std::max(t.y0, rect.y0), y1 = std::min(t.y1, rect.y1 - 1);
  if (x0 > x1 || y0 > y1) return;

  // E_k(p) = dx_k * (p.y - y_a) - dy_k * (p.x - x_a) for edge a -> b; exact in int64 (see
  // kGuardBandPx). Stepping one pixel adds a multiple of 256, so E stays exact as it moves.
  int64_t step_x[3], step_y[3], row[3];
  const int64_t px = int64_t(x0) * kSubpixelOne + kSubpixelHalf;
  const int64_t py = int64_t(y0) * kSubpixelOne + kSubpixelHalf;
  for (int k = 0; k < 3; ++k) {
    const int a = kEdgeStart[k], b = kEdgeEnd[k];
    const int64_t dx = t.x[b] - t.x[a], dy = t.y[b] - t.y[a];
    step_x[k] = -dy * kSubpixelOne;
    step_y[k] = dx * kSubpixelOne;
    row[k] = dx * (py - t.y[a]) - dy * (px - t.x[a]) - t.bias[k];  // biased: inside <=> >= 0
  }
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
      e0 += step_x[0]; e1 += step_x[1]; e2 += step_x[2];
    }
    row[0] += step_y[0]; row[1] += step_y[1]; row[2] += step_y[2];
  }
}

template <bool kCoverage>
void rasterize_all(const TileRect& rect, int tile, const std::vector<SetupChunk>& chunks,
                   std::size_t num_chunks, TileScratch& s) {
  for (std::size_t c = 0; c < num_chunks; ++c) {
    const SetupChunk& chunk = chunks[c];
    for (uint32_t i = chunk.tile_begin[tile]; i < chunk.tile_begin[tile + 1]; ++i) {
      const TriangleSetup& t = chunk.records[chunk.tile_records[i]];
      const uint32_t index = uint32_t(s.triangles.size());
      s.triangles.push_back({&t, &chunk});
      rasterize_triangle<kCoverage>(t, rect, index, s);
    }
  }
}

}  // namespace

void rasterize_tile(const Viewport& viewport, int tile, const std::vector<SetupChunk>& chunks,
                    std::size_t num_chunks, bool want_coverage, TileScratch& s) {
  const TileRect rect = tile_rect(viewport, tile);
  std::fill(std::begin(s.key), std::end(s.key), -std::numeric_limits<float>::infinity());
  std::fill(std::begin(s.visible), std::end(s.visible), kNoTriangle);
  if (want_coverage) std::fill(std::begin(s.coverage), std::end(s.coverage), 0u);
  s.triangles.clear();
  if (want_coverage)
    rasterize_all<true>(rect, tile, chunks, num_chunks, s);
  else
    rasterize_all<false>(rect, tile, chunks, num_chunks, s);
}

}  // namespace sr
