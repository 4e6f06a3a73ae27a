// Alpha masks (alpha_mask.hpp): the alpha test and the scalar raster path of masked draws.
#include "alpha_mask.hpp"

#include "interpolate.hpp"
#include "rasterize.hpp"

#include <optional>

namespace sr {

AlphaKind alpha_kind(const Draw& draw, uint8_t filter_override, AlphaTest& test) {
  const Material& m = draw.material;
  if (!m.alpha_mask) return AlphaKind::Opaque;
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

  bool passes(const AlphaTest& test, float e0, float e1, float e2) const {
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
    return alpha >= test.cutoff;
  }
};

}  // namespace

bool rasterize_masked(const AlphaTest& test, const SetupChunk& chunk, uint32_t record, int x0,
                      int x1, int y0, int y1, const TileRect& rect, uint32_t index,
                      int32_t sample_x, int32_t sample_y, bool coverage, TileScratch& s) {
  const TriangleSetup& t = chunk.records[record];
  const EdgeEquations eq = edge_equations_at(t, x0, y0, sample_x, sample_y);
  int64_t row[3];
  for (int k = 0; k < 3; ++k) row[k] = eq.origin[k] - t.bias[k];  // biased: inside <=> >= 0
  const float k0 = t.key_over_area[0], k1 = t.key_over_area[1], k2 = t.key_over_area[2];
  const int64_t b0 = t.bias[0], b1 = t.bias[1], b2 = t.bias[2];
  // Prepared on the first fragment that needs the test (most of a triangle's may be hidden).
  std::optional<TriangleAlpha> alpha;
  bool won = false;
  for (int y = y0; y <= y1; ++y) {
    int64_t e0 = row[0], e1 = row[1], e2 = row[2];
    const int line = (y - rect.y0) * kTileSizePx - rect.x0;
    for (int x = x0; x <= x1; ++x, e0 += eq.step_x[0], e1 += eq.step_x[1], e2 += eq.step_x[2]) {
      if ((e0 | e1 | e2) < 0) continue;
      const int i = line + x;
      // The same key as every raster path: barycentric weights from the exact edge values.
      const float f0 = float(e0 + b0), f1 = float(e1 + b1), f2 = float(e2 + b2);
      const float key = f0 * k0 + f1 * k1 + f2 * k2;
      if (!coverage && !(key > s.key[i] * s.tie)) continue;  // hidden: the test would not change that
      if (!alpha) alpha.emplace(test, chunk, record);
      if (!alpha->passes(test, f0, f1, f2)) continue;
      if (coverage) ++s.coverage[i];
      if (key > s.key[i] * s.tie) {  // on a tie (kTieFactor*) the earlier triangle stays
        s.key[i] = key;
        s.visible[i] = index;
        won = true;
      }
    }
    row[0] += eq.step_y[0]; row[1] += eq.step_y[1]; row[2] += eq.step_y[2];
  }
  return won;
}

}  // namespace sr
