// Setup stage, one face at a time: cull, orient, bounding box, edge biases, depth plane and
// perspective weights of each triangle, clipping where a vertex lies outside a plane.
#include "setup.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <utility>

namespace sr {

namespace {

// First and last pixel with a sample in [lo, hi] (fixed point), along an axis whose samples sit
// at offsets [min_offset, max_offset] from the pixel's corner: a pixel j has one when
// j * 256 + max_offset >= lo and j * 256 + min_offset <= hi. (One sample at the centre: both
// offsets 128.)
inline int32_t first_sample(int32_t lo, int32_t max_offset) {
  return (lo - max_offset + kSubpixelOne - 1) >> kSubpixelBits;
}
inline int32_t last_sample(int32_t hi, int32_t min_offset) { return (hi - min_offset) >> kSubpixelBits; }

// Sets key_over_area from depth keys for the snapped vertices that reproduce the unsnapped
// triangle's depth plane, and kExactDepth in t.flags.
//
// Coverage must use the snapped triangle (exact edge functions => watertight), but its keys need
// not: snapping moves a vertex by up to 1/512 px, and where depth changes fast across the screen
// (grazing planes) interpolating the original keys over the moved triangle is off by that shift
// times the depth gradient (3e-3 relative seen on a floor near the horizon). The key is affine in
// window space, so evaluating the true plane at the snapped vertices makes the interpolated key
// exact (to rounding) at every sample. Slivers, whose true plane is ill-conditioned, keep the
// original keys.
// `mu` (if not null) receives each snapped vertex's SnapShift (ExactWeights), of a well-shaped
// triangle only.
void plane_keys_over_area(const ProjectedVertex* const o[3], int64_t positive_area2,
                          TriangleSetup& t, double (*mu)[3]) {
  const double area2 = double(positive_area2);
  // The unsnapped triangle (its edges from vertex 0, in fixed-point units).
  const float dx[3] = {o[0]->dx, o[1]->dx, o[2]->dx}, dy[3] = {o[0]->dy, o[1]->dy, o[2]->dy};
  const SnapShift snap(t.x, t.y, dx, dy);
  if (!snap.degenerate()) {
    // One division for both reciprocals (divisions dominate this function's latency).
    const double r = 1.0 / (snap.area * area2);
    const double inv_area = area2 * r, inv_area2 = snap.area * r;
    const double dkey1 = double(o[1]->key) - double(o[0]->key);
    const double dkey2 = double(o[2]->key) - double(o[0]->key);
    bool well_shaped = true;
    // The plane's value at snapped vertex v is v's key plus its mu applied to the keys (the
    // changes sum to 0), which keeps the small correction apart from the large key.
    double shift[3][3];
    auto fitted = [&](int k) {
      const ProjectedVertex& v = *o[k];
      double* m = shift[k];
      snap.shift(inv_area, v.dx, v.dy, m);
      const double key = double(v.key) + (m[1] * dkey1 + m[2] * dkey2);
      // A well-shaped triangle moves its barycentrics a little; much more => sliver. The key's
      // sign is its camera type.
      well_shaped &= (std::fabs(m[0]) <= 0.25) & (std::fabs(m[1]) <= 0.25) &
                     (std::fabs(m[2]) <= 0.25) & ((key > 0.0) == (v.key > 0.0f));
      return key;
    };
    const double key0 = fitted(0), key1 = fitted(1), key2 = fitted(2);
    if (well_shaped && mu)
      for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j) mu[k][j] = shift[k][j];
    if (well_shaped) {
      t.key_over_area[0] = float(key0 * inv_area2);
      t.key_over_area[1] = float(key1 * inv_area2);
      t.key_over_area[2] = float(key2 * inv_area2);
      return;
    }
  }
  t.flags |= kExactDepth;
  const double inv_area2 = 1.0 / area2;
  for (int k = 0; k < 3; ++k) t.key_over_area[k] = float(double(o[k]->key) * inv_area2);
}

// False if the bounding box holds one or two pixels and the triangle covers none of their samples (the
// rasterizer's exact edge test, E_k - bias_k >= 0). A dense mesh has many such triangles: in a
// 1.3M-face sphere at 1024x1024, a quarter of those with a sample in their box; no record is
// cheaper than a record that draws nothing.
bool covers_box_samples(const TriangleSetup& t, const SamplePattern& samples) {
  if ((t.x1 - t.x0) + (t.y1 - t.y0) > 1) return true;
  for (const auto& [px, py] : {std::pair{t.x0, t.y0}, std::pair{t.x1, t.y1}}) {
    for (int s = 0; s < samples.count; ++s) {
      const int64_t cx = int64_t(px) * kSubpixelOne + samples.x[s];
      const int64_t cy = int64_t(py) * kSubpixelOne + samples.y[s];
      bool inside = true;
      for (int k = 0; k < 3; ++k) {
        const int a = kEdgeStart[k], b = kEdgeEnd[k];
        const int64_t e = int64_t(t.x[b] - t.x[a]) * (cy - t.y[a]) - int64_t(t.y[b] - t.y[a]) * (cx - t.x[a]);
        inside &= e - t.bias[k] >= 0;
      }
      if (inside) return true;
    }
  }
  return false;
}

// Shading's perspective weights (TriangleShading::persp) of oriented vertices o, and with `mu`
// (a well-shaped triangle's SnapShifts, else null: a sliver) the exact weights `e`.
void perspective_weights(const ProjectedVertex* const o[3], int64_t positive_area2,
                         TriangleShading& a, const double (*mu)[3], ExactWeights* e) {
  const double max_inv_w = std::max({double(o[0]->inv_w), double(o[1]->inv_w), double(o[2]->inv_w)});
  const double scale = 1.0 / (max_inv_w * double(positive_area2));
  double persp[3];
  for (int k = 0; k < 3; ++k) a.persp[k] = float(persp[k] = double(o[k]->inv_w) * scale);
  if (!e) return;
  for (int j = 0; j < 3; ++j)
    for (int k = 0; k < 3; ++k)
      e->q[j][k] = mu ? float(persp[j] * ((j == k ? 1.0 : 0.0) + mu[k][j]))
                      : j == k ? a.persp[j] : 0.0f;
}

}  // namespace

