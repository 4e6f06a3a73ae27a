// Setup stage: every per-triangle division, snap, cull, bounding box and edge equation.
#include "setup.hpp"

#include <algorithm>
#include <cmath>

namespace sr {

namespace {

// Round half away from zero (as lround) by truncation: one instruction instead of a libm call.
inline int32_t round_to_fixed(double window) {
  const double scaled = window * kSubpixelOne;
  return int32_t(scaled + (scaled >= 0.0 ? 0.5 : -0.5));
}

// Snaps one vertex. With `snap_outside`, a vertex outside some plane is snapped too (clipping
// output that rounding left a hair outside the plane it was clipped to: the guard band's margin
// keeps it representable).
ProjectedVertex project(const vec4& p_clip, float depth_view, const ClipPlanes& planes,
                        const Viewport& viewport, bool orthographic, bool snap_outside) {
  ProjectedVertex v{};
  v.p_clip = p_clip;
  v.depth_view = depth_view;
  const bool finite = std::isfinite(p_clip.x) && std::isfinite(p_clip.y) &&
                      std::isfinite(p_clip.z) && std::isfinite(p_clip.w) &&
                      std::isfinite(depth_view);
  if (!finite) {
    v.outcode = kInvalidVertex;
    return v;
  }
  v.outcode = planes.outcode(p_clip, depth_view);
  if (v.outcode != 0 && !snap_outside) return v;
  if (!(p_clip.w > 0.0f) || !(depth_view > 0.0f)) {  // not a projection we can rasterize
    v.outcode = kInvalidVertex;
    return v;
  }
  // Double precision: the snapped position must not depend on rounding in the divide.
  const double inv_w = 1.0 / double(p_clip.w);
  const double x_window = (double(p_clip.x) * inv_w + 1.0) * 0.5 * viewport.width;
  const double y_window = (1.0 - double(p_clip.y) * inv_w) * 0.5 * viewport.height;
  // Inside the guard band (+ margin) => |window| < 2^15, so fixed values fit in 24 bits.
  constexpr double kLimit = 32768.0 - 1.0;
  if (!(std::fabs(x_window) < kLimit && std::fabs(y_window) < kLimit)) {
    v.outcode = kInvalidVertex;
    return v;
  }
  v.x_window = x_window;
  v.y_window = y_window;
  v.x = round_to_fixed(x_window);
  v.y = round_to_fixed(y_window);
  v.key = orthographic ? -depth_view : float(1.0 / double(depth_view));
  v.inv_w = float(inv_w);
  return v;
}

// First and last pixel whose centre (j * 256 + 128) lies in [lo, hi] (fixed point).
inline int32_t first_sample(int32_t lo) { return (lo - kSubpixelHalf + kSubpixelOne - 1) >> kSubpixelBits; }
inline int32_t last_sample(int32_t hi) { return (hi - kSubpixelHalf) >> kSubpixelBits; }

// Depth keys for the snapped vertices that reproduce the unsnapped triangle's depth plane.
//
// Coverage must use the snapped triangle (exact edge functions => watertight), but its keys need
// not: snapping moves a vertex by up to 1/512 px, and where depth changes fast across the screen
// (grazing planes) interpolating the original keys over the moved triangle is off by that shift
// times the depth gradient (3e-3 relative seen on a floor near the horizon). The key is affine in
// window space, so evaluating the true plane at the snapped vertices makes the interpolated key
// exact (to rounding) at every sample. Slivers, whose true plane is ill-conditioned, keep the
// original keys.
void true_plane_keys(const ProjectedVertex* const o[3], const TriangleSetup& t, float keys[3]) {
  for (int k = 0; k < 3; ++k) keys[k] = o[k]->key;
  const double x0 = o[0]->x_window, y0 = o[0]->y_window;
  const double ex1 = o[1]->x_window - x0, ey1 = o[1]->y_window - y0;
  const double ex2 = o[2]->x_window - x0, ey2 = o[2]->y_window - y0;
  const double area = ex1 * ey2 - ey1 * ex2;
  if (!(std::fabs(area) > 1e-6)) return;
  const double inv_area = 1.0 / area;
  double fitted[3];
  for (int k = 0; k < 3; ++k) {
    const double dx = t.x[k] * (1.0 / kSubpixelOne) - x0, dy = t.y[k] * (1.0 / kSubpixelOne) - y0;
    const double mu1 = (dx * ey2 - dy * ex2) * inv_area, mu2 = (ex1 * dy - ey1 * dx) * inv_area;
    const double mu0 = 1.0 - mu1 - mu2;
    // A well-shaped triangle has mu ~ the unit vector of vertex k; far from it => sliver.
    if (std::fabs(mu0 - (k == 0)) > 0.25 || std::fabs(mu1 - (k == 1)) > 0.25 ||
        std::fabs(mu2 - (k == 2)) > 0.25)
      return;
    fitted[k] = mu0 * o[0]->key + mu1 * o[1]->key + mu2 * o[2]->key;
    if ((fitted[k] > 0.0) != (o[k]->key > 0.0f)) return;  // the key's sign is its camera type
  }
  for (int k = 0; k < 3; ++k) keys[k] = float(fitted[k]);
}

// Builds the record for one snapped triangle. Returns false if it is culled, degenerate or
// covers no sample centre.
bool setup_triangle(const ProjectedVertex* v[3], const SetupParams& params, uint32_t prim,
                    TriangleSetup& t, bool& swapped) {
  const int64_t area2 = int64_t(v[1]->x - v[0]->x) * (v[2]->y - v[0]->y) -
                        int64_t(v[1]->y - v[0]->y) * (v[2]->x - v[0]->x);
  if (area2 == 0) return false;  // Degenerate => cull.
  // y-down window space flips the sign of areas: counter-clockwise in NDC (OpenGL's front)
  // <=> area2 < 0 here, the triangle looking clockwise in these coordinates' algebra.
  const bool front = (area2 < 0) != params.mirrored;
  if (params.cull == Cull::Back && !front) return false;
  if (params.cull == Cull::Front && front) return false;

  swapped = area2 < 0;  // orient every record the same way so E_k > 0 inside
  const ProjectedVertex* o[3] = {v[0], swapped ? v[2] : v[1], swapped ? v[1] : v[2]};
  int32_t x_min = INT32_MAX, x_max = INT32_MIN, y_min = INT32_MAX, y_max = INT32_MIN;
  for (int k = 0; k < 3; ++k) {
    t.x[k] = o[k]->x;
    t.y[k] = o[k]->y;
    x_min = std::min(x_min, t.x[k]); x_max = std::max(x_max, t.x[k]);
    y_min = std::min(y_min, t.y[k]); y_max = std::max(y_max, t.y[k]);
  }
  t.x0 = std::max(first_sample(x_min), 0);
  t.y0 = std::max(first_sample(y_min), 0);
  t.x1 = std::min(last_sample(x_max), params.viewport.width - 1);
  t.y1 = std::min(last_sample(y_max), params.viewport.height - 1);
  if (t.x0 > t.x1 || t.y0 > t.y1) return false;  // No sample centre in the bounding box => cull.

  t.area2 = swapped ? -area2 : area2;
  float keys[3];
  true_plane_keys(o, t, keys);
  const double inv_area2 = 1.0 / double(t.area2);
  for (int k = 0; k < 3; ++k) {
    // Edge k runs from vertex k+1 to k+2. Direct3D's top-left rule in y-down window space: with
    // this winding, a top edge runs exactly horizontally to the right (dy == 0, dx > 0) and a
    // left edge runs upwards (dy < 0). Samples exactly on other edges are left to the neighbour.
    const int a = kEdgeStart[k], b = kEdgeEnd[k];
    const int32_t dx = t.x[b] - t.x[a], dy = t.y[b] - t.y[a];
    const bool top_left = dy < 0 || (dy == 0 && dx > 0);
    t.bias[k] = top_left ? 0 : 1;
    t.key_over_area[k] = float(double(keys[k]) * inv_area2);
    t.inv_w[k] = o[k]->inv_w;
  }
  t.prim = prim;
  t.draw = params.draw;
  t.clip_ref = kNoClip;
  t.corner[0] = 0;
  t.corner[1] = swapped ? 2 : 1;
  t.corner[2] = swapped ? 1 : 2;
  t.back_facing = front ? 0 : 1;
  return true;
}

void clip_and_setup(const ProjectedVertex* v[3], uint8_t planes_mask, const SetupParams& params,
                    uint32_t prim, SetupChunk& out) {
  ClipPoint in[3];
  for (int k = 0; k < 3; ++k) {
    in[k].p_clip = v[k]->p_clip;
    in[k].depth_view = v[k]->depth_view;
    in[k].bary_source = vec3(0.0f);
    in[k].bary_source[k] = 1.0f;
  }
  ClipPoint poly[kMaxClipPoints];
  const int n = clip_triangle(in, planes_mask, *params.planes, poly);
  if (n < 3) return;
  ProjectedVertex projected[kMaxClipPoints];
  for (int i = 0; i < n; ++i) {
    projected[i] = project(poly[i].p_clip, poly[i].depth_view, *params.planes, params.viewport,
                           params.orthographic, /*snap_outside=*/true);
    if (projected[i].outcode & kInvalidVertex) return;  // Unrepresentable after clipping => drop.
  }
  for (int i = 1; i + 1 < n; ++i) {  // fan: watertight inside, as all sub-triangles share snaps
    const ProjectedVertex* tri[3] = {&projected[0], &projected[i], &projected[i + 1]};
    TriangleSetup t;
    bool swapped = false;
    if (!setup_triangle(tri, params, prim, t, swapped)) continue;
    t.clip_ref = uint32_t(out.clip_bary.size() / 3);
    const int ids[3] = {0, swapped ? i + 1 : i, swapped ? i : i + 1};
    for (int k = 0; k < 3; ++k) out.clip_bary.push_back(poly[ids[k]].bary_source);
    out.records.push_back(t);
  }
}

}  // namespace

void project_vertices(const ClipVertex* in, std::size_t begin, std::size_t end,
                      const ClipPlanes& planes, const Viewport& viewport, bool orthographic,
                      ProjectedVertex* out) {
  for (std::size_t i = begin; i < end; ++i)
    out[i] = project(in[i - begin].p_clip, in[i - begin].depth_view, planes, viewport, orthographic, false);
}

void setup_chunk(const SetupParams& params, std::size_t begin, std::size_t end, SetupChunk& out) {
  out.records.clear();
  out.clip_bary.clear();
  const ivec3* faces = params.mesh->faces.data();
  for (std::size_t f = begin; f < end; ++f) {
    const ProjectedVertex* v[3] = {&params.vertices[faces[f].x], &params.vertices[faces[f].y],
                                   &params.vertices[faces[f].z]};
    const uint8_t any_out = v[0]->outcode | v[1]->outcode | v[2]->outcode;
    if (any_out & kInvalidVertex) continue;  // Non-finite after transform => drop.
    if (v[0]->outcode & v[1]->outcode & v[2]->outcode) continue;  // All outside one plane => cull.
    if (any_out == 0) {
      TriangleSetup t;
      bool swapped;
      if (setup_triangle(v, params, uint32_t(f), t, swapped)) out.records.push_back(t);
    } else {
      clip_and_setup(v, any_out, params, uint32_t(f), out);
    }
  }

  // Bin: counting sort of (tile, record) pairs keeps records in primitive order within a tile.
  const Viewport& vp = params.viewport;
  out.tile_begin.assign(vp.num_tiles() + 1, 0);
  for (const TriangleSetup& t : out.records)
    for (int ty = t.y0 / kTileSizePx; ty <= t.y1 / kTileSizePx; ++ty)
      for (int tx = t.x0 / kTileSizePx; tx <= t.x1 / kTileSizePx; ++tx)
        ++out.tile_begin[ty * vp.tiles_x + tx + 1];
  for (int i = 0; i < vp.num_tiles(); ++i) out.tile_begin[i + 1] += out.tile_begin[i];
  out.tile_records.resize(out.tile_begin[vp.num_tiles()]);
  std::vector<uint32_t> cursor(out.tile_begin.begin(), out.tile_begin.end() - 1);
  for (uint32_t r = 0; r < out.records.size(); ++r) {
    const TriangleSetup& t = out.records[r];
    for (int ty = t.y0 / kTileSizePx; ty <= t.y1 / kTileSizePx; ++ty)
      for (int tx = t.x0 / kTileSizePx; tx <= t.x1 / kTileSizePx; ++tx)
        out.tile_records[cursor[ty * vp.tiles_x + tx]++] = r;
  }
}

}  // namespace sr
