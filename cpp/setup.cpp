// Setup stage: every per-triangle division, snap, cull, bounding box and edge equation.
#include "setup.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <utility>

#include "simd.hpp"

namespace sr {

namespace {

// Round half away from zero (as lround) by truncation: one instruction instead of a libm call.
inline int32_t round_to_fixed(double scaled) {
  return int32_t(scaled + (scaled >= 0.0 ? 0.5 : -0.5));
}

// Snaps one vertex. With `snap_outside`, a vertex outside some plane is snapped too (clipping
// output that rounding left a hair outside the plane it was clipped to: the guard band's margin
// keeps it representable). Writes `v` in place: a returned copy would be read back with wider
// loads than it was written with, which stalls store-to-load forwarding.
void project(const vec4& p_clip, float depth_view, const ClipPlanes& planes,
             const Viewport& viewport, bool orthographic, bool snap_outside,
             ProjectedVertex& v) {
  v = ProjectedVertex{};
  const bool finite = std::isfinite(p_clip.x) && std::isfinite(p_clip.y) &&
                      std::isfinite(p_clip.z) && std::isfinite(p_clip.w) &&
                      std::isfinite(depth_view);
  if (!finite) {
    v.outcode = kInvalidVertex;
    return;
  }
  v.outcode = planes.outcode(p_clip, depth_view);
  if (v.outcode != 0 && !snap_outside) return;
  if (!(p_clip.w > 0.0f) || !(depth_view > 0.0f)) {  // not a projection we can rasterize
    v.outcode = kInvalidVertex;
    return;
  }
  // Double precision: the snapped position must not depend on rounding in the divide.
  const double inv_w = 1.0 / double(p_clip.w);
  const double x_window = (double(p_clip.x) * inv_w + 1.0) * 0.5 * viewport.width;
  const double y_window = (1.0 - double(p_clip.y) * inv_w) * 0.5 * viewport.height;
  // Inside the guard band (+ margin) => |window| < 2^15, so fixed values fit in 24 bits.
  constexpr double kLimit = 32768.0 - 1.0;
  if (!(std::fabs(x_window) < kLimit && std::fabs(y_window) < kLimit)) {
    v.outcode = kInvalidVertex;
    return;
  }
  const double x_scaled = x_window * kSubpixelOne, y_scaled = y_window * kSubpixelOne;
  v.x = round_to_fixed(x_scaled);
  v.y = round_to_fixed(y_scaled);
  v.dx = float(x_scaled - v.x);  // the subtraction is exact; float keeps 2^-24 of a subpixel
  v.dy = float(y_scaled - v.y);
  // 1.0f / d is float(1.0 / double(d)): a double quotient rounded to float is correctly rounded
  // (53 >= 2 * 24 + 2 bits), so the cheaper float divide gives the same key.
  v.key = orthographic ? -depth_view : 1.0f / depth_view;
  v.inv_w = float(inv_w);
}

// First and last pixel whose centre (j * 256 + 128) lies in [lo, hi] (fixed point).
inline int32_t first_sample(int32_t lo) { return (lo - kSubpixelHalf + kSubpixelOne - 1) >> kSubpixelBits; }
inline int32_t last_sample(int32_t hi) { return (hi - kSubpixelHalf) >> kSubpixelBits; }

// Sets key_over_area from depth keys for the snapped vertices that reproduce the unsnapped
// triangle's depth plane.
//
// Coverage must use the snapped triangle (exact edge functions => watertight), but its keys need
// not: snapping moves a vertex by up to 1/512 px, and where depth changes fast across the screen
// (grazing planes) interpolating the original keys over the moved triangle is off by that shift
// times the depth gradient (3e-3 relative seen on a floor near the horizon). The key is affine in
// window space, so evaluating the true plane at the snapped vertices makes the interpolated key
// exact (to rounding) at every sample. Slivers, whose true plane is ill-conditioned, keep the
// original keys.
void plane_keys_over_area(const ProjectedVertex* const o[3], int64_t positive_area2,
                          TriangleSetup& t) {
  const double area2 = double(positive_area2);
  // The unsnapped triangle's edges from vertex 0, in fixed-point units.
  const double ex1 = double(t.x[1] - t.x[0]) + (double(o[1]->dx) - double(o[0]->dx));
  const double ey1 = double(t.y[1] - t.y[0]) + (double(o[1]->dy) - double(o[0]->dy));
  const double ex2 = double(t.x[2] - t.x[0]) + (double(o[2]->dx) - double(o[0]->dx));
  const double ey2 = double(t.y[2] - t.y[0]) + (double(o[2]->dy) - double(o[0]->dy));
  const double area = ex1 * ey2 - ey1 * ex2;
  constexpr double kMinArea = 1e-6 * kSubpixelOne * kSubpixelOne;  // 1e-6 px^2
  if (std::fabs(area) > kMinArea) {
    // One division for both reciprocals (divisions dominate this function's latency).
    const double r = 1.0 / (area * area2);
    const double inv_area = area2 * r, inv_area2 = area * r;
    const double dkey1 = double(o[1]->key) - double(o[0]->key);
    const double dkey2 = double(o[2]->key) - double(o[0]->key);
    bool well_shaped = true;
    // Snapping moved vertex v by (-dx, -dy): the change of its barycentric coordinates in the
    // unsnapped triangle. The plane's value there is v's key plus that change applied to the
    // keys (the changes sum to 0), which keeps the small correction apart from the large key.
    auto fitted = [&](const ProjectedVertex& v) {
      const double sx = -double(v.dx), sy = -double(v.dy);
      const double mu1 = (sx * ey2 - sy * ex2) * inv_area, mu2 = (ex1 * sy - ey1 * sx) * inv_area;
      const double mu0 = -(mu1 + mu2);
      const double key = double(v.key) + (mu1 * dkey1 + mu2 * dkey2);
      // A well-shaped triangle moves its barycentrics a little; much more => sliver. The key's
      // sign is its camera type.
      well_shaped &= (std::fabs(mu0) <= 0.25) & (std::fabs(mu1) <= 0.25) &
                     (std::fabs(mu2) <= 0.25) & ((key > 0.0) == (v.key > 0.0f));
      return key;
    };
    const double key0 = fitted(*o[0]), key1 = fitted(*o[1]), key2 = fitted(*o[2]);
    if (well_shaped) {
      t.key_over_area[0] = float(key0 * inv_area2);
      t.key_over_area[1] = float(key1 * inv_area2);
      t.key_over_area[2] = float(key2 * inv_area2);
      return;
    }
  }
  const double inv_area2 = 1.0 / area2;
  for (int k = 0; k < 3; ++k) t.key_over_area[k] = float(double(o[k]->key) * inv_area2);
}

// False if the bounding box holds one or two sample centres and the triangle covers neither (the
// rasterizer's exact edge test, E_k - bias_k >= 0). A dense mesh has many such triangles: in a
// 1.3M-face sphere at 1024x1024, a quarter of those with a sample in their box; no record is
// cheaper than a record that draws nothing.
bool covers_box_samples(const TriangleSetup& t) {
  if ((t.x1 - t.x0) + (t.y1 - t.y0) > 1) return true;
  for (const auto& [px, py] : {std::pair{t.x0, t.y0}, std::pair{t.x1, t.y1}}) {
    const int64_t cx = int64_t(px) * kSubpixelOne + kSubpixelHalf;
    const int64_t cy = int64_t(py) * kSubpixelOne + kSubpixelHalf;
    bool inside = true;
    for (int k = 0; k < 3; ++k) {
      const int a = kEdgeStart[k], b = kEdgeEnd[k];
      const int64_t e = int64_t(t.x[b] - t.x[a]) * (cy - t.y[a]) - int64_t(t.y[b] - t.y[a]) * (cx - t.x[a]);
      inside &= e - t.bias[k] >= 0;
    }
    if (inside) return true;
  }
  return false;
}

// Shading's perspective weights (TriangleShading::persp) of oriented vertices o.
void perspective_weights(const ProjectedVertex* const o[3], int64_t positive_area2,
                         TriangleShading& a) {
  const double max_inv_w = std::max({double(o[0]->inv_w), double(o[1]->inv_w), double(o[2]->inv_w)});
  const double scale = 1.0 / (max_inv_w * double(positive_area2));
  for (int k = 0; k < 3; ++k) a.persp[k] = float(double(o[k]->inv_w) * scale);
}

// Builds the records for one snapped triangle whose corners are the mesh's vertices `vertex` (or
// null for a piece of a clipped face), `a` only if params.shade (its clip_ref left to the caller);
// `positive_area2` receives twice its area (> 0). Returns
// false if it is culled, degenerate, or has no sample centre in its box or covers none of the
// one or two there; those integer tests come before any floating-point work.
bool setup_triangle(const ProjectedVertex* const v[3], const SetupParams& params, uint32_t prim,
                    const int32_t* vertex, TriangleSetup& t, TriangleShading& a,
                    int64_t& positive_area2) {
  const int64_t area2 = int64_t(v[1]->x - v[0]->x) * (v[2]->y - v[0]->y) -
                        int64_t(v[1]->y - v[0]->y) * (v[2]->x - v[0]->x);
  if (area2 == 0) return false;  // Degenerate => cull.
  // y-down window space flips the sign of areas: counter-clockwise in NDC (OpenGL's front)
  // <=> area2 < 0 here, the triangle looking clockwise in these coordinates' algebra.
  const bool front = (area2 < 0) != params.transform->mirrored;
  if (params.cull == Cull::Back && !front) return false;
  if (params.cull == Cull::Front && front) return false;

  const int32_t x_min = std::min({v[0]->x, v[1]->x, v[2]->x});
  const int32_t x_max = std::max({v[0]->x, v[1]->x, v[2]->x});
  const int32_t y_min = std::min({v[0]->y, v[1]->y, v[2]->y});
  const int32_t y_max = std::max({v[0]->y, v[1]->y, v[2]->y});
  t.x0 = std::max(first_sample(x_min), 0);
  t.y0 = std::max(first_sample(y_min), 0);
  t.x1 = std::min(last_sample(x_max), params.viewport.width - 1);
  t.y1 = std::min(last_sample(y_max), params.viewport.height - 1);
  // No sample centre in the bounding box => cull: most faces of a dense mesh end here.
  if (t.x0 > t.x1 || t.y0 > t.y1) return false;

  const bool swapped = area2 < 0;  // orient every record the same way so E_k > 0 inside
  const ProjectedVertex* const o[3] = {v[0], swapped ? v[2] : v[1], swapped ? v[1] : v[2]};
  for (int k = 0; k < 3; ++k) {
    t.x[k] = o[k]->x;
    t.y[k] = o[k]->y;
  }
  positive_area2 = swapped ? -area2 : area2;
  for (int k = 0; k < 3; ++k) {
    // Edge k runs from vertex k+1 to k+2. Direct3D's top-left rule in y-down window space: with
    // this winding, a top edge runs exactly horizontally to the right (dy == 0, dx > 0) and a
    // left edge runs upwards (dy < 0). Samples exactly on other edges are left to the neighbour.
    const int a = kEdgeStart[k], b = kEdgeEnd[k];
    const int32_t dx = t.x[b] - t.x[a], dy = t.y[b] - t.y[a];
    const bool top_left = dy < 0 || (dy == 0 && dx > 0);
    t.bias[k] = top_left ? 0 : 1;
  }
  if (!covers_box_samples(t)) return false;
  plane_keys_over_area(o, positive_area2, t);
  t.unused_ = 0;
  t.prim = prim;
  t.draw = params.draw;
  if (params.shade) {
    perspective_weights(o, positive_area2, a);
    for (int k = 0; k < 3; ++k) a.vertex[k] = vertex ? vertex[k == 0 ? 0 : swapped ? 3 - k : k] : 0;
    a.clip_ref = kNoClip;
    a.swapped = swapped ? 1 : 0;
    a.back_facing = front ? 0 : 1;
  }
  return true;
}

// The first pass of binning, done while a just-appended record is at hand: counts it in
// every tile it overlaps (at tile_begin[tile + 2], see bin_records) and notes those tiles as
// first tile | (columns - 1) << 16 | (rows - 1) << 24 (num_tiles <= 2^16, tiles_x, tiles_y <= 2^8).
// Also adds its area to tile_area, split between tiles as its box is (for the choice of shading
// path: the sum estimates a tile's overdraw). `area2` is the record's, in fixed-point units^2.
// The common case, a record inside one tile, inline; one spanning tiles calls emit_spanning.
void emit_spanning(const TriangleSetup& t, float area, const Viewport& vp, SetupChunk& out) {
  const uint32_t tx0 = uint32_t(t.x0) / kTileSizePx, tx1 = uint32_t(t.x1) / kTileSizePx;
  const uint32_t ty0 = uint32_t(t.y0) / kTileSizePx, ty1 = uint32_t(t.y1) / kTileSizePx;
  uint32_t* count = out.tile_begin.data() + 2;
  const bool estimate = !out.tile_area.empty();
  const float per_pixel = area / (float(t.x1 - t.x0 + 1) * float(t.y1 - t.y0 + 1));
  for (uint32_t ty = ty0; ty <= ty1; ++ty) {
    const int rows = std::min(t.y1, int32_t(ty + 1) * kTileSizePx - 1) -
                     std::max(t.y0, int32_t(ty) * kTileSizePx) + 1;
    for (uint32_t tx = tx0; tx <= tx1; ++tx) {
      const int columns = std::min(t.x1, int32_t(tx + 1) * kTileSizePx - 1) -
                          std::max(t.x0, int32_t(tx) * kTileSizePx) + 1;
      ++count[ty * uint32_t(vp.tiles_x) + tx];
      if (estimate) out.tile_area[ty * uint32_t(vp.tiles_x) + tx] += per_pixel * float(rows * columns);
    }
  }
  out.record_tiles.push_back((ty0 * uint32_t(vp.tiles_x) + tx0) | (tx1 - tx0) << 16 | (ty1 - ty0) << 24);
}

inline void emit(const TriangleSetup& t, double area2, const Viewport& vp, SetupChunk& out) {
  const uint32_t tx0 = uint32_t(t.x0) / kTileSizePx, tx1 = uint32_t(t.x1) / kTileSizePx;
  const uint32_t ty0 = uint32_t(t.y0) / kTileSizePx, ty1 = uint32_t(t.y1) / kTileSizePx;
  const float area = float(area2) * (0.5f / float(kSubpixelOne * kSubpixelOne));
  if (tx0 != tx1 || ty0 != ty1) return emit_spanning(t, area, vp, out);
  const uint32_t tile = ty0 * uint32_t(vp.tiles_x) + tx0;
  ++out.tile_begin.data()[2 + tile];
  if (!out.tile_area.empty()) out.tile_area[tile] += area;
  out.record_tiles.push_back(tile);
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

void clip_and_setup(const ivec3& face, uint8_t planes_mask, const SetupParams& params,
                    uint32_t prim, SetupChunk& out) {
  ClipPoint in[3];
  for (int k = 0; k < 3; ++k) {
    const ClipVertex c = transform_point(*params.transform, params.mesh->positions[face[k]]);
    in[k].p_clip = c.p_clip;
    in[k].depth_view = c.depth_view;
    in[k].bary_source = vec3(0.0f);
    in[k].bary_source[k] = 1.0f;
  }
  ClipPoint poly[kMaxClipPoints];
  const int n = clip_triangle(in, planes_mask, *params.planes, poly);
  if (n < 3) return;
  ProjectedVertex projected[kMaxClipPoints];
  for (int i = 0; i < n; ++i) {
    project(poly[i].p_clip, poly[i].depth_view, *params.planes, params.viewport,
            params.orthographic, /*snap_outside=*/true, projected[i]);
    if (projected[i].outcode & kInvalidVertex) return;  // Unrepresentable after clipping => drop.
  }
  for (int i = 1; i + 1 < n; ++i) {  // fan: watertight inside, as all sub-triangles share snaps
    const ProjectedVertex* const tri[3] = {&projected[0], &projected[i], &projected[i + 1]};
    TriangleSetup t;
    TriangleShading a;
    int64_t area2;
    if (!setup_triangle(tri, params, prim, nullptr, t, a, area2)) continue;
    if (params.shade) {
      a.clip_ref = uint32_t(out.clip_bary.size() / 3);
      const int ids[3] = {0, a.swapped ? i + 1 : i, a.swapped ? i : i + 1};
      for (int k = 0; k < 3; ++k) out.clip_bary.push_back(poly[ids[k]].bary_source);
      out.shading.push_back(a);
    }
    out.records.push_back(t);
    emit(t, double(area2), params.viewport, out);
  }
}

using namespace simd;

static_assert(sizeof(ProjectedVertex) == kLanes * sizeof(int32_t) &&
                  offsetof(ProjectedVertex, dx) == 8 && offsetof(ProjectedVertex, key) == 16 &&
                  offsetof(ProjectedVertex, inv_w) == 20 && offsetof(ProjectedVertex, outcode) == 24,
              "project_eight writes a ProjectedVertex as eight 32-bit words");

typedef int64_t l4 __attribute__((vector_size(32)));
typedef uint32_t u8 __attribute__((vector_size(32)));

SR_INLINE i8 float_bits(f8 v) { return i8(v); }
SR_INLINE f4 low_half(f8 v) { return __builtin_shufflevector(v, v, 0, 1, 2, 3); }
SR_INLINE f4 high_half(f8 v) { return __builtin_shufflevector(v, v, 4, 5, 6, 7); }
// A lane mask (all-ones or zero per lane) as one bit per lane.
SR_INLINE unsigned mask_bits(i8 mask) {
  const i4 lo = __builtin_shufflevector(mask, mask, 0, 1, 2, 3);
  const i4 hi = __builtin_shufflevector(mask, mask, 4, 5, 6, 7);
  return unsigned(_mm_movemask_ps(__m128(lo)) | _mm_movemask_ps(__m128(hi)) << 4);
}
SR_INLINE unsigned mask_bits(l4 mask) {
  const __m128d lo = __m128d(__builtin_shufflevector(mask, mask, 0, 1));
  const __m128d hi = __m128d(__builtin_shufflevector(mask, mask, 2, 3));
  return unsigned(_mm_movemask_pd(lo) | _mm_movemask_pd(hi) << 2);
}

// Eight rows of eight 32-bit words become eight columns (records <-> fields).
SR_INLINE void transpose8(i8 (&r)[8]) {
  const i8 t0 = __builtin_shufflevector(r[0], r[1], 0, 8, 1, 9, 4, 12, 5, 13);
  const i8 t1 = __builtin_shufflevector(r[0], r[1], 2, 10, 3, 11, 6, 14, 7, 15);
  const i8 t2 = __builtin_shufflevector(r[2], r[3], 0, 8, 1, 9, 4, 12, 5, 13);
  const i8 t3 = __builtin_shufflevector(r[2], r[3], 2, 10, 3, 11, 6, 14, 7, 15);
  const i8 t4 = __builtin_shufflevector(r[4], r[5], 0, 8, 1, 9, 4, 12, 5, 13);
  const i8 t5 = __builtin_shufflevector(r[4], r[5], 2, 10, 3, 11, 6, 14, 7, 15);
  const i8 t6 = __builtin_shufflevector(r[6], r[7], 0, 8, 1, 9, 4, 12, 5, 13);
  const i8 t7 = __builtin_shufflevector(r[6], r[7], 2, 10, 3, 11, 6, 14, 7, 15);
  const i8 s0 = __builtin_shufflevector(t0, t2, 0, 1, 8, 9, 4, 5, 12, 13);
  const i8 s1 = __builtin_shufflevector(t0, t2, 2, 3, 10, 11, 6, 7, 14, 15);
  const i8 s2 = __builtin_shufflevector(t1, t3, 0, 1, 8, 9, 4, 5, 12, 13);
  const i8 s3 = __builtin_shufflevector(t1, t3, 2, 3, 10, 11, 6, 7, 14, 15);
  const i8 s4 = __builtin_shufflevector(t4, t6, 0, 1, 8, 9, 4, 5, 12, 13);
  const i8 s5 = __builtin_shufflevector(t4, t6, 2, 3, 10, 11, 6, 7, 14, 15);
  const i8 s6 = __builtin_shufflevector(t5, t7, 0, 1, 8, 9, 4, 5, 12, 13);
  const i8 s7 = __builtin_shufflevector(t5, t7, 2, 3, 10, 11, 6, 7, 14, 15);
  r[0] = __builtin_shufflevector(s0, s4, 0, 1, 2, 3, 8, 9, 10, 11);
  r[1] = __builtin_shufflevector(s1, s5, 0, 1, 2, 3, 8, 9, 10, 11);
  r[2] = __builtin_shufflevector(s2, s6, 0, 1, 2, 3, 8, 9, 10, 11);
  r[3] = __builtin_shufflevector(s3, s7, 0, 1, 2, 3, 8, 9, 10, 11);
  r[4] = __builtin_shufflevector(s0, s4, 4, 5, 6, 7, 12, 13, 14, 15);
  r[5] = __builtin_shufflevector(s1, s5, 4, 5, 6, 7, 12, 13, 14, 15);
  r[6] = __builtin_shufflevector(s2, s6, 4, 5, 6, 7, 12, 13, 14, 15);
  r[7] = __builtin_shufflevector(s3, s7, 4, 5, 6, 7, 12, 13, 14, 15);
}

// Eight vertices [i, i + 8) at once, lane by lane the operations of transform_point and project
// (IEEE operations in the same order, no contraction), so the same bits. A vertex that project()
// would not write plainly (outside a plane, not finite, w <= 0, outside the guard band's limit)
// is redone by project() itself afterwards.
SR_INLINE void project_eight(const vec3* positions, const DrawTransform& xf, std::size_t i,
                             const ClipPlanes& planes, const Viewport& viewport, bool orthographic,
                             ProjectedVertex* out) {
  f8 px, py, pz;
  load_xyz8(&positions[i].x, px, py, pz);

  const mat4& m = xf.model_view;
  const mat4& proj = xf.proj;
  f8 v[4], clip[4];
  for (int r = 0; r < 4; ++r)
    v[r] = (splat(m[0][r]) * px + splat(m[1][r]) * py) + (splat(m[2][r]) * pz + splat(m[3][r]));
  for (int r = 0; r < 4; ++r)
    clip[r] = (splat(proj[0][r]) * v[0] + splat(proj[1][r]) * v[1]) +
              (splat(proj[2][r]) * v[2] + splat(proj[3][r]) * v[3]);
  const f8 depth_view = -v[2];

  const i8 exponent = splat(int32_t(0x7f800000));
  const i8 finite = ((float_bits(clip[0]) & exponent) != exponent) &
                    ((float_bits(clip[1]) & exponent) != exponent) &
                    ((float_bits(clip[2]) & exponent) != exponent) &
                    ((float_bits(clip[3]) & exponent) != exponent) &
                    ((float_bits(depth_view) & exponent) != exponent);
  unsigned plain = mask_bits(finite);

  // The double-precision part, four lanes at a time.
  constexpr double kLimit = 32768.0 - 1.0;
  const l4 sign = broadcast<l4>(int64_t(0x8000000000000000ull)), half = l4(broadcast<d4>(0.5));
  const double width = double(viewport.width), height = double(viewport.height);
  i4 fixed[2][2];  // [x / y][half]
  f4 residual[2][2], inv_w_f[2];
  for (int h = 0; h < 2; ++h) {
    const auto part = [h](f8 v) {
      return __builtin_convertvector(h == 0 ? low_half(v) : high_half(v), d4);
    };
    const d4 x = part(clip[0]), y = part(clip[1]), w = part(clip[3]), d = part(depth_view);
    // ClipPlanes::outcode() == 0, project()'s w > 0 and depth > 0, and its window-limit test.
    l4 inside = (d - planes.near >= 0.0) & (planes.far - d >= 0.0) &
                (x - planes.ndc_x_min * w >= 0.0) & (planes.ndc_x_max * w - x >= 0.0) &
                (planes.ndc_y_max * w - y >= 0.0) & (y - planes.ndc_y_min * w >= 0.0) &
                (w > 0.0) & (d > 0.0);
    const d4 inv_w = 1.0 / w;
    const d4 window[2] = {(x * inv_w + 1.0) * 0.5 * width, (1.0 - y * inv_w) * 0.5 * height};
    for (int k = 0; k < 2; ++k) {
      inside &= d4(l4(window[k]) & ~sign) < kLimit;  // |window| < kLimit
      // round_to_fixed: + or - 1/2 by the sign bit, then truncate.
      const d4 scaled = window[k] * double(kSubpixelOne);
      fixed[k][h] = __builtin_convertvector(scaled + d4((l4(scaled) & sign) | half), i4);
      residual[k][h] = __builtin_convertvector(scaled - __builtin_convertvector(fixed[k][h], d4), f4);
    }
    inv_w_f[h] = __builtin_convertvector(inv_w, f4);
    plain &= mask_bits(inside) << (4 * h) | (0xfu << (4 - 4 * h));
  }
  const auto join = [](auto lo, auto hi) {
    return __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7);
  };
  const i8 xi = join(fixed[0][0], fixed[0][1]), yi = join(fixed[1][0], fixed[1][1]);
  const f8 dx = join(residual[0][0], residual[0][1]), dy = join(residual[1][0], residual[1][1]);
  const f8 key = orthographic ? -depth_view : 1.0f / depth_view;
  const f8 inv_w_8 = join(inv_w_f[0], inv_w_f[1]);

  // Eight records: an 8x8 transpose of (x, y, dx, dy, key, inv_w, outcode = 0, padding = 0).
  i8 rows[8] = {xi, yi, float_bits(dx), float_bits(dy), float_bits(key), float_bits(inv_w_8), i8{}, i8{}};
  transpose8(rows);
  ProjectedVertex* o = out + i;
  for (int k = 0; k < 8; ++k) store(o + k, rows[k]);

  for (unsigned redo = ~plain & 0xffu; redo != 0; redo &= redo - 1) {
    const int k = __builtin_ctz(redo);
    const ClipVertex cv = transform_point(xf, positions[i + k]);
    project(cv.p_clip, cv.depth_view, planes, viewport, orthographic, false, o[k]);
  }
}

SR_INLINE void project_range(const MeshData& mesh, const DrawTransform& xf, std::size_t begin,
                             std::size_t end, const ClipPlanes& planes, const Viewport& viewport,
                             bool orthographic, ProjectedVertex* out) {
  const vec3* positions = mesh.positions.data();
  std::size_t i = begin;
  for (; i + kLanes <= end; i += kLanes)
    project_eight(positions, xf, i, planes, viewport, orthographic, out);
  for (; i < end; ++i) {
    const ClipVertex c = transform_point(xf, positions[i]);
    project(c.p_clip, c.depth_view, planes, viewport, orthographic, false, out[i]);
  }
}

SR_TARGET_AVX2 void project_range_avx2(const MeshData& mesh, const DrawTransform& xf,
                                       std::size_t begin, std::size_t end,
                                       const ClipPlanes& planes, const Viewport& viewport,
                                       bool orthographic, ProjectedVertex* out) {
  project_range(mesh, xf, begin, end, planes, viewport, orthographic, out);
}

void project_range_generic(const MeshData& mesh, const DrawTransform& xf, std::size_t begin,
                           std::size_t end, const ClipPlanes& planes, const Viewport& viewport,
                           bool orthographic, ProjectedVertex* out) {
  project_range(mesh, xf, begin, end, planes, viewport, orthographic, out);
}

// One face on its own: what the eight-lane path leaves over (the last faces of a chunk, and any
// face with a vertex outside a plane or not finite).
void setup_face(const SetupParams& params, std::size_t f, SetupChunk& out) {
  const ivec3& face = params.mesh->faces[f];
  const ProjectedVertex* const v[3] = {&params.vertices[face.x], &params.vertices[face.y],
                                       &params.vertices[face.z]};
  const uint8_t any_out = v[0]->outcode | v[1]->outcode | v[2]->outcode;
  if (any_out & kInvalidVertex) return;  // Non-finite after transform => drop.
  if (v[0]->outcode & v[1]->outcode & v[2]->outcode) return;  // All outside one plane => cull.
  if (any_out == 0) {
    TriangleSetup t;
    TriangleShading a;
    int64_t area2;
    if (setup_triangle(v, params, uint32_t(f), &face.x, t, a, area2)) {
      out.records.push_back(t);
      if (params.shade) out.shading.push_back(a);
      emit(t, double(area2), params.viewport, out);
    }
  } else {
    clip_and_setup(face, any_out, params, uint32_t(f), out);
  }
}

SR_INLINE i8 select(i8 mask, i8 a, i8 b) { return (a & mask) | (b & ~mask); }
SR_INLINE f8 select(i8 mask, f8 a, f8 b) { return f8(select(mask, i8(a), i8(b))); }
SR_INLINE d4 select(l4 mask, d4 a, d4 b) { return d4((l4(a) & mask) | (l4(b) & ~mask)); }
SR_INLINE i8 min(i8 a, i8 b) { return a < b ? a : b; }
SR_INLINE i8 max(i8 a, i8 b) { return a < b ? b : a; }
SR_INLINE d4 max(d4 a, d4 b) { return select(l4(a < b), b, a); }  // as std::max
SR_INLINE d4 abs(d4 v) { return d4(l4(v) & ~broadcast<l4>(int64_t(0x8000000000000000ull))); }
// Half h (lanes 4h .. 4h + 3) of eight lanes, widened to double (exactly).
SR_INLINE d4 wide(i8 v, int h) {
  return __builtin_convertvector(h == 0 ? __builtin_shufflevector(v, v, 0, 1, 2, 3)
                                        : __builtin_shufflevector(v, v, 4, 5, 6, 7), d4);
}
SR_INLINE d4 wide(f8 v, int h) {
  return __builtin_convertvector(h == 0 ? low_half(v) : high_half(v), d4);
}

// One corner of eight faces: the ProjectedVertex records as fields, one face per lane.
struct CornerLanes {
  i8 x, y;
  f8 dx, dy, key, inv_w;
  i8 outcode;
};

SR_INLINE CornerLanes gather_corner(const ProjectedVertex* vertices, const int32_t* face_index,
                                    int corner) {
  i8 rows[8];
  for (int j = 0; j < 8; ++j) rows[j] = load<i8>(vertices + face_index[3 * j + corner]);
  transpose8(rows);
  return {rows[0], rows[1], f8(rows[2]), f8(rows[3]), f8(rows[4]), f8(rows[5]),
          rows[6] & splat(0xff)};
}

// Faces [f, f + 8) at once: setup_triangle and plane_keys_over_area lane by lane, with the same
// IEEE operations in the same order (area2, a product of 25-bit integers, is exact in double),
// so the same records. Integer tests (culling, the empty bounding box) come first for all eight;
// the floating-point work only if some face survives. Faces with a vertex outside a plane or not
// finite go to setup_face, in order, so records keep primitive order.
SR_INLINE void setup_eight(const SetupParams& params, std::size_t f, SetupChunk& out) {
  const int32_t* face_index = &params.mesh->faces[f].x;
  CornerLanes v[3];
  for (int k = 0; k < 3; ++k) v[k] = gather_corner(params.vertices, face_index, k);
  const unsigned special = mask_bits((v[0].outcode | v[1].outcode | v[2].outcode) != 0);

  const i8 ex1 = v[1].x - v[0].x, ey1 = v[1].y - v[0].y;
  const i8 ex2 = v[2].x - v[0].x, ey2 = v[2].y - v[0].y;
  d4 area2[2];
  unsigned negative = 0, nonzero = 0;
  for (int h = 0; h < 2; ++h) {
    area2[h] = wide(ex1, h) * wide(ey2, h) - wide(ey1, h) * wide(ex2, h);
    negative |= mask_bits(l4(area2[h] < 0.0)) << (4 * h);
    nonzero |= mask_bits(l4(area2[h] != 0.0)) << (4 * h);
  }
  const unsigned front = negative ^ (params.transform->mirrored ? 0xffu : 0u);
  const unsigned facing = params.cull == Cull::Back ? front
                          : params.cull == Cull::Front ? ~front : 0xffu;
  const i8 x_min = min(min(v[0].x, v[1].x), v[2].x), x_max = max(max(v[0].x, v[1].x), v[2].x);
  const i8 y_min = min(min(v[0].y, v[1].y), v[2].y), y_max = max(max(v[0].y, v[1].y), v[2].y);
  const i8 zero{}, half = splat(kSubpixelHalf), round_up = splat(kSubpixelOne - 1 - kSubpixelHalf);
  const i8 x0 = max((x_min + round_up) >> kSubpixelBits, zero);
  const i8 y0 = max((y_min + round_up) >> kSubpixelBits, zero);
  const i8 x1 = min((x_max - half) >> kSubpixelBits, splat(params.viewport.width - 1));
  const i8 y1 = min((y_max - half) >> kSubpixelBits, splat(params.viewport.height - 1));
  const unsigned nonempty = mask_bits((x0 <= x1) & (y0 <= y1));
  unsigned keep = ~special & nonzero & facing & nonempty & 0xffu;
  if ((keep | special) == 0) return;  // the common case in a dense mesh

  alignas(32) int32_t lane_x[3][8], lane_y[3][8], lane_box[4][8], lane_bias[3][8];
  alignas(32) float lane_key[3][8], lane_persp[3][8];
  alignas(32) double lane_area2[8];
  if (keep != 0) {
    // Orient: vertices 1 and 2 swap where area2 < 0.
    const i8 swapped = (splat(int32_t(negative)) & i8{1, 2, 4, 8, 16, 32, 64, 128}) != zero;
    const CornerLanes* o[3] = {&v[0], &v[1], &v[2]};
    i8 ox[3], oy[3];
    f8 odx[3], ody[3], okey[3];
    for (int k = 0; k < 3; ++k) {
      const CornerLanes& a = *o[k];
      const CornerLanes& b = *o[k == 0 ? 0 : 3 - k];  // the vertex it swaps with
      ox[k] = select(swapped, b.x, a.x);
      oy[k] = select(swapped, b.y, a.y);
      odx[k] = select(swapped, b.dx, a.dx);
      ody[k] = select(swapped, b.dy, a.dy);
      okey[k] = select(swapped, b.key, a.key);
    }
    // The top-left rule, as in setup_triangle: bias 0 for top and left edges, else 1.
    i8 edge_dx[3], edge_dy[3], bias[3];
    for (int k = 0; k < 3; ++k) {
      const int a = kEdgeStart[k], b = kEdgeEnd[k];
      edge_dx[k] = ox[b] - ox[a];
      edge_dy[k] = oy[b] - oy[a];
      const i8 top_left = (edge_dy[k] < zero) | ((edge_dy[k] == zero) & (edge_dx[k] > zero));
      bias[k] = top_left + splat(1);
    }
    // A box holding one or two sample centres: test them (covers_box_samples).
    const i8 few = (x1 - x0) + (y1 - y0) <= splat(1);
    if (keep & mask_bits(few)) {
      i8 covered = zero;
      for (int s = 0; s < 2; ++s) {
        const i8 cx = ((s == 0 ? x0 : x1) << kSubpixelBits) + half;
        const i8 cy = ((s == 0 ? y0 : y1) << kSubpixelBits) + half;
        i8 inside = ~zero;
        for (int k = 0; k < 3; ++k) {
          const int a = kEdgeStart[k];
          // Exact in 32 bits where few samples bound the triangle (spans < 3 px); lanes where
          // they do not wrap harmlessly (unsigned) and are not used.
          const u8 e = u8(edge_dx[k]) * u8(cy - oy[a]) - u8(edge_dy[k]) * u8(cx - ox[a]);
          inside &= i8(e) >= bias[k];
        }
        covered |= inside;
      }
      keep &= ~mask_bits(few & ~covered);
    }
    if (keep != 0) {
      f8 oinv_w[3];
      for (int k = 0; k < 3; ++k) {
        store(lane_x[k], ox[k]);
        store(lane_y[k], oy[k]);
        oinv_w[k] = select(swapped, o[k == 0 ? 0 : 3 - k]->inv_w, o[k]->inv_w);
        store(lane_bias[k], bias[k]);
      }
      store(lane_box[0], x0);
      store(lane_box[1], y0);
      store(lane_box[2], x1);
      store(lane_box[3], y1);
      // plane_keys_over_area and perspective_weights, four lanes at a time (a half without
      // survivors is skipped).
      constexpr double kMinArea = 1e-6 * kSubpixelOne * kSubpixelOne;
      f4 key_over_area[3][2] = {}, persp[3][2] = {};
      for (int h = 0; h < 2; ++h) {
        if ((keep >> (4 * h) & 0xfu) == 0) continue;
        const d4 t_area2 = abs(area2[h]);
        store(lane_area2 + 4 * h, t_area2);
        const d4 dx0 = wide(odx[0], h), dy0 = wide(ody[0], h);
        const d4 ex1 = wide(ox[1] - ox[0], h) + (wide(odx[1], h) - dx0);
        const d4 ey1 = wide(oy[1] - oy[0], h) + (wide(ody[1], h) - dy0);
        const d4 ex2 = wide(ox[2] - ox[0], h) + (wide(odx[2], h) - dx0);
        const d4 ey2 = wide(oy[2] - oy[0], h) + (wide(ody[2], h) - dy0);
        const d4 area = ex1 * ey2 - ey1 * ex2;
        const d4 r = 1.0 / (area * t_area2);
        const d4 inv_area = t_area2 * r, inv_area2 = area * r;
        const d4 key0 = wide(okey[0], h);
        const d4 dkey1 = wide(okey[1], h) - key0, dkey2 = wide(okey[2], h) - key0;
        l4 well_shaped = abs(area) > kMinArea;
        d4 fitted[3];
        for (int k = 0; k < 3; ++k) {
          const d4 key = wide(okey[k], h);
          const d4 sx = -wide(odx[k], h), sy = -wide(ody[k], h);
          const d4 mu1 = (sx * ey2 - sy * ex2) * inv_area, mu2 = (ex1 * sy - ey1 * sx) * inv_area;
          const d4 mu0 = -(mu1 + mu2);
          fitted[k] = key + (mu1 * dkey1 + mu2 * dkey2);
          well_shaped &= (abs(mu0) <= 0.25) & (abs(mu1) <= 0.25) & (abs(mu2) <= 0.25) &
                         ((fitted[k] > 0.0) == (key > 0.0));
        }
        // The plain keys' division only where a surviving lane needs it (slivers are rare).
        d4 inv_t_area2{};
        if (~mask_bits(well_shaped) & keep >> (4 * h) & 0xfu) inv_t_area2 = 1.0 / t_area2;
        for (int k = 0; k < 3; ++k)
          key_over_area[k][h] = __builtin_convertvector(
              select(well_shaped, fitted[k] * inv_area2, wide(okey[k], h) * inv_t_area2), f4);
        if (params.shade) {
          const d4 w0 = wide(oinv_w[0], h), w1 = wide(oinv_w[1], h), w2 = wide(oinv_w[2], h);
          const d4 scale = 1.0 / (max(max(w0, w1), w2) * t_area2);
          persp[0][h] = __builtin_convertvector(w0 * scale, f4);
          persp[1][h] = __builtin_convertvector(w1 * scale, f4);
          persp[2][h] = __builtin_convertvector(w2 * scale, f4);
        }
      }
      for (int k = 0; k < 3; ++k) {
        store(lane_key[k], __builtin_shufflevector(key_over_area[k][0], key_over_area[k][1],
                                                   0, 1, 2, 3, 4, 5, 6, 7));
        store(lane_persp[k], __builtin_shufflevector(persp[k][0], persp[k][1],
                                                     0, 1, 2, 3, 4, 5, 6, 7));
      }
    }
  }

  for (unsigned todo = keep | special; todo != 0; todo &= todo - 1) {
    const int j = __builtin_ctz(todo);
    if (special >> j & 1) {
      setup_face(params, f + j, out);
      continue;
    }
    TriangleSetup& t = out.records.emplace_back();  // written in place, every field
    for (int k = 0; k < 3; ++k) {
      t.x[k] = lane_x[k][j];
      t.y[k] = lane_y[k][j];
      t.key_over_area[k] = lane_key[k][j];
      t.bias[k] = uint8_t(lane_bias[k][j]);
    }
    t.unused_ = 0;
    t.x0 = lane_box[0][j];
    t.y0 = lane_box[1][j];
    t.x1 = lane_box[2][j];
    t.y1 = lane_box[3][j];
    t.prim = uint32_t(f + j);
    t.draw = params.draw;
    if (params.shade) {
      TriangleShading& a = out.shading.emplace_back();
      const bool swapped = negative >> j & 1;
      const int32_t* vertex = face_index + 3 * j;
      for (int k = 0; k < 3; ++k) a.persp[k] = lane_persp[k][j];
      a.vertex[0] = vertex[0];
      a.vertex[1] = vertex[swapped ? 2 : 1];
      a.vertex[2] = vertex[swapped ? 1 : 2];
      a.clip_ref = kNoClip;
      a.swapped = swapped ? 1 : 0;
      a.back_facing = (front >> j & 1) ? 0 : 1;
    }
    emit(t, lane_area2[j], params.viewport, out);
  }
}

// Faces reach their vertices through indices, and the order of a mesh's vertices is its
// author's: in a large mesh each gather from the projected vertices may be a cache miss that no
// hardware prefetcher foresees. So the vertices of the faces this many places ahead are fetched
// early. Setup for ico8 at 1024x1024, depth only, 2 threads: 8.5 -> 8.0 ms with vertices in
// order of first use, 10.1 -> 8.1 ms in trimesh's icosphere order, 20 -> 12 ms shuffled; the
// same for a mesh that fits in cache.
constexpr std::size_t kPrefetchFaces = 64;

SR_INLINE void setup_range(const SetupParams& params, std::size_t begin, std::size_t end,
                           SetupChunk& out) {
  const std::size_t num_faces = params.mesh->faces.size();
  std::size_t f = begin;
  for (; f + kLanes <= end; f += kLanes) {
    if (f + kPrefetchFaces + kLanes <= num_faces) {
      const int32_t* ahead = &params.mesh->faces[f + kPrefetchFaces].x;
      for (int j = 0; j < 3 * kLanes; ++j) __builtin_prefetch(params.vertices + ahead[j]);
    }
    setup_eight(params, f, out);
  }
  for (; f < end; ++f) setup_face(params, f, out);
}

SR_TARGET_AVX2 void setup_range_avx2(const SetupParams& params, std::size_t begin,
                                     std::size_t end, SetupChunk& out) {
  setup_range(params, begin, end, out);
}

void setup_range_generic(const SetupParams& params, std::size_t begin, std::size_t end,
                         SetupChunk& out) {
  setup_range(params, begin, end, out);
}

}  // namespace

void project_vertices(const MeshData& mesh, const DrawTransform& xf, std::size_t begin,
                      std::size_t end, const ClipPlanes& planes, const Viewport& viewport,
                      bool orthographic, Isa isa, ProjectedVertex* out) {
  (isa == Isa::Avx2 ? project_range_avx2 : project_range_generic)(mesh, xf, begin, end, planes,
                                                                  viewport, orthographic, out);
}

void setup_chunk(const SetupParams& params, std::size_t begin, std::size_t end, SetupChunk& out) {
  out.records.clear();
  out.shading.clear();
  out.record_tiles.clear();
  out.clip_bary.clear();
  out.tile_begin.assign(params.viewport.num_tiles() + 2, 0);
  out.tile_area.assign(params.estimate_overdraw ? params.viewport.num_tiles() : 0, 0.0f);
  (params.isa == Isa::Avx2 ? setup_range_avx2 : setup_range_generic)(params, begin, end, out);
  bin_records(params.viewport, out);
}

}  // namespace sr
