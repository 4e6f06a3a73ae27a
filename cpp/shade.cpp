// Shade stage: perspective-correct barycentrics, attribute interpolation, unlit / Lambert.
#include "shade.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <immintrin.h>

namespace sr {

namespace {

// Unit vector in float, or zero for a zero (or non-finite) vector.
inline vec3 unit(const dvec3& v) {
  const double len = glm::length(v);
  return len > 0.0 && std::isfinite(len) ? vec3(v / len) : vec3(0.0f);
}

// std::clamp(v, 0, 1) * 255 + 0.5 truncated.
inline uint32_t to_unorm8(float v) { return uint32_t(std::clamp(v, 0.0f, 1.0f) * 255.0f + 0.5f); }

// Picks a prepared triangle's per-pixel work (ShadeTriangle) and its per-triangle values;
// `uniform_color`: the three colours are equal (only color[0] need be set).
void classify(const ShadeParams& p, bool uniform_color, ShadeTriangle& s) {
  const bool lit = p.shading == Shading::Lambert;
  s.one_normal = s.normal[0] == s.normal[1] && s.normal[0] == s.normal[2];
  if (s.one_normal) {
    const vec3 n = s.normal[0];
    const float len2 = glm::dot(n, n);
    s.unit_normal = len2 > 0.0f ? n * (1.0f / std::sqrt(len2)) : vec3(0.0f);
  }
  if (uniform_color && (!lit || s.one_normal)) {
    s.color_kind = ShadeTriangle::kConstantColor;
    vec3 c = s.color[0];
    if (lit) c *= p.ambient + (1.0f - p.ambient) *
                                  std::max(glm::dot(s.unit_normal, p.to_light_world), 0.0f);
    s.rgb = to_unorm8(c.x) | to_unorm8(c.y) << 8 | to_unorm8(c.z) << 16;
  } else if (uniform_color) {
    s.color_kind = ShadeTriangle::kUniformLit;
    for (int k = 0; k < 3; ++k) s.light_dot[k] = glm::dot(s.normal[k], p.to_light_world);
    s.color255 = glm::clamp(s.color[0], 0.0f, 1.0f) * 255.0f;
  } else {
    s.color_kind = ShadeTriangle::kVaryingColor;
  }
}

// The triangle's flat normal in world space: the counter-clockwise face normal of corners
// c0, c1, c2, in double (a float cross product or a scaled normal can overflow: a triangle 1e20
// units wide, a pose scaling by 0.1).
inline vec3 flat_normal(const ShadeDraw& d, int32_t c0, int32_t c1, int32_t c2) {
  const vec3* positions = d.mesh->positions.data();
  const dvec3 p0(positions[c0]);
  return unit(d.normal_to_world *
              glm::cross(dvec3(positions[c1]) - p0, dvec3(positions[c2]) - p0));
}

// Prepares one visible triangle into `s`: its perspective weights and its attributes at its own
// three vertices. An unclipped record names its mesh vertices; a clipped triangle's vertices
// carry weights of the source face's corners, and attributes, linear in those weights, are
// mapped here once. Normals only if lit or an output (kNormals): else one zero normal.
// (Written in place: returned by value, the copy cost as much as the rest.)
template <bool kNormals>
void prepare(const ShadeParams& p, const VisibleTriangle& vt, ShadeTriangle& s) {
  const TriangleSetup& t = *vt.tri;
  const TriangleShading& a = vt.chunk->shading[std::size_t(vt.tri - vt.chunk->records.data())];
  const ShadeDraw& d = p.draws[t.draw];
  const MeshData& mesh = *d.mesh;
  bool uniform_color;
  for (int k = 0; k < 3; ++k) s.persp[k] = a.persp[k];
  if (a.clip_ref == kNoClip) {
    const int32_t* v = a.vertex;
    if (!kNormals) {
      s.normal[0] = s.normal[1] = s.normal[2] = vec3(0.0f);
    } else if (d.world_normals) {
      for (int k = 0; k < 3; ++k) s.normal[k] = d.world_normals[v[k]];
    } else {  // no vertex normals => flat; the record's order is the face's, 1 and 2 swapped or not
      s.normal[0] = a.swapped ? flat_normal(d, v[0], v[2], v[1]) : flat_normal(d, v[0], v[1], v[2]);
      s.normal[1] = s.normal[2] = s.normal[0];
    }
    if (mesh.colors.empty()) {
      s.color[0] = vec3(d.color);
      uniform_color = true;
    } else {
      for (int k = 0; k < 3; ++k) s.color[k] = mesh.colors[v[k]];
      uniform_color = s.color[0] == s.color[1] && s.color[0] == s.color[2];
    }
  } else {
    const ivec3 f = mesh.faces[t.prim];
    vec3 normal_src[3] = {}, color_src[3];
    if (kNormals) {
      if (d.world_normals) {
        for (int c = 0; c < 3; ++c) normal_src[c] = d.world_normals[f[c]];
      } else {
        normal_src[0] = normal_src[1] = normal_src[2] = flat_normal(d, f.x, f.y, f.z);
      }
    }
    for (int c = 0; c < 3; ++c)
      color_src[c] = mesh.colors.empty() ? vec3(d.color) : vec3(mesh.colors[f[c]]);
    const vec3* weights = &vt.chunk->clip_bary[3 * std::size_t(a.clip_ref)];
    for (int k = 0; k < 3; ++k) {
      const vec3 w = weights[k];
      s.normal[k] = w.x * normal_src[0] + w.y * normal_src[1] + w.z * normal_src[2];
      s.color[k] = w.x * color_src[0] + w.y * color_src[1] + w.z * color_src[2];
    }
    uniform_color = s.color[0] == s.color[1] && s.color[0] == s.color[2];
  }
  if (kNormals && a.back_facing)  // two-sided: the side the camera sees
    for (vec3& n : s.normal) n = -n;
  classify(p, uniform_color, s);
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

// std::clamp(v, 0, 1) * 255 + 0.5 truncated, per lane, as to_unorm8 does.
SR_INLINE i8 to_unorm8(f8 v) {
  const f8 zero = splat(0.0f), one = splat(1.0f);
  const f8 c = v < zero ? zero : (one < v ? one : v);
  return __builtin_convertvector(c * 255.0f + 0.5f, i8);
}

// b0 v[0] + b1 v[1] + b2 v[2] per component, eight pixels at a time.
struct Lanes3 {
  f8 x, y, z;
};
SR_INLINE Lanes3 weighted(const vec3 (&v)[3], f8 b0, f8 b1, f8 b2) {
  return {b0 * v[0].x + b1 * v[1].x + b2 * v[2].x, b0 * v[0].y + b1 * v[1].y + b2 * v[2].y,
          b0 * v[0].z + b1 * v[1].z + b2 * v[2].z};
}

// Per-triangle constants of shade_group.
struct ShadeConstants {
  f8 persp[3];
  f8 light[3];  // to_light_world, or for kUniformLit the vertices' dot(normal[k], to_light_world)
  f8 ambient, diffuse;
  ShadeConstants() = default;
  SR_INLINE ShadeConstants(const ShadeParams& p, const ShadeTriangle& s) {
    for (int k = 0; k < 3; ++k) {
      persp[k] = splat(s.persp[k]);
      light[k] = s.color_kind == ShadeTriangle::kUniformLit ? splat(s.light_dot[k])
                                                            : splat(p.to_light_world[k]);
    }
    ambient = splat(p.ambient);
    diffuse = splat(1.0f - p.ambient);
  }
};

// Shades eight pixels of one triangle from their exact edge values e0..e2, writing the lanes in
// `mine` to the scratch buffers at i: eight pixels of a row, or with kPairs four pixels of row i
// and four of the row below.
template <bool kColor, bool kLit, bool kNormal, bool kPairs>
SR_INLINE void shade_group(const ShadeTriangle& s, const ShadeConstants& c, f8 e0, f8 e1, f8 e2,
                           i8 mine, int i, ShadeScratch& out) {
  const auto merge = [&](auto* p, auto v) {
    raster::store_lanes<kPairs>(p, mine ? v : raster::load_lanes<kPairs, decltype(v)>(p));
  };
  const bool varying_color = kColor && s.color_kind == ShadeTriangle::kVaryingColor;
  const bool varying_normal = kNormal && !s.one_normal;
  if (varying_color || varying_normal) {
    // Perspective-correct barycentrics from the exact edge values.
    f8 b0 = e0 * c.persp[0], b1 = e1 * c.persp[1], b2 = e2 * c.persp[2];
    const f8 inv_sum = 1.0f / (b0 + b1 + b2);
    b0 *= inv_sum; b1 *= inv_sum; b2 *= inv_sum;
    f8 nx{}, ny{}, nz{};
    if (varying_normal || (kLit && varying_color)) {
      const Lanes3 n = weighted(s.normal, b0, b1, b2);
      nx = n.x; ny = n.y; nz = n.z;
      const f8 len2 = nx * nx + ny * ny + nz * nz;
      const f8 r = 1.0f / simd::sqrt(len2);
      const i8 nonzero = len2 > 0.0f;
      nx = nonzero ? nx * r : f8{};
      ny = nonzero ? ny * r : f8{};
      nz = nonzero ? nz * r : f8{};
    }
    if (varying_normal) {
      merge(out.normal[0] + i, nx);
      merge(out.normal[1] + i, ny);
      merge(out.normal[2] + i, nz);
    }
    if (varying_color) {
      const Lanes3 rgb = weighted(s.color, b0, b1, b2);
      f8 r = rgb.x, g = rgb.y, b = rgb.z;
      if constexpr (kLit) {
        const f8 d = nx * c.light[0] + ny * c.light[1] + nz * c.light[2];
        const f8 f = c.ambient + c.diffuse * (f8{} < d ? d : f8{});
        r *= f; g *= f; b *= f;
      }
      merge(out.rgb + i, to_unorm8(r) | (to_unorm8(g) << 8) | (to_unorm8(b) << 16));
    }
  }
  if constexpr (kNormal) {
    if (!varying_normal)
      for (int k = 0; k < 3; ++k) merge(out.normal[k] + i, splat(s.unit_normal[k]));
  }
  if constexpr (kColor) {
    if (s.color_kind == ShadeTriangle::kConstantColor) {
      merge(out.rgb + i, splat(int32_t(s.rgb)));
    } else if (kLit && s.color_kind == ShadeTriangle::kUniformLit) {
      // Unnormalised perspective weights: the normal's length and dot(n, L) share their scale.
      const f8 b0 = e0 * c.persp[0], b1 = e1 * c.persp[1], b2 = e2 * c.persp[2];
      const Lanes3 n = weighted(s.normal, b0, b1, b2);
      const f8 len2 = n.x * n.x + n.y * n.y + n.z * n.z;
      const f8 dot = b0 * c.light[0] + b1 * c.light[1] + b2 * c.light[2];
      const f8 d = dot / simd::sqrt(len2);  // NaN for a zero normal: no diffuse term
      const f8 f = c.ambient + c.diffuse * (f8{} < d ? d : f8{});
      // f lies in [0, 1] up to rounding, so f * color255 + 0.5 in [0, 256): no clamp needed.
      const auto unorm8 = [&](float c255) { return __builtin_convertvector(f * c255 + 0.5f, i8); };
      merge(out.rgb + i, unorm8(s.color255.x) | (unorm8(s.color255.y) << 8) |
                             (unorm8(s.color255.z) << 16));
    }
  }
}

// Shades the pixels of rows [y0, y1], columns [x0, x1] of the tile that visible triangle `index`
// owns, into the scratch buffers.
template <bool kColor, bool kLit, bool kNormal, typename Edges>
SR_INLINE void shade_pixels(const ShadeParams& p, const ShadeTriangle& s, Edges edges, int x0,
                            int x1, int y0, int y1, const TileRect& rect,
                            const TileScratch& raster, uint32_t index, ShadeScratch& out) {
  const ShadeConstants c(p, s);
  const i8 lane = lane_index(), index_v = splat(int32_t(index));
  const int width = x1 - x0 + 1;
  for (int y = y0; y <= y1; ++y, edges.next_row()) {
    int i = (y - rect.y0) * kTileSizePx + (x0 - rect.x0);
    typename Edges::Cursor cursor = edges.cursor();
    for (int dx = 0; dx < width; dx += kLanes, i += kLanes, cursor.next(edges)) {
      const i8 mine = (load<i8>(raster.visible + i) == index_v) & (lane < width - dx);
      if (any(mine))
        shade_group<kColor, kLit, kNormal, false>(s, c, cursor.edge(0), cursor.edge(1),
                                                  cursor.edge(2), mine, i, out);
    }
  }
}

// The same for a small triangle whose box is at most four pixels wide, two rows at a time.
template <bool kColor, bool kLit, bool kNormal>
SR_INLINE void shade_pairs(const ShadeParams& p, const ShadeTriangle& s, SmallEdgePairs edges,
                           int x0, int x1, int y0, int y1, const TileRect& rect,
                           const TileScratch& raster, uint32_t index, ShadeScratch& out) {
  const ShadeConstants c(p, s);
  const i8 lane = lane_index(), index_v = splat(int32_t(index));
  const i8 in_box_x = (lane & 3) < x1 - x0 + 1, row = lane >> 2;
  for (int y = y0; y <= y1; y += 2, edges.next_rows()) {
    const int i = (y - rect.y0) * kTileSizePx + (x0 - rect.x0);
    const i8 mine = (raster::load_lanes<true, i8>(raster.visible + i) == index_v) & in_box_x &
                    (row < y1 - y + 1);
    if (any(mine))
      shade_group<kColor, kLit, kNormal, true>(s, c, edges.edge(0), edges.edge(1),
                                               edges.edge(2), mine, i, out);
  }
}

template <bool kColor, bool kLit, bool kNormal>
SR_INLINE void shade_triangle(const ShadeParams& p, const TileRect& rect, const TileScratch& raster,
                              uint32_t index, ShadeScratch& out) {
  const VisibleTriangle& vt = raster.triangles[index];
  const TriangleSetup& t = *vt.tri;
  const int x0 = std::max(int(t.x0), rect.x0), x1 = std::min(int(t.x1), rect.x1 - 1);
  const int y0 = std::max(int(t.y0), rect.y0), y1 = std::min(int(t.y1), rect.y1 - 1);
  ShadeTriangle s;
  prepare<kLit || kNormal>(p, vt, s);
  const EdgeEquations eq = edge_equations(t, x0, y0);
  if (is_small(t) && x1 - x0 < 4 && y1 > y0)
    shade_pairs<kColor, kLit, kNormal>(p, s, SmallEdgePairs(eq), x0, x1, y0, y1, rect, raster, index, out);
  else if (is_small(t))
    shade_pixels<kColor, kLit, kNormal>(p, s, SmallEdges(eq), x0, x1, y0, y1, rect, raster, index, out);
  else
    shade_pixels<kColor, kLit, kNormal>(p, s, LargeEdges(eq), x0, x1, y0, y1, rect, raster, index, out);
}

template <bool kColor, bool kLit, bool kNormal>
SR_INLINE void shade_visible(const ShadeParams& p, const TileRect& rect, const TileScratch& raster,
                             ShadeScratch& scratch) {
  scratch.used.assign(raster.triangles.size(), 0);
  for (int y = rect.y0; y < rect.y1; ++y) {
    const uint32_t* visible = raster.visible + (y - rect.y0) * kTileSizePx;
    for (int x = 0; x < rect.x1 - rect.x0; ++x)
      if (visible[x] != kNoTriangle) scratch.used[visible[x]] = 1;
  }
  for (uint32_t v = 0; v < scratch.used.size(); ++v)
    if (scratch.used[v]) shade_triangle<kColor, kLit, kNormal>(p, rect, raster, v, scratch);
}

template <bool kColor, bool kLit, bool kNormal>
SR_TARGET_AVX2 void shade_visible_avx2(const ShadeParams& p, const TileRect& rect,
                                       const TileScratch& raster, ShadeScratch& scratch) {
  shade_visible<kColor, kLit, kNormal>(p, rect, raster, scratch);
}

template <bool kColor, bool kLit, bool kNormal>
void shade_visible_generic(const ShadeParams& p, const TileRect& rect, const TileScratch& raster,
                           ShadeScratch& scratch) {
  shade_visible<kColor, kLit, kNormal>(p, rect, raster, scratch);
}

using ShadeFn = void (*)(const ShadeParams&, const TileRect&, const TileScratch&, ShadeScratch&);

// Feature set chosen once per render: [isa][color][lit][normal] (lighting without colour is moot).
#define SR_SHADE_TABLE(suffix)                                                         \
  {{{nullptr, shade_visible_##suffix<false, false, true>},                             \
    {nullptr, shade_visible_##suffix<false, false, true>}},                            \
   {{shade_visible_##suffix<true, false, false>, shade_visible_##suffix<true, false, true>}, \
    {shade_visible_##suffix<true, true, false>, shade_visible_##suffix<true, true, true>}}}
constexpr ShadeFn kShadeTable[2][2][2][2] = {SR_SHADE_TABLE(generic), SR_SHADE_TABLE(avx2)};
#undef SR_SHADE_TABLE

// Forward shading: the raster kernels' hook (rasterize.hpp) that shades the lanes a triangle wins
// as it wins them, preparing the triangle on its first win. Triangles on the int64 raster path
// are noted and shaded afterwards, from the visibility buffer, as in deferred shading. A pixel
// overwritten later was shaded in vain (overdraw); its final value is the same either way, since
// a pixel's shade depends only on the triangle and the pixel.
template <bool kColor, bool kLit, bool kNormal>
struct ForwardShading {
  static constexpr bool kShades = true;
  const ShadeParams& p;
  ShadeScratch& out;
  const VisibleTriangle* current = nullptr;  // valid until the next triangle()
  bool ready = false;
  ShadeTriangle s{};
  ShadeConstants c{};

  SR_INLINE void triangle(const VisibleTriangle& vt) {
    current = &vt;
    ready = false;
  }
  template <bool kPairs>
  SR_INLINE void shade(i8 win, int i, f8 e0, f8 e1, f8 e2) {
    if (!ready) {
      prepare<kLit || kNormal>(p, *current, s);
      c = ShadeConstants(p, s);
      ready = true;
    }
    shade_group<kColor, kLit, kNormal, kPairs>(s, c, e0, e1, e2, win, i, out);
  }
  SR_INLINE void large_won(uint32_t index) { out.large.push_back(index); }
  // What prepare() will read of record i's vertices (raster::rasterize_all).
  SR_INLINE void prefetch_attributes(const SetupChunk& chunk, uint32_t i) {
    const TriangleShading& a = chunk.shading[i];
    if (a.clip_ref != kNoClip) return;
    const ShadeDraw& d = p.draws[chunk.records[i].draw];
    if constexpr (kLit || kNormal)
      if (d.world_normals)
        for (int k = 0; k < 3; ++k) __builtin_prefetch(d.world_normals + a.vertex[k]);
    if constexpr (kColor)
      if (!d.mesh->colors.empty())
        for (int k = 0; k < 3; ++k) __builtin_prefetch(d.mesh->colors.data() + a.vertex[k]);
  }
};

template <bool kColor, bool kLit, bool kNormal, bool kCoverage>
SR_INLINE void forward_tile(const ShadeParams& p, const TileRect& rect, int tile,
                            const std::vector<SetupChunk>& chunks, std::size_t num_chunks,
                            TileScratch& raster, ShadeScratch& scratch) {
  scratch.large.clear();
  ForwardShading<kColor, kLit, kNormal> hook{p, scratch};
  raster::rasterize_all<kCoverage>(rect, tile, chunks, num_chunks, raster, hook);
  for (const uint32_t index : scratch.large)
    shade_triangle<kColor, kLit, kNormal>(p, rect, raster, index, scratch);
}

template <bool kColor, bool kLit, bool kNormal, bool kCoverage>
SR_TARGET_AVX2 void forward_tile_avx2(const ShadeParams& p, const TileRect& rect, int tile,
                                      const std::vector<SetupChunk>& chunks,
                                      std::size_t num_chunks, TileScratch& raster,
                                      ShadeScratch& scratch) {
  forward_tile<kColor, kLit, kNormal, kCoverage>(p, rect, tile, chunks, num_chunks, raster, scratch);
}

template <bool kColor, bool kLit, bool kNormal, bool kCoverage>
void forward_tile_generic(const ShadeParams& p, const TileRect& rect, int tile,
                          const std::vector<SetupChunk>& chunks, std::size_t num_chunks,
                          TileScratch& raster, ShadeScratch& scratch) {
  forward_tile<kColor, kLit, kNormal, kCoverage>(p, rect, tile, chunks, num_chunks, raster, scratch);
}

using ForwardFn = void (*)(const ShadeParams&, const TileRect&, int, const std::vector<SetupChunk>&,
                           std::size_t, TileScratch&, ShadeScratch&);

// [isa][color][lit][normal][coverage]; nothing to shade without colour or normals.
#define SR_FORWARD_PAIR(suffix, c, l, n) {forward_tile_##suffix<c, l, n, false>, forward_tile_##suffix<c, l, n, true>}
#define SR_FORWARD_TABLE(suffix)                                                                \
  {{{{nullptr, nullptr}, SR_FORWARD_PAIR(suffix, false, false, true)},                          \
    {{nullptr, nullptr}, SR_FORWARD_PAIR(suffix, false, false, true)}},                         \
   {{SR_FORWARD_PAIR(suffix, true, false, false), SR_FORWARD_PAIR(suffix, true, false, true)},  \
    {SR_FORWARD_PAIR(suffix, true, true, false), SR_FORWARD_PAIR(suffix, true, true, true)}}}
constexpr ForwardFn kForwardTable[2][2][2][2][2] = {SR_FORWARD_TABLE(generic), SR_FORWARD_TABLE(avx2)};
#undef SR_FORWARD_TABLE
#undef SR_FORWARD_PAIR

// Depth of the visible pixels of one row, eight at a time.
SR_INLINE void resolve_depth_row(const float* key, const uint32_t* visible, int n,
                                 bool orthographic, float* depth) {
  int x = 0;
  for (; x + kLanes <= n; x += kLanes) {
    const f8 k = load<f8>(key + x);
    const f8 d = orthographic ? -k : 1.0f / k;
    store(depth + x, load<i8>(visible + x) != int32_t(kNoTriangle) ? d : f8{});
  }
  for (; x < n; ++x) depth[x] = visible[x] != kNoTriangle ? depth_from_key(key[x], orthographic) : 0.0f;
}
SR_TARGET_AVX2 void resolve_depth_row_avx2(const float* key, const uint32_t* visible, int n,
                                           bool orthographic, float* depth) {
  resolve_depth_row(key, visible, n, orthographic, depth);
}
void resolve_depth_row_generic(const float* key, const uint32_t* visible, int n,
                               bool orthographic, float* depth) {
  resolve_depth_row(key, visible, n, orthographic, depth);
}
// The same values with non-temporal stores, where the row is 16-byte aligned and whole vectors.
SR_TARGET_AVX2 void resolve_depth_row_stream(const float* key, const uint32_t* visible, int n,
                                             bool orthographic, float* depth) {
  if ((reinterpret_cast<uintptr_t>(depth) & 15) != 0 || n % kLanes != 0)
    return resolve_depth_row(key, visible, n, orthographic, depth);
  // Intrinsics rather than f8: clang rejects non-AVX helpers returning 32-byte vectors here.
  const __m256 one = _mm256_set1_ps(1.0f), sign = _mm256_set1_ps(-0.0f);
  const __m256i none = _mm256_set1_epi32(int32_t(kNoTriangle));
  for (int x = 0; x < n; x += kLanes) {
    const __m256 k = _mm256_loadu_ps(key + x);
    const __m256 d = orthographic ? _mm256_xor_ps(k, sign) : _mm256_div_ps(one, k);
    const __m256i vis = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(visible + x));
    const __m256 v = _mm256_andnot_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(vis, none)), d);
    _mm_stream_ps(depth + x, _mm256_castps256_ps128(v));
    _mm_stream_ps(depth + x + 4, _mm256_extractf128_ps(v, 1));
  }
}

// Unpacks a row of packed colours (r | g << 8 | b << 16) to 3-byte pixels, background where
// nothing is visible.
void write_rgb_generic(const uint32_t* rgb, const uint32_t* visible, int n, uint32_t background,
                       uint8_t* out) {
  for (int x = 0; x < n; ++x) {
    const uint32_t c = visible[x] == kNoTriangle ? background : rgb[x];
    out[3 * x] = uint8_t(c);
    out[3 * x + 1] = uint8_t(c >> 8);
    out[3 * x + 2] = uint8_t(c >> 16);
  }
}
// The same, four pixels per byte shuffle (each 16-byte store spills 4 bytes into the next pixel,
// written afterwards; where a spill would leave the row, the last four go as 8 + 4 bytes).
SR_TARGET_AVX2 SR_INLINE __m128i rgb_four(const uint32_t* rgb, const uint32_t* visible,
                                           __m128i background) {
  const __m128i pack = _mm_setr_epi8(0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1);
  const __m128i c = _mm_loadu_si128(reinterpret_cast<const __m128i*>(rgb));
  const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(visible));
  const __m128i none = _mm_cmpeq_epi32(v, _mm_set1_epi32(int32_t(kNoTriangle)));
  return _mm_shuffle_epi8(_mm_blendv_epi8(c, background, none), pack);
}
SR_TARGET_AVX2 void write_rgb_avx2(const uint32_t* rgb, const uint32_t* visible, int n,
                                   uint32_t background, uint8_t* out) {
  const __m128i bg = _mm_set1_epi32(int32_t(background));
  int x = 0;
  for (; x + 6 <= n; x += 4)
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + 3 * x), rgb_four(rgb + x, visible + x, bg));
  if (x + 4 <= n) {
    const __m128i last = rgb_four(rgb + x, visible + x, bg);
    _mm_storel_epi64(reinterpret_cast<__m128i*>(out + 3 * x), last);
    const int32_t tail = _mm_extract_epi32(last, 2);
    std::memcpy(out + 3 * x + 8, &tail, 4);
    x += 4;
  }
  write_rgb_generic(rgb + x, visible + x, n - x, background, out + 3 * x);
}

// The same values with non-temporal stores: sixteen pixels as three aligned 16-byte stores,
// where the row is 16-byte aligned and whole groups of sixteen.
SR_TARGET_AVX2 void write_rgb_stream(const uint32_t* rgb, const uint32_t* visible, int n,
                                     uint32_t background, uint8_t* out) {
  if ((reinterpret_cast<uintptr_t>(out) & 15) != 0 || n % 16 != 0)
    return write_rgb_avx2(rgb, visible, n, background, out);
  const __m128i bg = _mm_set1_epi32(int32_t(background));
  for (int x = 0; x < n; x += 16) {
    // Twelve bytes each, the top four zero.
    const __m128i p0 = rgb_four(rgb + x, visible + x, bg);
    const __m128i p1 = rgb_four(rgb + x + 4, visible + x + 4, bg);
    const __m128i p2 = rgb_four(rgb + x + 8, visible + x + 8, bg);
    const __m128i p3 = rgb_four(rgb + x + 12, visible + x + 12, bg);
    __m128i* o = reinterpret_cast<__m128i*>(out + 3 * x);
    _mm_stream_si128(o, _mm_or_si128(p0, _mm_slli_si128(p1, 12)));
    _mm_stream_si128(o + 1, _mm_or_si128(_mm_srli_si128(p1, 4), _mm_slli_si128(p2, 8)));
    _mm_stream_si128(o + 2, _mm_or_si128(_mm_srli_si128(p2, 8), _mm_slli_si128(p3, 4)));
  }
}

// Copies the tile's resolved values to the requested outputs, background where nothing is visible.
void write_tile(const ShadeParams& p, const TileRect& rect, const TileScratch& raster,
                const ShadeScratch& shaded, Isa isa) {
  const Framebuffer& fb = *p.framebuffer;
  const std::size_t width = std::size_t(fb.width);
  const int n = rect.x1 - rect.x0;
  const bool stream = p.stream && isa == Isa::Avx2;
  const auto resolve_depth = stream                ? resolve_depth_row_stream
                             : isa == Isa::Avx2    ? resolve_depth_row_avx2
                                                   : resolve_depth_row_generic;
  const auto write_rgb = stream ? write_rgb_stream
                         : isa == Isa::Avx2 ? write_rgb_avx2 : write_rgb_generic;
  for (int y = rect.y0; y < rect.y1; ++y) {
    const int row = (y - rect.y0) * kTileSizePx;
    const std::size_t o = std::size_t(y) * width + std::size_t(rect.x0);
    const uint32_t* visible = raster.visible + row;
    if (fb.coverage) std::memcpy(fb.coverage + o, raster.coverage + row, sizeof(uint32_t) * n);
    if (fb.depth) resolve_depth(raster.key + row, visible, n, p.orthographic, fb.depth + o);
    if (fb.mask)
      for (int x = 0; x < n; ++x) fb.mask[o + x] = visible[x] != kNoTriangle;
    if (fb.triangle_id)
      for (int x = 0; x < n; ++x)
        fb.triangle_id[o + x] = visible[x] == kNoTriangle ? -1 : int32_t(raster.triangles[visible[x]].tri->prim);
    if (fb.instance_id)
      for (int x = 0; x < n; ++x)
        fb.instance_id[o + x] = visible[x] == kNoTriangle ? -1 : p.draws[raster.triangles[visible[x]].tri->draw].instance_id;
    if (fb.normal) {
      float* normal = fb.normal + 3 * o;
      for (int x = 0; x < n; ++x) {
        const bool bg = visible[x] == kNoTriangle;
        for (int c = 0; c < 3; ++c) normal[3 * x + c] = bg ? 0.0f : shaded.normal[c][row + x];
      }
    }
    if (fb.color) {
      const uint32_t background = p.background[0] | p.background[1] << 8 | p.background[2] << 16;
      write_rgb(shaded.rgb + row, visible, n, background, fb.color + 3 * o);
    }
  }
  if (stream) _mm_sfence();  // order the non-temporal stores before the tile is done
}

// World-space unit normals. The unit normal does not depend on the matrix's scale, so the matrix
// is scaled to a largest entry of 1 and the work done in float, eight normals at a time; a normal
// whose transformed squared length is outside [2^-100, 2^100] (a zero normal, or one scaled near
// float's limits) is redone as unit(m * dvec3(n)) in double. The scalar loop that finishes the
// range repeats the float operations (grouped as GLM groups them), so the same bits.
struct NormalMatrix {
  dmat3 m;     // normal_to_world
  float f[3][3];  // m / max |m_ij|, columns first
  explicit NormalMatrix(const dmat3& matrix) : m(matrix) {
    double largest = 0.0;
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) largest = std::max(largest, std::fabs(m[c][r]));
    const double scale = largest > 0.0 && std::isfinite(largest) ? 1.0 / largest : 0.0;
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) f[c][r] = float(m[c][r] * scale);
  }
};
constexpr float kMinNormalLength2 = 0x1p-100f, kMaxNormalLength2 = 0x1p100f;

inline vec3 unit_world_normal(const NormalMatrix& nm, const vec3& n) {
  float w[3];
  for (int r = 0; r < 3; ++r) w[r] = (nm.f[0][r] * n.x + nm.f[1][r] * n.y) + nm.f[2][r] * n.z;
  const float len2 = (w[0] * w[0] + w[1] * w[1]) + w[2] * w[2];
  if (!(len2 >= kMinNormalLength2 && len2 <= kMaxNormalLength2)) return unit(nm.m * dvec3(n));
  const float r = 1.0f / std::sqrt(len2);
  return vec3(w[0] * r, w[1] * r, w[2] * r);
}

SR_INLINE void world_normals_range(const MeshData& mesh, const NormalMatrix& nm, std::size_t begin,
                                   std::size_t end, vec3* out) {
  const vec3* normals = mesh.normals.data();
  std::size_t i = begin;
  for (; i + kLanes <= end; i += kLanes) {
    f8 x, y, z;
    load_xyz8(&normals[i].x, x, y, z);
    f8 w[3];
    for (int r = 0; r < 3; ++r)
      w[r] = (splat(nm.f[0][r]) * x + splat(nm.f[1][r]) * y) + splat(nm.f[2][r]) * z;
    const f8 len2 = (w[0] * w[0] + w[1] * w[1]) + w[2] * w[2];
    const i8 ok = (len2 >= splat(kMinNormalLength2)) & (len2 <= splat(kMaxNormalLength2));
    const f8 r = 1.0f / simd::sqrt(len2);
    const f8 u[3] = {w[0] * r, w[1] * r, w[2] * r};
    // Back to xyz triples.
    const f8 t_a = __builtin_shufflevector(u[0], u[1], 0, 8, 0, 1, 9, 0, 2, 10);
    const f8 t_b = __builtin_shufflevector(u[0], u[1], 0, 3, 11, 0, 4, 12, 0, 5);
    const f8 t_c = __builtin_shufflevector(u[0], u[1], 13, 0, 6, 14, 0, 7, 15, 0);
    store(&out[i].x, __builtin_shufflevector(t_a, u[2], 0, 1, 8, 3, 4, 9, 6, 7));
    store(&out[i].x + 8, __builtin_shufflevector(t_b, u[2], 10, 1, 2, 11, 4, 5, 12, 7));
    store(&out[i].x + 16, __builtin_shufflevector(t_c, u[2], 0, 13, 2, 3, 14, 5, 6, 15));
    if (!all(ok))
      for (int k = 0; k < kLanes; ++k)
        if (!ok[k]) out[i + k] = unit(nm.m * dvec3(normals[i + k]));
  }
  for (; i < end; ++i) out[i] = unit_world_normal(nm, normals[i]);
}

SR_TARGET_AVX2 void world_normals_avx2(const MeshData& mesh, const NormalMatrix& nm,
                                       std::size_t begin, std::size_t end, vec3* out) {
  world_normals_range(mesh, nm, begin, end, out);
}

void world_normals_generic(const MeshData& mesh, const NormalMatrix& nm, std::size_t begin,
                           std::size_t end, vec3* out) {
  world_normals_range(mesh, nm, begin, end, out);
}

}  // namespace

void world_normals(const MeshData& mesh, const dmat3& normal_to_world, std::size_t begin,
                   std::size_t end, Isa isa, vec3* out) {
  const NormalMatrix nm(normal_to_world);
  (isa == Isa::Avx2 ? world_normals_avx2 : world_normals_generic)(mesh, nm, begin, end, out);
}

bool can_shade_forward(const ShadeParams& params) {
  const Framebuffer& fb = *params.framebuffer;
  return fb.color != nullptr || fb.normal != nullptr;
}

void rasterize_and_shade_tile(const ShadeParams& params, const Viewport& viewport, int tile,
                              const std::vector<SetupChunk>& chunks, std::size_t num_chunks,
                              bool want_coverage, Isa isa, TileScratch& raster,
                              ShadeScratch& scratch) {
  const Framebuffer& fb = *params.framebuffer;
  const TileRect rect = tile_rect(viewport, tile);
  const ForwardFn fn = kForwardTable[isa == Isa::Avx2][fb.color != nullptr]
                                    [params.shading == Shading::Lambert][fb.normal != nullptr]
                                    [want_coverage];
  if (!fn) throw std::logic_error("rasterize_and_shade_tile: nothing to shade");
  raster.clear(want_coverage);
  fn(params, rect, tile, chunks, num_chunks, raster, scratch);
  write_tile(params, rect, raster, scratch, isa);
}

void shade_tile(const ShadeParams& params, const Viewport& viewport, int tile,
                const TileScratch& raster, Isa isa, ShadeScratch& scratch) {
  const Framebuffer& fb = *params.framebuffer;
  const TileRect rect = tile_rect(viewport, tile);
  const ShadeFn fn = kShadeTable[isa == Isa::Avx2][fb.color != nullptr]
                                [params.shading == Shading::Lambert][fb.normal != nullptr];
  if (fn) fn(params, rect, raster, scratch);
  write_tile(params, rect, raster, scratch, isa);
}

}  // namespace sr
