// Shade stage: perspective-correct barycentrics, attribute interpolation, unlit / Lambert.
#include "shade.hpp"

#include <algorithm>
#include <cmath>

namespace sr {

namespace {

// Unit vector in float, or zero for a zero (or non-finite) vector.
inline vec3 unit(const dvec3& v) {
  const double len = glm::length(v);
  return len > 0.0 && std::isfinite(len) ? vec3(v / len) : vec3(0.0f);
}

// Prepares one visible triangle: its exact edge functions relative to the tile, and its
// attributes at its own three vertices. A clipped triangle's vertices carry weights of the
// source face's corners; attributes are linear in those weights, so they are mapped here once.
ShadeTriangle prepare(const ShadeParams& p, const VisibleTriangle& vt, const TileRect& rect) {
  const TriangleSetup& t = *vt.tri;
  const ShadeDraw& d = p.draws[t.draw];
  ShadeTriangle s;
  const int64_t px = int64_t(rect.x0) * kSubpixelOne + kSubpixelHalf;
  const int64_t py = int64_t(rect.y0) * kSubpixelOne + kSubpixelHalf;
  for (int k = 0; k < 3; ++k) {
    const int a = kEdgeStart[k], b = kEdgeEnd[k];
    const int64_t dx = t.x[b] - t.x[a], dy = t.y[b] - t.y[a];
    s.edge_origin[k] = dx * (py - t.y[a]) - dy * (px - t.x[a]);
    s.edge_step_x[k] = -dy * kSubpixelOne;
    s.edge_step_y[k] = dx * kSubpixelOne;
    s.persp[k] = float(double(t.inv_w[k]) / double(t.area2));
  }
  {
    const MeshData& mesh = *d.mesh;
    const ivec3 f = mesh.faces[t.prim];
    // Normals are transformed and normalised in double: a float cross product or a scaled
    // normal can overflow (a triangle 1e20 units wide, a pose scaling by 0.1).
    vec3 normal_src[3], color_src[3];
    if (!mesh.normals.empty()) {
      for (int c = 0; c < 3; ++c) normal_src[c] = unit(d.normal_to_world * dvec3(mesh.normals[f[c]]));
    } else {  // no vertex normals => flat: the counter-clockwise face normal
      const dvec3 p0(mesh.positions[f.x]);
      const dvec3 n = d.normal_to_world *
                      glm::cross(dvec3(mesh.positions[f.y]) - p0, dvec3(mesh.positions[f.z]) - p0);
      normal_src[0] = normal_src[1] = normal_src[2] = unit(n);
    }
    if (t.back_facing)  // two-sided: the side the camera sees
      for (vec3& n : normal_src) n = -n;
    for (int c = 0; c < 3; ++c)
      color_src[c] = mesh.colors.empty() ? vec3(d.color) : vec3(mesh.colors[f[c]]);
    if (t.clip_ref == kNoClip) {
      for (int k = 0; k < 3; ++k) {
        s.normal[k] = normal_src[t.corner[k]];
        s.color[k] = color_src[t.corner[k]];
      }
    } else {
      const vec3* weights = &vt.chunk->clip_bary[3 * std::size_t(t.clip_ref)];
      for (int k = 0; k < 3; ++k) {
        const vec3 w = weights[k];
        s.normal[k] = w.x * normal_src[0] + w.y * normal_src[1] + w.z * normal_src[2];
        s.color[k] = w.x * color_src[0] + w.y * color_src[1] + w.z * color_src[2];
      }
    }
  }
  return s;
}

inline uint8_t to_unorm8(float v) { return uint8_t(std::clamp(v, 0.0f, 1.0f) * 255.0f + 0.5f); }

template <bool kColor, bool kLit, bool kNormal>
void shade(const ShadeParams& p, const TileRect& rect, const TileScratch& raster,
           ShadeScratch& scratch) {
  constexpr bool kAttributes = kColor || kNormal;
  const Framebuffer& fb = *p.framebuffer;
  // Local copies: stores through uint8_t* may alias anything, so members would be reloaded.
  uint8_t* const color = fb.color;
  float* const depth = fb.depth;
  bool* const mask = fb.mask;
  float* const normal = fb.normal;
  int32_t* const triangle_id = fb.triangle_id;
  int32_t* const instance_id = fb.instance_id;
  uint32_t* const coverage = fb.coverage;
  const std::size_t width = std::size_t(fb.width);
  const bool orthographic = p.orthographic;
  const vec3 to_light = p.to_light_world;
  const float ambient = p.ambient, diffuse = 1.0f - p.ambient;
  const uint8_t bg0 = p.background[0], bg1 = p.background[1], bg2 = p.background[2];

  if constexpr (kAttributes) {
    scratch.slot.assign(raster.triangles.size(), kNoTriangle);
    scratch.triangles.clear();
  }

  for (int y = rect.y0; y < rect.y1; ++y) {
    const int row = (y - rect.y0) * kTileSizePx;
    for (int x = rect.x0; x < rect.x1; ++x) {
      const int i = row + (x - rect.x0);
      const std::size_t o = std::size_t(y) * width + std::size_t(x);
      const uint32_t v = raster.visible[i];
      if (coverage) coverage[o] = raster.coverage[i];
      if (v == kNoTriangle) {  // Background.
        if (depth) depth[o] = 0.0f;
        if (mask) mask[o] = false;
        if (triangle_id) triangle_id[o] = -1;
        if (instance_id) instance_id[o] = -1;
        if constexpr (kNormal) normal[3 * o] = normal[3 * o + 1] = normal[3 * o + 2] = 0.0f;
        if constexpr (kColor) {
          color[3 * o] = bg0;
          color[3 * o + 1] = bg1;
          color[3 * o + 2] = bg2;
        }
        continue;
      }
      if (depth) depth[o] = depth_from_key(raster.key[i], orthographic);
      if (mask) mask[o] = true;
      const TriangleSetup& t = *raster.triangles[v].tri;
      if (triangle_id) triangle_id[o] = int32_t(t.prim);
      if (instance_id) instance_id[o] = p.draws[t.draw].instance_id;
      if constexpr (kAttributes) {
        if (scratch.slot[v] == kNoTriangle) {  // first pixel of this triangle in the tile
          scratch.slot[v] = uint32_t(scratch.triangles.size());
          scratch.triangles.push_back(prepare(p, raster.triangles[v], rect));
        }
        const ShadeTriangle& s = scratch.triangles[scratch.slot[v]];
        // Perspective-correct barycentrics from the exact edge values (all >= 0 here).
        const int64_t dx = x - rect.x0, dy = y - rect.y0;
        float b[3];
        for (int k = 0; k < 3; ++k)
          b[k] = float(s.edge_origin[k] + s.edge_step_x[k] * dx + s.edge_step_y[k] * dy) * s.persp[k];
        const float inv_sum = 1.0f / (b[0] + b[1] + b[2]);
        b[0] *= inv_sum; b[1] *= inv_sum; b[2] *= inv_sum;
        vec3 n(0.0f);
        if constexpr (kLit || kNormal) {
          n = b[0] * s.normal[0] + b[1] * s.normal[1] + b[2] * s.normal[2];
          const float len2 = glm::dot(n, n);
          n = len2 > 0.0f ? n * (1.0f / std::sqrt(len2)) : vec3(0.0f);
        }
        if constexpr (kNormal) {
          normal[3 * o] = n.x;
          normal[3 * o + 1] = n.y;
          normal[3 * o + 2] = n.z;
        }
        if constexpr (kColor) {
          vec3 c = b[0] * s.color[0] + b[1] * s.color[1] + b[2] * s.color[2];
          if constexpr (kLit) c *= ambient + diffuse * std::max(0.0f, glm::dot(n, to_light));
          color[3 * o] = to_unorm8(c.x);
          color[3 * o + 1] = to_unorm8(c.y);
          color[3 * o + 2] = to_unorm8(c.z);
        }
      }
    }
  }
}

using ShadeFn = void (*)(const ShadeParams&, const TileRect&, const TileScratch&, ShadeScratch&);

// Feature set chosen once per draw: [color][lit][normal].
constexpr ShadeFn kShadeTable[2][2][2] = {
    {{shade<false, false, false>, shade<false, false, true>},
     {shade<false, false, false>, shade<false, false, true>}},  // lighting without colour is moot
    {{shade<true, false, false>, shade<true, false, true>},
     {shade<true, true, false>, shade<true, true, true>}},
};

}  // namespace

void shade_tile(const ShadeParams& params, const Viewport& viewport, int tile,
                const TileScratch& raster, ShadeScratch& scratch) {
  const Framebuffer& fb = *params.framebuffer;
  const ShadeFn fn = kShadeTable[fb.color != nullptr][params.shading == Shading::Lambert]
                                [fb.normal != nullptr];
  fn(params, tile_rect(viewport, tile), raster, scratch);
}

}  // namespace sr
