// Alpha masks (alpha_mask.hpp): the alpha test and the scalar raster path of masked draws.
#include "alpha_mask.hpp"

#include "blend.hpp"
#include "interpolate.hpp"
#include "lines.hpp"
#include "rasterize.hpp"

#include <algorithm>
#include <cstring>
#include <optional>

namespace sr {

AlphaKind alpha_kind(const Draw& draw, uint8_t filter_override, AlphaTest& test) {
  const Material& m = draw.material;
  if (!m.alpha_mask && !m.alpha_blend) return AlphaKind::Opaque;
  const MeshData& mesh = *draw.mesh;
  const Texture* t = m.base_color_texture;
  const bool texture_alpha = t && (t->channels() == 2 || t->channels() == 4);
  test.mesh = &mesh;
  test.texture = texture_alpha ? t : nullptr;
  test.filter = !texture_alpha ? TextureFilter::Nearest
                : filter_override != kNoFilterOverride ? TextureFilter(filter_override)
                                                       : t->filter;
  test.alpha = draw.color.a;
  test.cutoff = m.alpha_cutoff;
  test.uv_periodic_axes = interp::uv_periodic_axes(m);
  if (m.alpha_blend) {
    if (texture_alpha || !mesh.colors.empty()) return AlphaKind::Blended;
    // One alpha for the whole draw: 1 covers what lies behind (opaque, the same colours), 0
    // adds nothing (not even to the alpha output).
    return !(draw.color.a > 0.0f) ? AlphaKind::Invisible
           : draw.color.a >= 1.0f ? AlphaKind::Opaque
                                  : AlphaKind::Blended;
  }
  if (texture_alpha || !mesh.colors.empty()) return AlphaKind::Masked;
  // One alpha for the whole draw.
  return draw.color.a >= m.alpha_cutoff ? AlphaKind::Opaque : AlphaKind::Invisible;
}

namespace {

// One masked triangle's alpha at a fragment, from the exact edge values: what shade_group
// computes there (the same float operations in the same order, so the same uv and derivatives
// to the bit), then the sample.
struct TriangleAlpha {
  float persp[3];
  const float (*q)[3];  // the exact weights (setup writes them for masked draws), or null
  float uv[3][2];
  float vertex_alpha[3][1];
  float sum_dx, sum_dy, uv_dx[2], uv_dy[2];
  bool varying_alpha;

  TriangleAlpha(const AlphaTest& test, const SetupChunk& chunk, uint32_t record) {
    const TriangleSetup& t = chunk.records[record];
    const TriangleShading& a = chunk.shading[record];
    const MeshData& mesh = *test.mesh;
    for (int k = 0; k < 3; ++k) persp[k] = a.persp[k];
    q = chunk.exact.empty() ? nullptr : chunk.exact[record].q;
    varying_alpha = !mesh.colors.empty();
    if (varying_alpha) {
      // Vertex alphas, mapped like any attribute (clipped pieces by their clip weights).
      if (a.clip_ref == kNoClip) {
        for (int k = 0; k < 3; ++k) vertex_alpha[k][0] = mesh.colors[a.vertex[k]].a;
      } else {
        const ivec3 f = mesh.faces[t.prim];
        const vec3* w = &chunk.clip_bary[3 * std::size_t(a.clip_ref)];
        for (int k = 0; k < 3; ++k)
          vertex_alpha[k][0] = w[k].x * mesh.colors[f[0]].a + w[k].y * mesh.colors[f[1]].a +
                               w[k].z * mesh.colors[f[2]].a;
      }
    }
    if (test.texture) {
      interp::triangle_attributes<2>(mesh, t, a, chunk, uv);
      interp::reduce_uv_period(uv, test.uv_periodic_axes);
      interp::attribute_derivatives<2>(t, a.persp, q, uv, sum_dx, sum_dy, uv_dx, uv_dy);
    }
  }