// (setup.hpp)
bool setup_triangle(const ProjectedVertex* const v[3], const SetupParams& params, uint32_t prim,
                    const int32_t* vertex, TriangleSetup& t, TriangleShading& a, ExactWeights& e,
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
  const SamplePattern& samples = params.viewport.samples;
  t.x0 = std::max(first_sample(x_min, samples.max_x), 0);
  t.y0 = std::max(first_sample(y_min, samples.max_y), 0);
  t.x1 = std::min(last_sample(x_max, samples.min_x), params.viewport.width - 1);
  t.y1 = std::min(last_sample(y_max, samples.min_y), params.viewport.height - 1);
  // No sample in the bounding box => cull: most faces of a dense mesh end here.
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
  if (!covers_box_samples(t, samples)) return false;
  t.flags = 0;
  double mu[3][3];
  plane_keys_over_area(o, positive_area2, t, params.exact_weights ? mu : nullptr);
  t.prim = prim;
  t.draw = params.draw;
  if (params.shade) {
    perspective_weights(o, positive_area2, a, t.flags & kExactDepth ? nullptr : mu,
                        params.exact_weights ? &e : nullptr);
    for (int k = 0; k < 3; ++k) a.vertex[k] = vertex ? vertex[k == 0 ? 0 : swapped ? 3 - k : k] : 0;
    a.clip_ref = kNoClip;
    a.swapped = swapped ? 1 : 0;
    a.back_facing = front ? 0 : 1;
  }
  return true;
}

namespace {

void clip_and_setup(const ivec3& face, uint8_t planes_mask, const SetupParams& params,
                    uint32_t prim, SetupChunk& out) {
  ClipPoint in[3];
  for (int k = 0; k < 3; ++k) {
    const vec3& position = params.mesh->positions[face[k]];
    const ClipVertex c = transform_point(*params.transform, position);
    in[k].p_clip = c.p_clip;
    in[k].depth_view = c.depth_view;
    const ClipVertexD d = transform_point_d(*params.transform, position);
    in[k].p_clip_d = d.p_clip;
    in[k].depth_view_d = d.depth_view;
    in[k].bary_source = vec3(0.0f);
    in[k].bary_source[k] = 1.0f;
  }
  ClipPoint poly[kMaxClipPoints];
  const int n = clip_triangle(in, planes_mask, *params.planes, poly);
  if (n < 3) return;
  ProjectedVertex projected[kMaxClipPoints];
  for (int i = 0; i < n; ++i) {
    const ExactClip exact{poly[i].p_clip_d.x, poly[i].p_clip_d.y, poly[i].p_clip_d.w,
                          poly[i].depth_view_d};
    project(poly[i].p_clip, poly[i].depth_view, exact, *params.planes, params.viewport,
            params.orthographic, /*snap_outside=*/true, projected[i]);
    if (projected[i].outcode & kInvalidVertex) return;  // Unrepresentable after clipping => drop.
  }
  setup_fan(projected, poly, n, params, prim, out);
}

}  // namespace

void setup_fan(const ProjectedVertex* projected, const ClipPoint* poly, int n, const SetupParams& params,
               uint32_t prim, SetupChunk& out) {
  for (int i = 1; i + 1 < n; ++i) {  // fan: watertight inside, as all sub-triangles share snaps
    const ProjectedVertex* const tri[3] = {&projected[0], &projected[i], &projected[i + 1]};
    TriangleSetup t;
    TriangleShading a;
    ExactWeights e;
    int64_t area2;
    if (!setup_triangle(tri, params, prim, nullptr, t, a, e, area2)) continue;
    if (params.shade) {
      a.clip_ref = uint32_t(out.clip_bary.size() / 3);
      const int ids[3] = {0, a.swapped ? i + 1 : i, a.swapped ? i : i + 1};
      for (int k = 0; k < 3; ++k) out.clip_bary.push_back(poly[ids[k]].bary_source);
      out.shading.push_back(a);
      if (params.exact_weights) out.exact.push_back(e);
    }
    out.records.push_back(t);
    emit(t.x0, t.y0, t.x1, t.y1, double(area2), params.viewport, out);
  }
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
    ExactWeights e;
    int64_t area2;
    if (setup_triangle(v, params, uint32_t(f), &face.x, t, a, e, area2)) {
      out.records.push_back(t);
      if (params.shade) out.shading.push_back(a);
      if (params.shade && params.exact_weights) out.exact.push_back(e);
      emit(t.x0, t.y0, t.x1, t.y1, double(area2), params.viewport, out);
    }
  } else {
    clip_and_setup(face, any_out, params, uint32_t(f), out);
  }
}

void setup_chunk(const SetupParams& params, std::size_t begin, std::size_t end, SetupChunk& out) {
  out.alpha = params.alpha;
  out.records.clear();
  out.shading.clear();
  out.record_tiles.clear();
  out.clip_bary.clear();
  out.exact.clear();
  out.tile_begin.assign(params.viewport.num_tiles() + 2, 0);
  out.tile_area.assign(params.estimate_overdraw ? params.viewport.num_tiles() : 0, 0.0f);
  setup_faces(params, begin, end, out);
  bin_records(params.viewport, out);
}

}  // namespace sr
