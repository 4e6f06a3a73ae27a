// Interpolation: what shading reads of a visible triangle, fetched once per triangle (prepare),
// and the per-pixel machinery to interpolate it perspective-correctly from exact edge values.
#pragma once

#include "normals.hpp"
#include "rasterize.hpp"
#include "shade.hpp"
#include "shade_models.hpp"
#include "simd.hpp"

#include <cmath>

namespace sr {
namespace interp {

// The triangle's flat normal in world space: the counter-clockwise face normal of corners
// c0, c1, c2, in double (a float cross product or a scaled normal can overflow: a triangle 1e20
// units wide, a pose scaling by 0.1). Unit for any face of float32 corners that is not
// degenerate in double: the cross product is at most ~1e78, the normal matrix's largest entry
// in [1, 2) (make_draw_transform), and unit() rescales a result whose squared length over- or
// underflows (a pose scaling one axis by 1e-160). Where corner c0's angle is below ~2^-30 rad
// (c0 1e19 away from the other two: both edges round to the same double, and their cross product
// is 0) the cross product has cancelled, and is taken again at the corner of the largest angle
// (well_conditioned_cross); every other face keeps corner c0's, so the same bits as before.
inline vec3 flat_normal(const ShadeDraw& d, int32_t c0, int32_t c1, int32_t c2) {
  const vec3* positions = d.mesh->positions.data();
  const dvec3 p0(positions[c0]), p1(positions[c1]), p2(positions[c2]);
  const dvec3 e1 = p1 - p0, e2 = p2 - p0;
  dvec3 n = glm::cross(e1, e2);
  // |n|^2 < 2^-60 (e1.e2)^2: the angle at c0 below ~2^-30 (|e1|^2 |e2|^2 = |n|^2 + (e1.e2)^2).
  // (Written as a product of the dot with itself: one dot product fewer than the edges' lengths.)
  const double e12 = glm::dot(e1, e2);
  if (__builtin_expect(!(glm::dot(n, n) >= 0x1p-60 * (e12 * e12)), 0))
    n = well_conditioned_cross(positions, c0, c1, c2);
  return unit(d.normal_to_world * n);
}

// A mesh vertex in world space (models that read positions).
inline vec3 world_position(const ShadeDraw& d, int32_t vertex) {
  return vec3(d.model_to_world * dvec4(dvec3(d.mesh->positions[vertex]), 1.0));
}

// The first N floats of a vertex's attributes: its uvs, the one attribute array so far (zero
// where the mesh has none).
template <int N>
inline void vertex_attributes(const MeshData& mesh, int32_t vertex, float* out) {
  static_assert(N == 2, "uvs are the only vertex attribute array so far");
  const vec2 uv = mesh.uvs.empty() ? vec2(0.0f) : mesh.uvs[vertex];
  out[0] = uv.x;
  out[1] = uv.y;
}

// The first N attributes at a record's three vertices: its mesh vertices' (unclipped), or, for a
// piece of a clipped face, the source corners' mapped by the record's clip weights.
template <int N>
inline void triangle_attributes(const MeshData& mesh, const TriangleSetup& t,
                                const TriangleShading& a, const SetupChunk& chunk,
                                float (*out)[N]) {
  if (a.clip_ref == kNoClip) {
    for (int k = 0; k < 3; ++k) vertex_attributes<N>(mesh, a.vertex[k], out[k]);
    return;
  }
  const ivec3 f = mesh.faces[t.prim];
  const vec3* weights = &chunk.clip_bary[3 * std::size_t(a.clip_ref)];
  float src[3][N];
  for (int c = 0; c < 3; ++c) vertex_attributes<N>(mesh, f[c], src[c]);
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < N; ++j)
      out[k][j] = weights[k].x * src[0][j] + weights[k].y * src[1][j] + weights[k].z * src[2][j];
}

// Texture coordinates far from 0 lose their fraction in float32 (at 1e6 they step by 1/16) when
// interpolated, before the wrap reduces them. Along an axis where every texture of the draw wraps
// periodically (uv_periodic_axes), an even integer near the triangle's first uv is
// taken from all three: the same texels, the fraction kept. Derivatives do not change.
// Bit 0 (u) / bit 1 (v): every texture of the material wraps periodically along that axis
// (repeat, period 1, or mirror, period 2), so its uvs may be shifted by an even integer.
inline uint8_t uv_periodic_axes(const Material& m) {
  uint8_t axes = 3;
  for (const Texture* t : m.textures()) {
    if (!t) continue;
    if (t->wrap_u == Wrap::Clamp) axes &= uint8_t(~1u);
    if (t->wrap_v == Wrap::Clamp) axes &= uint8_t(~2u);
  }
  return axes;
}

inline void reduce_uv_period(float (*uv)[2], uint8_t periodic_axes) {
  for (int j = 0; j < 2; ++j) {
    if (!(periodic_axes & (1u << j))) continue;
    const float offset = 2.0f * std::floor(uv[0][j] * 0.5f);
    if (offset == 0.0f || !std::isfinite(offset)) continue;
    for (int k = 0; k < 3; ++k) uv[k][j] -= offset;
  }
}

// Screen derivatives of a record's unnormalised perspective weights b_j (E_j persp_j, or with
// `q` the exact weights sum_k q[j][k] E_k): of their sum (sum_dx, sum_dy) and of the attributes
// they weight (attr_dx, attr_dy). E_k (edge kEdgeStart[k] -> kEdgeEnd[k], the weight of vertex
// k) steps by -dy * one per pixel in x and dx * one in y. Per pixel then
// d(attr)/dx = (attr_dx - attr * sum_dx) / sum b_j.
template <int N>
inline void attribute_derivatives(const TriangleSetup& t, const float* persp, const float (*q)[3],
                                  const float (*attr)[N], float& sum_dx, float& sum_dy,
                                  float* attr_dx, float* attr_dy) {
  double ex[3], ey[3];  // E_k's steps
  for (int k = 0; k < 3; ++k) {
    const int i = kEdgeStart[k], j = kEdgeEnd[k];
    ex[k] = -double(int64_t(t.y[j]) - t.y[i]) * kSubpixelOne;
    ey[k] = double(int64_t(t.x[j]) - t.x[i]) * kSubpixelOne;
  }
  double sx = 0.0, sy = 0.0, ax[N] = {}, ay[N] = {};
  for (int k = 0; k < 3; ++k) {
    const double gx = q ? q[k][0] * ex[0] + q[k][1] * ex[1] + q[k][2] * ex[2] : ex[k] * persp[k];
    const double gy = q ? q[k][0] * ey[0] + q[k][1] * ey[1] + q[k][2] * ey[2] : ey[k] * persp[k];
    sx += gx;
    sy += gy;
    for (int c = 0; c < N; ++c) {
      ax[c] += gx * attr[k][c];
      ay[c] += gy * attr[k][c];
    }
  }
  sum_dx = float(sx);
  sum_dy = float(sy);
  for (int c = 0; c < N; ++c) {
    attr_dx[c] = float(ax[c]);
    attr_dy[c] = float(ay[c]);
  }
}

// Prepares one visible triangle into `s`: its perspective weights and what its draw reads of its
// three vertices (ShadeDraw::needs), then classifies it (shade_models.hpp). An unclipped record
// names its mesh vertices; a clipped triangle's vertices carry weights of the source face's
// corners, and attributes, linear in those weights, are mapped here once. Normals only if the
// draw's model reads them or they are an output: else one zero normal.
// (Written in place: returned by value, the copy cost as much as the rest.)
// A plain kernel's draws (KernelKind) read normals and colours only, as its model does.
// Returns the draw's model.
template <KernelKind K>
SR_INLINE Brdf prepare(const ShadeParams& p, const VisibleTriangle& vt, ShadeTriangle& s,
                       LitClassCache& cache) {
  constexpr bool kLit = K == KernelKind::Lit;
  constexpr bool kColors = K != KernelKind::NormalColor;  // (the normal as a colour reads none)
  const TriangleSetup& t = *vt.tri;
  const TriangleShading& a = vt.chunk->shading[std::size_t(vt.tri - vt.chunk->records.data())];
  const ShadeDraw& d = p.draws[t.draw];
  const MeshData& mesh = *d.mesh;
  const uint8_t needs = d.needs;
  const bool normals = K == KernelKind::Headlight || K == KernelKind::NormalColor ||
                       (needs & kNeedsNormal);
  const bool attributes = kLit && (needs & kNeedsUv);
  bool uniform_color;
  for (int k = 0; k < 3; ++k) s.persp[k] = a.persp[k];
  // The exact weights (pipeline.hpp, ExactWeights: setup wrote them where a draw reads them).
  const std::size_t record = std::size_t(vt.tri - vt.chunk->records.data());
  s.q = vt.chunk->exact.empty() ? nullptr : vt.chunk->exact[record].q;
  s.exact = kLit && d.exact_shading && s.q;
  if (a.clip_ref == kNoClip) {
    const int32_t* v = a.vertex;
    if (!normals) {
      // (nothing reads them: classify)
    } else if (d.world_normals) {
      for (int k = 0; k < 3; ++k) s.normal[k] = d.world_normals[v[k]];
    } else {  // no vertex normals => flat; the record's order is the face's, 1 and 2 swapped or not
      s.normal[0] = a.swapped ? flat_normal(d, v[0], v[2], v[1]) : flat_normal(d, v[0], v[1], v[2]);
      s.normal[1] = s.normal[2] = s.normal[0];
    }
    if (!kColors) {
      uniform_color = true;
    } else if (mesh.colors.empty()) {
      s.color[0] = s.color[1] = s.color[2] = vec3(d.color);
      uniform_color = true;
    } else {
      for (int k = 0; k < 3; ++k) s.color[k] = mesh.colors[v[k]];
      uniform_color = s.color[0] == s.color[1] && s.color[0] == s.color[2];
    }
    if (kLit && (needs & kNeedsPosition))
      for (int k = 0; k < 3; ++k) s.position[k] = world_position(d, v[k]);
    if (attributes) triangle_attributes<2>(mesh, t, a, *vt.chunk, s.attr);
  } else {
    const ivec3 f = mesh.faces[t.prim];
    vec3 normal_src[3] = {}, color_src[3];
    if (normals) {
      if (d.world_normals) {
        for (int c = 0; c < 3; ++c) normal_src[c] = d.world_normals[f[c]];
      } else {
        normal_src[0] = normal_src[1] = normal_src[2] = flat_normal(d, f.x, f.y, f.z);
      }
    }
    for (int c = 0; c < 3; ++c)
      color_src[c] = !kColors || mesh.colors.empty() ? vec3(d.color) : vec3(mesh.colors[f[c]]);
    const vec3* weights = &vt.chunk->clip_bary[3 * std::size_t(a.clip_ref)];
    for (int k = 0; k < 3; ++k) {
      const vec3 w = weights[k];
      if (normals) s.normal[k] = w.x * normal_src[0] + w.y * normal_src[1] + w.z * normal_src[2];
      s.color[k] = w.x * color_src[0] + w.y * color_src[1] + w.z * color_src[2];
    }
    if (kLit && (needs & kNeedsPosition)) {
      vec3 src[3];
      for (int c = 0; c < 3; ++c) src[c] = world_position(d, f[c]);
      for (int k = 0; k < 3; ++k) {
        const vec3 w = weights[k];
        s.position[k] = w.x * src[0] + w.y * src[1] + w.z * src[2];
      }
    }
    if (attributes) triangle_attributes<2>(mesh, t, a, *vt.chunk, s.attr);
    uniform_color = s.color[0] == s.color[1] && s.color[0] == s.color[2];
  }
  const bool textured = kLit && (needs & kTexturedUv);  // uvs for sampling (not uv colours)
  if (textured) reduce_uv_period(s.attr, uv_periodic_axes(d.material));
  if (normals && d.world_normals) {
    // A zero vertex normal (a file's, or one a singular pose collapses) falls back to the face
    // normal, so that shading never loses the surface's orientation (one check per triangle).
    const bool zero0 = s.normal[0] == vec3(0.0f), zero1 = s.normal[1] == vec3(0.0f),
               zero2 = s.normal[2] == vec3(0.0f);
    if (zero0 || zero1 || zero2) {
      const vec3 face = a.clip_ref != kNoClip ? flat_normal(d, mesh.faces[t.prim].x, mesh.faces[t.prim].y,
                                                            mesh.faces[t.prim].z)
                        : a.swapped ? flat_normal(d, a.vertex[0], a.vertex[2], a.vertex[1])
                                    : flat_normal(d, a.vertex[0], a.vertex[1], a.vertex[2]);
      if (zero0) s.normal[0] = face;
      if (zero1) s.normal[1] = face;
      if (zero2) s.normal[2] = face;
    }
  }
  if (normals && a.back_facing)  // two-sided: the side the camera sees
    for (vec3& n : s.normal) n = -n;
  if (textured)
    attribute_derivatives<2>(t, a.persp, s.exact ? s.q : nullptr, s.attr, s.sum_dx, s.sum_dy,
                             s.attr_dx, s.attr_dy);
  if (kLit && (needs & kNeedsFaceNormal)) {
    const vec3 n = a.clip_ref != kNoClip ? flat_normal(d, mesh.faces[t.prim].x, mesh.faces[t.prim].y,
                                                       mesh.faces[t.prim].z)
                   : a.swapped ? flat_normal(d, a.vertex[0], a.vertex[2], a.vertex[1])
                               : flat_normal(d, a.vertex[0], a.vertex[1], a.vertex[2]);
    s.face_normal = a.back_facing ? -n : n;
  }
  classify<K>(p.in, d.brdf, needs, d.material, t.draw, a.back_facing, uniform_color, s, cache);
  return d.brdf;
}

using namespace simd;

// Eight lanes of float edge values E_k for pixels (x .. x + 7, y) of one triangle, stepped along
// its rows; each lane holds float(E_k), rounded once from the exact value, as a scalar
// float(int64) would. Small triangles (is_small) use the rasterizer's SmallEdges.
// Any triangle: exact values in double (|E| < 2^51 < 2^53), two halves of four lanes.
struct LargeEdges {
  d4 lo[3], hi[3];
  double step_x8[3], step_y[3];
  SR_INLINE explicit LargeEdges(const EdgeEquations& eq) {
    const d4 lane{0.0, 1.0, 2.0, 3.0};
    for (int k = 0; k < 3; ++k) {
      lo[k] = double(eq.origin[k]) + lane * double(eq.step_x[k]);
      hi[k] = double(eq.origin[k]) + (lane + 4.0) * double(eq.step_x[k]);
      step_x8[k] = double(eq.step_x[k] * kLanes);
      step_y[k] = double(eq.step_y[k]);
    }
  }
  struct Cursor {
    d4 lo[3], hi[3];
    SR_INLINE f8 edge(int k) const { return to_float(lo[k], hi[k]); }
    SR_INLINE void next(const LargeEdges& s) {
      for (int k = 0; k < 3; ++k) {
        lo[k] += s.step_x8[k];
        hi[k] += s.step_x8[k];
      }
    }
  };
  SR_INLINE Cursor cursor() const { return {{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}}; }
  SR_INLINE void next_row() {
    for (int k = 0; k < 3; ++k) {
      lo[k] += step_y[k];
      hi[k] += step_y[k];
    }
  }
};

// b0 v[0] + b1 v[1] + b2 v[2] per component, eight pixels at a time.
struct Lanes3 {
  f8 x, y, z;
};
SR_INLINE Lanes3 weighted(const vec3 (&v)[3], f8 b0, f8 b1, f8 b2) {
  return {b0 * v[0].x + b1 * v[1].x + b2 * v[2].x, b0 * v[0].y + b1 * v[1].y + b2 * v[2].y,
          b0 * v[0].z + b1 * v[1].z + b2 * v[2].z};
}

}  // namespace interp
}  // namespace sr