  // The fragment's alpha (the test compares it with the cutoff; blending composites with it).
  float value(const AlphaTest& test, float e0, float e1, float e2) const {
    if (!varying_alpha && !test.texture) return test.alpha;  // (a blended draw's one alpha)
    float b0, b1, b2;
    if (q) {  // (shade_kernels.hpp, exact_weights: the same operations)
      b0 = e0 * q[0][0] + e1 * q[0][1] + e2 * q[0][2];
      b1 = e0 * q[1][0] + e1 * q[1][1] + e2 * q[1][2];
      b2 = e0 * q[2][0] + e1 * q[2][1] + e2 * q[2][2];
    } else {
      b0 = e0 * persp[0]; b1 = e1 * persp[1]; b2 = e2 * persp[2];
    }
    const float inv_sum = 1.0f / (b0 + b1 + b2);
    b0 *= inv_sum; b1 *= inv_sum; b2 *= inv_sum;
    float alpha = test.alpha;
    if (varying_alpha)
      alpha = b0 * vertex_alpha[0][0] + b1 * vertex_alpha[1][0] + b2 * vertex_alpha[2][0];
    if (test.texture) {
      const float u = b0 * uv[0][0] + b1 * uv[1][0] + b2 * uv[2][0];
      const float v = b0 * uv[0][1] + b1 * uv[1][1] + b2 * uv[2][1];
      const float dudx = (uv_dx[0] - u * sum_dx) * inv_sum, dvdx = (uv_dx[1] - v * sum_dx) * inv_sum;
      const float dudy = (uv_dy[0] - u * sum_dy) * inv_sum, dvdy = (uv_dy[1] - v * sum_dy) * inv_sum;
      alpha *= sample_texture(*test.texture, test.filter, u, v, dudx, dvdx, dudy, dvdy).a;
    }
    return alpha;
  }
  bool passes(const AlphaTest& test, float e0, float e1, float e2) const {
    return value(test, e0, e1, e2) >= test.cutoff;
  }
};

// Calls fn(i, f0, f1, f2, key) for each pixel of [x0, x1] x [y0, y1] of the tile at `rect` whose
// sample (sample_x, sample_y) the record covers: i its scratch index, f_k its exact (unbiased) edge
// values as floats, key its depth key; the same values as every raster path computes.
template <typename Fn>
void each_covered(const TriangleSetup& t, int x0, int x1, int y0, int y1, const TileRect& rect,
                  int32_t sample_x, int32_t sample_y, Fn&& fn) {
  const EdgeEquations eq = edge_equations_at(t, x0, y0, sample_x, sample_y);
  int64_t row[3];
  for (int k = 0; k < 3; ++k) row[k] = eq.origin[k] - t.bias[k];  // biased: inside <=> >= 0
  const float k0 = t.key_over_area[0], k1 = t.key_over_area[1], k2 = t.key_over_area[2];
  const int64_t b0 = t.bias[0], b1 = t.bias[1], b2 = t.bias[2];
  for (int y = y0; y <= y1; ++y) {
    int64_t e0 = row[0], e1 = row[1], e2 = row[2];
    const int line = (y - rect.y0) * kTileSizePx - rect.x0;
    for (int x = x0; x <= x1; ++x, e0 += eq.step_x[0], e1 += eq.step_x[1], e2 += eq.step_x[2]) {
      if ((e0 | e1 | e2) < 0) continue;
      // The same key as every raster path: barycentric weights from the exact edge values.
      const float f0 = float(e0 + b0), f1 = float(e1 + b1), f2 = float(e2 + b2);
      fn(line + x, f0, f1, f2, f0 * k0 + f1 * k1 + f2 * k2);
    }
    row[0] += eq.step_y[0]; row[1] += eq.step_y[1]; row[2] += eq.step_y[2];
  }
}

}  // namespace

bool rasterize_masked(const AlphaTest& test, const SetupChunk& chunk, uint32_t record, int x0,
                      int x1, int y0, int y1, const TileRect& rect, uint32_t index,
                      int32_t sample_x, int32_t sample_y, bool coverage, TileScratch& s) {
  // Prepared on the first fragment that needs the test (most of a triangle's may be hidden).
  std::optional<TriangleAlpha> alpha;
  bool won = false;
  each_covered(chunk.records[record], x0, x1, y0, y1, rect, sample_x, sample_y,
               [&](int i, float f0, float f1, float f2, float key) {
    if (!coverage && !(key > s.key[i] * s.tie)) return;  // hidden: the test would not change that
    if (!alpha) alpha.emplace(test, chunk, record);
    if (!alpha->passes(test, f0, f1, f2)) return;
    if (coverage) ++s.coverage[i];
    if (key > s.key[i] * s.tie) {  // on a tie (kTieFactor*) the earlier triangle stays
      s.key[i] = key;
      s.visible[i] = index;
      won = true;
    }
  });
  return won;
}

int gather_blended(const std::vector<SetupChunk>& chunks, std::size_t begin, std::size_t end,
                   int tile, const TileRect& rect, const AlphaTest* const* tests,
                   const TileScratch& opaque, bool first, BlendScratch& s) {
  // Only s.box is written; the layers' entries outside it stay empty from the tile's first walk
  // (whole arrays: the shading kernels read every pixel of the tile, and past it).
  const TileRect& box = s.box;
  for (int y = box.y0; y < box.y1; ++y) {
    const int row = (y - rect.y0) * kTileSizePx - rect.x0;
    std::fill(s.count + row + box.x0, s.count + row + box.x1, uint8_t(0));
    if (first) std::fill(s.total + row + box.x0, s.total + row + box.x1, 0u);
    if (!first)
      for (TileScratch& layer : s.layer)
        std::fill(layer.visible + row + box.x0, layer.visible + row + box.x1, kNoTriangle);
  }
  if (first)
    for (TileScratch& layer : s.layer)
      std::fill(std::begin(layer.visible), std::end(layer.visible), kNoTriangle);
  std::vector<VisibleTriangle>& list = s.layer[0].triangles;
  if (first) list.clear();
  uint32_t index = 0;
  const float tie = opaque.tie;
  for (std::size_t c = begin; c < end; ++c) {
    const SetupChunk& chunk = chunks[c];
    const uint32_t records_end = chunk.tile_begin[tile + 1];
    for (uint32_t r = chunk.tile_begin[tile]; r < records_end; ++r, ++index) {
      const uint32_t record = chunk.tile_records[r];
      const TriangleSetup& t = chunk.records[record];
      if (first) list.push_back({&t, &chunk});
      const int x0 = std::max(int(t.x0), rect.x0), x1 = std::min(int(t.x1), rect.x1 - 1);
      const int y0 = std::max(int(t.y0), rect.y0), y1 = std::min(int(t.y1), rect.y1 - 1);
      if (x0 > x1 || y0 > y1) continue;
      const AlphaTest& test = *tests[t.draw];
      std::optional<TriangleAlpha> alpha;
      each_covered(t, x0, x1, y0, y1, rect, opaque.sample_x, opaque.sample_y,
                   [&](int i, float f0, float f1, float f2, float key) {
        // In front of the opaque surface, as the depth test decides between the two: a draw
        // after it must beat its key, one before it only not be beaten (lines and points are
        // drawn after every triangle). Only a near tie asks which was drawn first.
        const uint32_t seen = opaque.visible[i];
        if (seen != kNoTriangle) {
          const float other = opaque.key[i];
          if (!(key > other * tie)) {  // not clearly nearer
            if (other > key * tie) return;  // clearly farther
            const bool later = seen == kPrimitivePixel || t.draw > opaque.triangles[seen].tri->draw;
            if (later) return;
          }
        }
        if (first) ++s.total[i];
        else if (s.taken[i] >= s.total[i] ||
                 !blend_before(s.floor_key[i], s.floor_index[i], key, index, tie))
          return;  // composited by an earlier walk
        const int n = s.count[i];
        if (n == kBlendLayers &&
            !blend_before(key, index, s.layer[kBlendLayers - 1].key[i],
                          s.layer[kBlendLayers - 1].visible[i], tie))
          return;
        if (!alpha) alpha.emplace(test, chunk, record);
        const float a = alpha->value(test, f0, f1, f2);
        // Insert, nearest first (the farthest of a full buffer drops out).
        int at = n < kBlendLayers ? n : kBlendLayers - 1;
        for (; at > 0 && blend_before(key, index, s.layer[at - 1].key[i], s.layer[at - 1].visible[i], tie);
             --at) {
          s.alpha_of[at][i] = s.alpha_of[at - 1][i];
          s.layer[at].key[i] = s.layer[at - 1].key[i];
          s.layer[at].visible[i] = s.layer[at - 1].visible[i];
        }
        s.alpha_of[at][i] = a;
        s.layer[at].key[i] = key;
        s.layer[at].visible[i] = index;
        s.count[i] = uint8_t(n < kBlendLayers ? n + 1 : n);
      });
    }
  }
  int most = 0;
  for (int y = box.y0; y < box.y1; ++y)
    for (int x = box.x0; x < box.x1; ++x)
      most = std::max(most, int(s.count[(y - rect.y0) * kTileSizePx + x - rect.x0]));
  return most;
}

}  // namespace sr
