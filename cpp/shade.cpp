// Shade stage: perspective-correct barycentrics, attribute interpolation, unlit / Lambert.
#include "shade.hpp"

#include <algorithm>
#include <cmath>

namespace sr {

namespace {

// Weights of the source face's three corners at the centre of pixel (x, y), perspective-correct.
vec3 source_barycentrics(const VisibleTriangle& vt, int x, int y) {
  const TriangleSetup& t = *vt.tri;
  const int64_t px = int64_t(x) * kSubpixelOne + kSubpixelHalf;
  const int64_t py = int64_t(y) * kSubpixelOne + kSubpixelHalf;
  double w[3], sum = 0.0;
  for (int k = 0; k < 3; ++k) {
    const int a = (k + 1) % 3, b = (k + 2) % 3;
    const int64_t e = int64_t(t.x[b] - t.x[a]) * (py - t.y[a]) - int64_t(t.y[b] - t.y[a]) * (px - t.x[a]);
    // bary_screen_k = e / area2; dividing by w_k (and renormalising) makes it perspective-correct.
    w[k] = double(e) * t.inv_w[k];
    sum += w[k];
  }
  vec3 bary_source(0.0f);
  if (t.clip_ref == kNoClip) {
    for (int k = 0; k < 3; ++k) bary_source[t.corner[k]] = float(w[k] / sum);
  } else {
    const vec3* src = &vt.chunk->clip_bary[3 * std::size_t(t.clip_ref)];
    for (int k = 0; k < 3; ++k) bary_source += float(w[k] / sum) * src[k];
  }
  return bary_source;
}

vec3 world_normal(const ShadeDraw& d, const TriangleSetup& t, const vec3& bary) {
  const MeshData& mesh = *d.mesh;
  const ivec3 f = mesh.faces[t.prim];
  vec3 n_model;
  if (!mesh.normals.empty()) {
    n_model = bary.x * mesh.normals[f.x] + bary.y * mesh.normals[f.y] + bary.z * mesh.normals[f.z];
  } else {  // no vertex normals => flat: the counter-clockwise face normal
    const vec3 p0 = mesh.positions[f.x];
    n_model = glm::cross(mesh.positions[f.y] - p0, mesh.positions[f.z] - p0);
  }
  vec3 n = d.normal_to_world * n_model;
  const float len = glm::length(n);
  n = len > 0.0f ? n / len : vec3(0.0f);
  return t.back_facing ? -n : n;  // two-sided: the side the camera sees
}

inline uint8_t to_unorm8(float v) { return uint8_t(std::clamp(v, 0.0f, 1.0f) * 255.0f + 0.5f); }

template <bool kColor, bool kLit, bool kNormal>
void shade(const ShadeParams& p, const TileRect& rect, const TileScratch& s) {
  Framebuffer& fb = *p.framebuffer;
  for (int y = rect.y0; y < rect.y1; ++y) {
    for (int x = rect.x0; x < rect.x1; ++x) {
      const int i = (y - rect.y0) * kTileSizePx + (x - rect.x0);
      const std::size_t o = std::size_t(y) * fb.width + x;
      const uint32_t v = s.visible[i];
      if (fb.coverage) fb.coverage[o] = s.coverage[i];
      if (v == kNoTriangle) {  // Background.
        if (fb.depth) fb.depth[o] = 0.0f;
        if (fb.mask) fb.mask[o] = false;
        if (fb.triangle_id) fb.triangle_id[o] = -1;
        if (fb.instance_id) fb.instance_id[o] = -1;
        if constexpr (kNormal) fb.normal[3 * o] = fb.normal[3 * o + 1] = fb.normal[3 * o + 2] = 0.0f;
        if constexpr (kColor) for (int c = 0; c < 3; ++c) fb.color[3 * o + c] = p.background[c];
        continue;
      }
      const VisibleTriangle& vt = s.triangles[v];
      const TriangleSetup& t = *vt.tri;
      const ShadeDraw& d = p.draws[t.draw];
      if (fb.depth) fb.depth[o] = depth_from_key(s.key[i], p.orthographic);
      if (fb.mask) fb.mask[o] = true;
      if (fb.triangle_id) fb.triangle_id[o] = int32_t(t.prim);
      if (fb.instance_id) fb.instance_id[o] = d.instance_id;
      if constexpr (kColor || kNormal) {
        const bool smooth = !d.mesh->normals.empty();
        const bool vertex_colors = kColor && !d.mesh->colors.empty();
        const bool need_bary = ((kLit || kNormal) && smooth) || vertex_colors;
        const vec3 bary = need_bary ? source_barycentrics(vt, x, y) : vec3(0.0f);
        vec3 n(0.0f);
        if constexpr (kLit || kNormal) n = world_normal(d, t, bary);
        if constexpr (kNormal)
          for (int c = 0; c < 3; ++c) fb.normal[3 * o + c] = n[c];
        if constexpr (kColor) {
          vec3 base;
          if (vertex_colors) {
            const ivec3 f = d.mesh->faces[t.prim];
            const auto& col = d.mesh->colors;
            base = vec3(bary.x * col[f.x] + bary.y * col[f.y] + bary.z * col[f.z]);
          } else {
            base = vec3(d.color);
          }
          float light = 1.0f;
          if constexpr (kLit)
            light = p.ambient + (1.0f - p.ambient) * std::max(0.0f, glm::dot(n, p.to_light_world));
          for (int c = 0; c < 3; ++c) fb.color[3 * o + c] = to_unorm8(base[c] * light);
        }
      }
    }
  }
}

using ShadeFn = void (*)(const ShadeParams&, const TileRect&, const TileScratch&);

// Feature set chosen once per draw: [color][lit][normal].
constexpr ShadeFn kShadeTable[2][2][2] = {
    {{shade<false, false, false>, shade<false, false, true>},
     {shade<false, false, false>, shade<false, false, true>}},  // lighting without colour is moot
    {{shade<true, false, false>, shade<true, false, true>},
     {shade<true, true, false>, shade<true, true, true>}},
};

}  // namespace

void shade_tile(const ShadeParams& params, const Viewport& viewport, int tile,
                const TileScratch& scratch) {
  const Framebuffer& fb = *params.framebuffer;
  const ShadeFn fn = kShadeTable[fb.color != nullptr][params.shading == Shading::Lambert]
                                [fb.normal != nullptr];
  fn(params, tile_rect(viewport, tile), scratch);
}

}  // namespace sr
