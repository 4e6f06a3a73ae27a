// Alpha blending (blend.hpp): the tile's blended layers, peeled, shaded and composited.
#include "blend.hpp"

#include <algorithm>

namespace sr {

bool blend_tile(const BlendParams& params, const TileRect& rect, int tile,
                const TileScratch& opaque, const ShadeScratch& opaque_shade, BlendScratch& s) {
  // The pixels the tile's blended records may cover (most tiles of a scene have none).
  TileRect& box = s.box;
  box = {rect.x1, rect.y1, rect.x0 - 1, rect.y0 - 1};
  for (std::size_t c = params.begin; c < params.end; ++c) {
    const SetupChunk& chunk = (*params.chunks)[c];
    for (uint32_t r = chunk.tile_begin[tile]; r < chunk.tile_begin[tile + 1]; ++r) {
      const TriangleSetup& t = chunk.records[chunk.tile_records[r]];
      box.x0 = std::min(box.x0, int(t.x0)); box.y0 = std::min(box.y0, int(t.y0));
      box.x1 = std::max(box.x1, int(t.x1)); box.y1 = std::max(box.y1, int(t.y1));
    }
  }
  box = {std::max(box.x0, rect.x0), std::max(box.y0, rect.y0), std::min(box.x1 + 1, rect.x1),
         std::min(box.y1 + 1, rect.y1)};  // (half-open, like rect)
  if (box.x0 >= box.x1 || box.y0 >= box.y1) return false;
  const int width = rect.x1 - rect.x0;
  for (int y = box.y0; y < box.y1; ++y) {
    const int row = (y - rect.y0) * kTileSizePx - rect.x0;
    for (int x = box.x0; x < box.x1; ++x) {
      s.taken[row + x] = 0;
      s.transmit[row + x] = 1.0f;
      s.sum[0][row + x] = s.sum[1][row + x] = s.sum[2][row + x] = 0.0f;
      s.touched[row + x] = false;
      s.hit[row + x] = kNoTriangle;
    }
  }
  const bool colour = params.shade && params.shade->color;
  bool any = false;
  for (bool first = true;; first = false) {
    const int most = gather_blended(*params.chunks, params.begin, params.end, tile, rect,
                                    params.tests, opaque, first, s);
    if (most == 0) break;
    any = true;
    if (params.shade) {
      const TileScratch* rasters[kBlendLayers];
      ShadeScratch* outs[kBlendLayers];
      for (int l = 0; l < most; ++l) {
        if (l > 0 && first) s.layer[l].triangles = s.layer[0].triangles;
        rasters[l] = &s.layer[l];
        outs[l] = &s.shaded[l];
      }
      params.kernels->deferred(*params.shade, rect, rasters, outs, most);
    }
    // Front to back; a pixel with fragments left takes them in the next walk.
    bool more = false;
    for (int y = box.y0; y < box.y1; ++y) {
      const int row = (y - rect.y0) * kTileSizePx - rect.x0;
      for (int x = box.x0; x < box.x1; ++x) {
        const int i = row + x;
        // (At most the fragments left: see BlendScratch::total.)
        const int n = int(std::min<uint32_t>(s.count[i], s.total[i] - s.taken[i]));
        if (n == 0) continue;
        s.touched[i] = true;
        float t = s.transmit[i];
        for (int l = 0; l < n; ++l) {
          const float raw = s.alpha_of[l][i];
          const float a = !(raw > 0.0f) ? 0.0f : raw < 1.0f ? raw : 1.0f;
          if (colour) {
            const float w = t * a;
            for (int c = 0; c < 3; ++c) s.sum[c][i] += w * s.shaded[l].rgb[c][i];
          }
          if (params.surfaces && s.hit[i] == kNoTriangle && a >= params.threshold) {
            s.hit[i] = s.layer[l].visible[i];
            s.hit_key[i] = s.layer[l].key[i];
            if (params.normals)
              for (int c = 0; c < 3; ++c) s.hit_normal[c][i] = s.shaded[l].normal[c][i];
          }
          t *= 1.0f - a;
        }
        s.transmit[i] = t;
        s.taken[i] += uint32_t(n);
        if (!(t > 0.0f)) s.taken[i] = s.total[i];  // nothing behind shows through
        s.floor_key[i] = s.layer[n - 1].key[i];
        s.floor_index[i] = s.layer[n - 1].visible[i];
        more |= s.taken[i] < s.total[i];
      }
    }
    if (!more) break;
  }
  if (!any) return false;
  const vec3& background = params.background_linear;
  for (int y = rect.y0; y < rect.y1; ++y) {
    const int row = (y - rect.y0) * kTileSizePx;
    const bool rows = y >= box.y0 && y < box.y1;
    for (int x = 0; x < width; ++x) {
      const int i = row + x;
      const uint32_t seen = opaque.visible[i];
      const bool surface = seen != kNoTriangle;
      const int px = rect.x0 + x;
      if (!(rows && px >= box.x0 && px < box.x1 && s.touched[i])) {
        s.seen[i] = seen;
        s.alpha[i] = surface ? 1.0f : 0.0f;
        if (params.shade)
          for (int c = 0; c < 3; ++c) s.color[c][i] = s.radiance[c][i] = opaque_shade.rgb[c][i];
        continue;
      }
      const float t = s.transmit[i];
      s.seen[i] = 0;  // (any entry but kNoTriangle)
      s.alpha[i] = surface ? 1.0f : 1.0f - t;
      if (params.shade)
        for (int c = 0; c < 3; ++c) {
          const float behind = surface ? opaque_shade.rgb[c][i] : 0.0f;
          s.radiance[c][i] = s.sum[c][i] + t * behind;
          s.color[c][i] = s.sum[c][i] + t * (surface ? behind : background[c]);
        }
    }
  }
  return true;
}

namespace {

// Appends the tile's blended records to `raster`'s list: returns the first one's index there.
uint32_t append_blended(const BlendScratch& s, TileScratch& raster) {
  const uint32_t base = uint32_t(raster.triangles.size());
  for (const VisibleTriangle& vt : s.layer[0].triangles) {
    raster.triangles.push_back(vt);
    raster.flags |= vt.tri->flags;
  }
  return base;
}

// Whether pixel i (tile-relative x, y) lies in the walked box and has a recorded fragment.
inline bool has_hit(const BlendScratch& s, const TileRect& rect, int x, int y, int i) {
  const int px = rect.x0 + x, py = rect.y0 + y;
  return px >= s.box.x0 && px < s.box.x1 && py >= s.box.y0 && py < s.box.y1 &&
         s.hit[i] != kNoTriangle;
}

}  // namespace

void take_blend_surfaces(const BlendParams& params, const TileRect& rect, const BlendScratch& s,
                         TileScratch& raster, float* const normal[3]) {
  const uint32_t base = append_blended(s, raster);
  for (int y = 0; y < rect.y1 - rect.y0; ++y)
    for (int x = 0; x < rect.x1 - rect.x0; ++x) {
      const int i = y * kTileSizePx + x;
      if (!has_hit(s, rect, x, y, i)) continue;
      raster.visible[i] = base + s.hit[i];
      raster.key[i] = s.hit_key[i];
      if (params.normals)
        for (int c = 0; c < 3; ++c) normal[c][i] = s.hit_normal[c][i];
    }
}

void clear_blend_surfaces(const TileRect& rect, BlendScratch& s) {
  for (int y = 0; y < rect.y1 - rect.y0; ++y)
    std::fill_n(s.best_rank + y * kTileSizePx, rect.x1 - rect.x0, BlendScratch::kNoRank);
}

void blend_surface_sample(const BlendParams& params, const TileRect& rect, int rank, BlendScratch& s) {
  for (int y = 0; y < rect.y1 - rect.y0; ++y)
    for (int x = 0; x < rect.x1 - rect.x0; ++x) {
      const int i = y * kTileSizePx + x;
      if (!has_hit(s, rect, x, y, i) || s.best_rank[i] <= rank) continue;
      s.best_rank[i] = uint8_t(rank);
      s.best[i] = s.hit[i];  // (every sample lists the tile's blended records alike)
      s.best_key[i] = s.hit_key[i];
      if (params.normals)
        for (int c = 0; c < 3; ++c) s.best_normal[c][i] = s.hit_normal[c][i];
    }
}

void take_blend_surfaces_multisample(const BlendParams& params, const TileRect& rect,
                                     const BlendScratch& s, const uint8_t* order,
                                     const uint8_t* rank_of, TileScratch& resolved,
                                     int32_t* representative, float* const normal[3]) {
  const uint32_t base = append_blended(s, resolved);
  for (int y = 0; y < rect.y1 - rect.y0; ++y)
    for (int x = 0; x < rect.x1 - rect.x0; ++x) {
      const int i = y * kTileSizePx + x;
      const int rank = s.best_rank[i];
      if (rank == BlendScratch::kNoRank) continue;
      if (resolved.visible[i] != kNoTriangle && rank_of[representative[i]] < rank) continue;
      resolved.visible[i] = base + s.best[i];
      resolved.key[i] = s.best_key[i];
      representative[i] = order[rank];
      if (params.normals)
        for (int c = 0; c < 3; ++c) normal[c][i] = s.best_normal[c][i];
    }
}

}  // namespace sr
