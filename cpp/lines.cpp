// Lines and points: setup once per render, then the per-tile overlay (rules: lines.hpp).
#include "lines.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace sr {

namespace {

// Primitives per setup block: enough that a million points make a few dozen work items.
constexpr std::size_t kPrimitiveBlock = 16384;

bool finite3(const vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// No NaN or inf among `rows`: one pass of exponent tests the compiler vectorises (run on every
// render, where std::isfinite per component was a measurable share of a point cloud's render:
// benchmarks/RESULTS.md, "Measurements behind the code").
bool all_finite(ConstSpan<vec3> rows) {
  const float* v = reinterpret_cast<const float*>(rows.data());
  uint32_t bad = 0;
  for (std::size_t i = 0; i < 3 * rows.size(); ++i) {
    uint32_t bits;
    std::memcpy(&bits, v + i, sizeof bits);
    bad |= uint32_t((bits & 0x7f800000u) == 0x7f800000u);
  }
  return bad == 0;
}

// A point of a segment (or a point) in clip space with what is interpolated along it.
struct LinePoint {
  dvec4 p_clip;
  double depth_view;
  dvec3 color;
  dvec3 world;
};
LinePoint lerp(const LinePoint& a, const LinePoint& b, double t) {
  return {a.p_clip + (b.p_clip - a.p_clip) * t, a.depth_view + (b.depth_view - a.depth_view) * t,
          a.color + (b.color - a.color) * t, a.world + (b.world - a.world) * t};
}

struct DrawContext {
  const PrimitiveDraw* draw;
  DrawTransform xf;
  const ClipPlanes* planes;
  const Viewport* viewport;
  bool orthographic;
  bool need_world;  // the position / ray_depth outputs: one more transform per point
  dvec3 eye;        // the camera's position in model space (clip_far_segment's pivot)
  double error_px;  // 2^-50 max(width, height): px off per unit of m / w (clip_segment)
};

LinePoint transform(const DrawContext& c, std::size_t index) {
  const PrimitiveDraw& d = *c.draw;
  const vec3 p = d.positions[index];
  const ClipVertexD v = transform_point_d(c.xf, p);
  const dvec3 color = d.colors.empty() ? dvec3(d.color) : dvec3(d.colors[index]);
  return {v.p_clip, v.depth_view, color,
          c.need_world ? dvec3(d.model * dvec4(dvec3(p), 1.0)) : dvec3(0.0)};
}

// Window coordinates (vertex.cpp's transform, in double).
void window(const Viewport& vp, const dvec4& p_clip, double& x, double& y) {
  const double inv_w = 1.0 / p_clip.w;
  x = (p_clip.x * inv_w + 1.0) * 0.5 * vp.width;
  y = (1.0 - p_clip.y * inv_w) * 0.5 * vp.height;
}

// How Liang-Barsky below ended.
enum class Clipped { Kept, Gone, Unsure };

// Liang-Barsky against the six planes (near, far, guard band) on the clip-space endpoints: Gone
// if nothing is left, Unsure where the clip-space lerp may be far from the exact clipped point
// (clip_far_segment then clips the segment again). `a` and `b` are written only when Kept.
//
// Why Unsure: a clipped point is a + (b - a) t, and when the endpoints are huge next to the
// visible part (a segment from x = -1e20 to 1e20 crossing the view at depth 5), t is a double
// near 0.5 (one ulp there moves the point by 2^-53 |b - a|) and the sum cancels: at 1e20 both
// clipped ends came out at the same point and the line drew one pixel. The rounding is up to a
// few ulps of the largest endpoint coordinate `m`, so the result is kept only where that is at
// most 2^-16 px in the window at the clipped ends' w (and 2^-24 relatively in their depth);
// everything else (every segment of ordinary size) keeps the bits it always had.
Clipped clip_segment(const ClipPlanes& planes, double error_px, LinePoint& a, LinePoint& b) {
  double t0 = 0.0, t1 = 1.0;
  for (int plane = 0; plane < kNumClipPlanes; ++plane) {
    const double da = planes.distance(plane, a.p_clip, a.depth_view);
    const double db = planes.distance(plane, b.p_clip, b.depth_view);
    if (!(da >= 0.0) && !(db >= 0.0)) return Clipped::Gone;  // both outside (or NaN) => gone
    if (da < 0.0) t0 = std::max(t0, da / (da - db));
    else if (db < 0.0) t1 = std::min(t1, da / (da - db));
  }
  if (!(t0 <= t1)) return Clipped::Unsure;  // (a sliver's t0 and t1 may have crossed by rounding)
  const LinePoint ca = t0 > 0.0 ? lerp(a, b, t0) : a;
  const LinePoint cb = t1 < 1.0 ? lerp(a, b, t1) : b;
  const double w = std::min(ca.p_clip.w, cb.p_clip.w);
  if (t0 > 0.0 || t1 < 1.0) {
    double m = 0.0, m_depth = std::max(std::fabs(a.depth_view), std::fabs(b.depth_view));
    for (const LinePoint* p : {&a, &b})
      m = std::max({m, std::fabs(p->p_clip.x), std::fabs(p->p_clip.y), std::fabs(p->p_clip.w)});
    const double depth = std::min(std::fabs(ca.depth_view), std::fabs(cb.depth_view));
    if (!(w > 0.0))  // behind the eye, unless rounding of that size put it there
      return m * 0x1p-48 < std::min(std::fabs(ca.p_clip.w), std::fabs(cb.p_clip.w))
                 ? Clipped::Gone : Clipped::Unsure;
    if (!(m * error_px <= 0x1p-16 * w) || !(m_depth * 0x1p-50 <= 0x1p-24 * depth))
      return Clipped::Unsure;
  }
  if (!(w > 0.0)) return Clipped::Gone;
  a = ca;
  b = cb;
  return Clipped::Kept;
}

// Double-double sums (an unevaluated hi + lo, to about 2^-106 relative): the pivot below.
struct DD {
  double hi, lo;
};
DD two_sum(double a, double b) {  // exact: a + b = hi + lo (Knuth)
  const double s = a + b, v = s - a;
  return {s, (a - (s - v)) + (b - v)};
}
DD fast_two_sum(double a, double b) {  // exact where |a| >= |b|
  const double s = a + b;
  return {s, b - (s - a)};
}
DD operator+(const DD& x, const DD& y) {
  DD s = two_sum(x.hi, y.hi);
  const DD t = two_sum(x.lo, y.lo);
  s = fast_two_sum(s.hi, s.lo + t.hi);
  return fast_two_sum(s.hi, s.lo + t.lo);
}
DD two_prod(double a, double b) {  // exact: a b = hi + lo
  const double p = a * b;
  return {p, std::fma(a, b, -p)};
}

// Clip space and view depth of a model-space point (w = 1) or direction (w = 0), in double.
ClipVertexD transform_d(const DrawTransform& xf, const dvec4& p) {
  const dvec4 v = xf.model_view_d * p;
  return {xf.proj_d * v, -v.z};
}

// The signed distance's change along a clip-space direction (ClipPlanes::distance less its
// constant part).
double plane_slope(const ClipPlanes& planes, int plane, const dvec4& d, double d_depth) {
  switch (plane) {
    case 0: return d_depth;
    case 1: return -d_depth;
    case 2: return d.x - planes.ndc_x_min * d.w;
    case 3: return planes.ndc_x_max * d.w - d.x;
    case 4: return planes.ndc_y_max * d.w - d.y;
    default: return d.y - planes.ndc_y_min * d.w;
  }
}

// A segment as pivot + s d (model space), with the two transformed and the colours of its ends.
struct SegmentFrame {
  dvec3 pivot, d;
  ClipVertexD pivot_clip, d_clip;
  double s_a;  // end A's s
  dvec3 color_a, color_b;

  LinePoint at(const DrawContext& c, double s) const {
    const double k = std::clamp(s - s_a, 0.0, 1.0);  // from A toward B
    return {pivot_clip.p_clip + s * d_clip.p_clip, pivot_clip.depth_view + s * d_clip.depth_view,
            color_a + (color_b - color_a) * k,
            c.need_world ? dvec3(c.draw->model * dvec4(pivot + s * d, 1.0)) : dvec3(0.0)};
  }
};

// Clips segment A-B (model-space endpoints `pa`, `pb`; `a`, `b` their transformed points) where
// clip_segment is Unsure: relative to a pivot P on the segment near the camera, found in model
// space, where the float inputs are exact in double. P = A + t D is summed in double-double from
// A and D = B - A (both exact), so it lies on the segment to a rounding of its own size however
// large A and B are. The segment is then P + s D, s in [s_a, s_b], which is transformed as a point
// and a direction and clipped in s: the clipped points P + s D have the size of the visible part,
// not of the endpoints. An end inside every plane stays as it was (its own transform).
bool clip_far_segment(const DrawContext& c, const dvec3& pa, const dvec3& pb, LinePoint& a,
                      LinePoint& b) {
  DD p[3], d[3];  // the pivot, and D = B - A exactly
  dvec3 d_hi;
  for (int i = 0; i < 3; ++i) {
    d[i] = two_sum(pb[i], -pa[i]);
    d_hi[i] = d[i].hi;
  }
  const double len2 = glm::dot(d_hi, d_hi);
  if (!(len2 > 0.0) || !std::isfinite(len2)) return false;  // (a point: clip_segment decided)
  // The parameter of the point nearest the eye, on the segment, and the point; then the same
  // from there (t is only known to 2^-53 here, which is 2^-53 |D| along the segment).
  double t = glm::dot(c.eye - pa, d_hi) / len2;
  t = std::isfinite(t) ? std::clamp(t, 0.0, 1.0) : 0.0;
  dvec3 p1;
  for (int i = 0; i < 3; ++i) {
    p[i] = DD{pa[i], 0.0} + two_prod(t, d[i].hi) + two_prod(t, d[i].lo);
    p1[i] = p[i].hi + p[i].lo;
  }
  double u = glm::dot(c.eye - p1, d_hi) / len2;
  u = std::isfinite(u) ? std::clamp(u, -t, 1.0 - t) : 0.0;
  dvec3 pivot;
  for (int i = 0; i < 3; ++i) {
    p[i] = p[i] + two_prod(u, d[i].hi) + two_prod(u, d[i].lo);
    pivot[i] = p[i].hi + p[i].lo;
  }
  const double s_a = -t - u, s_b = (1.0 - t) - u;
  const ClipVertexD pc = transform_d(c.xf, dvec4(pivot, 1.0));
  const ClipVertexD dc = transform_d(c.xf, dvec4(d_hi, 0.0));
  double lo = s_a, hi = s_b;
  for (int plane = 0; plane < kNumClipPlanes; ++plane) {
    const double dp = c.planes->distance(plane, pc.p_clip, pc.depth_view);
    const double dd = plane_slope(*c.planes, plane, dc.p_clip, dc.depth_view);
    if (dd > 0.0) lo = std::max(lo, -dp / dd);
    else if (dd < 0.0) hi = std::min(hi, -dp / dd);
    else if (!(dp >= 0.0)) return false;  // parallel and outside (or NaN)
  }
  if (!(lo <= hi)) return false;
  const SegmentFrame f{pivot, d_hi, pc, dc, s_a, a.color, b.color};
  if (lo > s_a) a = f.at(c, lo);
  if (hi < s_b) b = f.at(c, hi);
  return a.p_clip.w > 0.0 && b.p_clip.w > 0.0;
}

// floor, for the window coordinates of clipped primitives (within the guard band plus a width
// of at most kMaxPrimitiveWidthPx: far inside int32): a truncation and a compare, where
// std::floor is a libm call on the generic x86-64 target (a fifth of a point cloud's setup).
int32_t floor_px(double v) {
  const int32_t t = int32_t(v);
  return t - int32_t(v < double(t));
}

// Inclusive pixel box of a line's footprint (thick lines: the capsule's, with a pixel to spare).
void line_box(const LineRecord& r, int32_t box[4]) {
  const int32_t pad = r.width > 1.0f ? int32_t(std::ceil(r.width * 0.5f)) + 1 : 0;
  box[0] = std::min(r.px[0], r.px[1]) - pad;
  box[1] = std::min(r.py[0], r.py[1]) - pad;
  box[2] = std::max(r.px[0], r.px[1]) + pad;
  box[3] = std::max(r.py[0], r.py[1]) + pad;
}

// Tiles [tx0, tx1] x [ty0, ty1] an inclusive pixel box touches; false if it misses the image.
bool box_tiles(const Viewport& vp, const int32_t box[4], int& tx0, int& ty0, int& tx1, int& ty1) {
  if (box[2] < 0 || box[3] < 0 || box[0] >= vp.width || box[1] >= vp.height) return false;
  tx0 = std::max(box[0], 0) / kTileSizePx;
  ty0 = std::max(box[1], 0) / kTileSizePx;
  tx1 = std::min(box[2], vp.width - 1) / kTileSizePx;
  ty1 = std::min(box[3], vp.height - 1) / kTileSizePx;
  return true;
}

void setup_lines(const DrawContext& c, std::size_t begin, std::size_t end, PrimitiveBlock& out) {
  const PrimitiveDraw& d = *c.draw;
  for (std::size_t s = begin; s < end; ++s) {
    const std::size_t ia = std::size_t(d.segments[s].x), ib = std::size_t(d.segments[s].y);
    LinePoint a = transform(c, ia);
    LinePoint b = transform(c, ib);
    const Clipped clipped = clip_segment(*c.planes, c.error_px, a, b);
    if (clipped == Clipped::Gone) continue;
    if (clipped == Clipped::Unsure &&
        !clip_far_segment(c, dvec3(d.positions[ia]), dvec3(d.positions[ib]), a, b))
      continue;
    LineRecord r;
    const LinePoint* ends[2] = {&a, &b};
    for (int e = 0; e < 2; ++e) {
      const LinePoint& p = *ends[e];
      window(*c.viewport, p.p_clip, r.x[e], r.y[e]);
      r.px[e] = floor_px(r.x[e]);
      r.py[e] = floor_px(r.y[e]);
      r.inv_w[e] = 1.0 / p.p_clip.w;
      r.depth[e] = p.depth_view;
      r.color[e] = vec3(p.color);
      r.world[e] = vec3(p.world);
    }
    r.width = d.width;
    r.instance_id = d.instance_id;
    // Keys grow toward the camera: 1 / depth scaled up, or -depth scaled toward 0.
    r.bias = c.orthographic ? 1.0f - d.depth_bias : 1.0f / (1.0f - d.depth_bias);
    int32_t box[4];
    int tx0, ty0, tx1, ty1;
    line_box(r, box);
    if (box_tiles(*c.viewport, box, tx0, ty0, tx1, ty1)) out.lines.push_back(r);
  }
}

void setup_points(const DrawContext& c, std::size_t begin, std::size_t end, PrimitiveBlock& out) {
  const PrimitiveDraw& d = *c.draw;
  const double half = std::max(double(d.width), 1.0) * 0.5;
  for (std::size_t i = begin; i < end; ++i) {
    const LinePoint p = transform(c, i);
    bool inside = p.p_clip.w > 0.0;
    for (int plane = 0; plane < kNumClipPlanes; ++plane)
      inside = inside && c.planes->distance(plane, p.p_clip, p.depth_view) >= 0.0;
    if (!inside) continue;
    double x, y;
    window(*c.viewport, p.p_clip, x, y);
    // Pixels whose centre j + 0.5 lies in (x - half, x + half].
    PointRecord r;
    r.x0 = floor_px(x - half - 0.5) + 1;
    r.x1 = floor_px(x + half - 0.5);
    r.y0 = floor_px(y - half - 0.5) + 1;
    r.y1 = floor_px(y + half - 0.5);
    r.key = c.orthographic ? -float(p.depth_view) : float(1.0 / p.depth_view);
    r.color = vec3(p.color);
    r.world = vec3(p.world);
    r.instance_id = d.instance_id;
    const int32_t box[4] = {r.x0, r.y0, r.x1, r.y1};
    int tx0, ty0, tx1, ty1;
    if (r.x0 <= r.x1 && r.y0 <= r.y1 && box_tiles(*c.viewport, box, tx0, ty0, tx1, ty1))
      out.dots.push_back(r);
  }
}

// Points of size <= 1: the pixel holding the point, (floor(x), floor(y)) (the square rule's
// single pixel), with no colour or world point (read once per pixel won, in the resolve).
void setup_pixels(const DrawContext& c, std::size_t begin, std::size_t end, PrimitiveBlock& out) {
  const PrimitiveDraw& d = *c.draw;
  const Viewport& vp = *c.viewport;
  const ClipPlanes& planes = *c.planes;
  out.pixels.resize(end - begin);
  out.single_tile.resize(end - begin);
  std::size_t n = 0;
  for (std::size_t i = begin; i < end; ++i) {
    const ClipVertexD v = transform_point_d(c.xf, d.positions[i]);
    const dvec4& p = v.p_clip;
    const double depth = v.depth_view;
    // setup_points' tests: w > 0 and every plane's distance >= 0 (NaN fails).
    const bool inside = p.w > 0.0 && depth - planes.near >= 0.0 && planes.far - depth >= 0.0 &&
                        p.x - planes.ndc_x_min * p.w >= 0.0 &&
                        planes.ndc_x_max * p.w - p.x >= 0.0 &&
                        planes.ndc_y_max * p.w - p.y >= 0.0 && p.y - planes.ndc_y_min * p.w >= 0.0;
    if (!inside) continue;
    double x, y;
    window(vp, p, x, y);
    const int32_t px = floor_px(x), py = floor_px(y);
    if (px < 0 || py < 0 || px >= vp.width || py >= vp.height) continue;
    out.pixels[n] = {uint32_t((py % kTileSizePx) * kTileSizePx + px % kTileSizePx),
                     c.orthographic ? -float(depth) : float(1.0 / depth), uint32_t(i)};
    out.single_tile[n] = uint32_t((py / kTileSizePx) * vp.tiles_x + px / kTileSizePx);
    ++n;
  }
  out.pixels.resize(n);
  out.single_tile.resize(n);
}

// Per-tile record lists of one block (counting sort: records stay in primitive order).
void bin_block(const Viewport& vp, PrimitiveBlock& block) {
  const std::size_t num_tiles = std::size_t(vp.num_tiles());
  block.tile_begin.assign(num_tiles + 1, 0);
  if (block.one_pixel) {  // one tile each, found by setup_pixels
    const std::size_t n = block.pixels.size();
    for (std::size_t i = 0; i < n; ++i) ++block.tile_begin[block.single_tile[i] + 1];
    for (std::size_t t = 0; t < num_tiles; ++t) block.tile_begin[t + 1] += block.tile_begin[t];
    std::vector<uint32_t> next(block.tile_begin.begin(), block.tile_begin.end() - 1);
    block.binned_pixels.resize(n);
    for (std::size_t i = 0; i < n; ++i) block.binned_pixels[next[block.single_tile[i]]++] = block.pixels[i];
    return;
  }
  const std::size_t n = block.points ? block.dots.size() : block.lines.size();
  const auto for_tiles = [&](std::size_t i, auto&& fn) {
    int32_t box[4];
    if (block.points) {
      const PointRecord& r = block.dots[i];
      box[0] = r.x0; box[1] = r.y0; box[2] = r.x1; box[3] = r.y1;
    } else {
      line_box(block.lines[i], box);
    }
    int tx0, ty0, tx1, ty1;
    if (!box_tiles(vp, box, tx0, ty0, tx1, ty1)) return;
    for (int ty = ty0; ty <= ty1; ++ty)
      for (int tx = tx0; tx <= tx1; ++tx) fn(std::size_t(ty) * vp.tiles_x + tx);
  };
  // Points: most lie in one tile, which the counting pass notes (single_tile) so the copying
  // pass need not find it again.
  constexpr uint32_t kSeveral = 0xffffffffu;
  if (block.points) block.single_tile.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    uint32_t only = kSeveral, count = 0;
    for_tiles(i, [&](std::size_t t) {
      ++block.tile_begin[t + 1];
      only = uint32_t(t);
      ++count;
    });
    if (block.points) block.single_tile[i] = count == 1 ? only : kSeveral;
  }
  for (std::size_t t = 0; t < num_tiles; ++t) block.tile_begin[t + 1] += block.tile_begin[t];
  std::vector<uint32_t> next(block.tile_begin.begin(), block.tile_begin.end() - 1);
  if (block.points) {
    block.binned_dots.resize(block.tile_begin[num_tiles]);
    for (std::size_t i = 0; i < n; ++i) {
      const uint32_t only = block.single_tile[i];
      if (only != kSeveral) block.binned_dots[next[only]++] = block.dots[i];
      else for_tiles(i, [&](std::size_t t) { block.binned_dots[next[t]++] = block.dots[i]; });
    }
  } else {
    block.tile_records.resize(block.tile_begin[num_tiles]);
    for (std::size_t i = 0; i < n; ++i)
      for_tiles(i, [&](std::size_t t) { block.tile_records[next[t]++] = uint32_t(i); });
  }
}

// One fragment: depth-tested against the pixel's key (ties keep what was drawn first) as
// `test_key` (the key, or a biased one). A winner records only its key and record: colour and
// position are resolved once per pixel, after the tile's last primitive.
struct Ref {
  uint32_t block, record;
};
SR_INLINE bool plot(const OverlayTarget& t, int i, float key, float test_key, Ref ref) {
  if (t.visible[i] != kNoTriangle && !(test_key > t.key[i] * t.tie)) return false;
  t.key[i] = key;
  t.visible[i] = kPrimitivePixel;
  t.pixels->block[i] = ref.block;
  t.pixels->record[i] = ref.record;
  return true;
}

// Where on line `r` pixel (x, y) is: the segment's point nearest the pixel centre in the window,
// as the perspective-correct parameter u along the 3-D segment, and its depth key.
SR_INLINE double line_parameter(const LineRecord& r, int x, int y, bool orthographic, float& key) {
  const double ex = r.x[1] - r.x[0], ey = r.y[1] - r.y[0];
  const double len2 = ex * ex + ey * ey;
  double s = len2 > 0.0 ? ((x + 0.5 - r.x[0]) * ex + (y + 0.5 - r.y[0]) * ey) / len2 : 0.0;
  s = std::clamp(s, 0.0, 1.0);
  const double wa = (1.0 - s) * r.inv_w[0], wb = s * r.inv_w[1];
  const double u = wb / (wa + wb);
  const double depth = r.depth[0] + (r.depth[1] - r.depth[0]) * u;
  key = orthographic ? -float(depth) : float(1.0 / depth);
  return u;
}

SR_INLINE void line_fragment(const OverlayTarget& t, const TileRect& rect, const LineRecord& r,
                             bool orthographic, int x, int y, Ref ref) {
  float key;
  line_parameter(r, x, y, orthographic, key);
  plot(t, (y - rect.y0) * kTileSizePx + (x - rect.x0), key, key * r.bias, ref);
}

// A line one pixel wide: one pixel per major-axis step inside the tile (closed forms, so a tile
// starts mid-line without walking to it).
void draw_thin_line(const OverlayTarget& t, const TileRect& rect, const LineRecord& r,
                    LineAlgorithm algorithm, bool orthographic, Ref ref) {
  const int64_t dx = int64_t(r.px[1]) - r.px[0], dy = int64_t(r.py[1]) - r.py[0];
  const bool x_major = std::abs(dx) >= std::abs(dy);
  const int64_t major0 = x_major ? r.px[0] : r.py[0], minor0 = x_major ? r.py[0] : r.px[0];
  const int64_t d_major = x_major ? dx : dy, d_minor = x_major ? dy : dx;
  const int64_t steps = std::abs(d_major), minor_abs = std::abs(d_minor);
  const int64_t major_sign = d_major < 0 ? -1 : 1, minor_sign = d_minor < 0 ? -1 : 1;
  // Steps k whose major coordinate lies in the tile's range [lo, hi).
  const int64_t lo = x_major ? rect.x0 : rect.y0, hi = x_major ? rect.x1 : rect.y1;
  const int64_t min_lo = x_major ? rect.y0 : rect.x0, min_hi = x_major ? rect.y1 : rect.x1;
  int64_t k0 = major_sign > 0 ? lo - major0 : major0 - (hi - 1);
  int64_t k1 = major_sign > 0 ? hi - 1 - major0 : major0 - lo;
  k0 = std::max<int64_t>(k0, 0);
  k1 = std::min<int64_t>(k1, steps);
  for (int64_t k = k0; k <= k1; ++k) {
    const int64_t major = major0 + major_sign * k;
    int64_t minor;
    if (steps == 0) {
      minor = minor0;
    } else if (algorithm == LineAlgorithm::Bresenham) {  // round(k |dm| / M), halves away from the start
      minor = minor0 + minor_sign * ((2 * k * minor_abs + steps) / (2 * steps));
    } else {  // DDA: round half up of the exact minor coordinate
      minor = int64_t(std::floor(double(minor0) + double(k * d_minor) / double(steps) + 0.5));
    }
    if (minor < min_lo || minor >= min_hi) continue;
    const int x = int(x_major ? major : minor), y = int(x_major ? minor : major);
    line_fragment(t, rect, r, orthographic, x, y, ref);
  }
}

// A line wider than one pixel: every pixel whose centre is within width / 2 of the projected
// segment (the clipped endpoints' window positions). Per major-axis pixel, the candidates are the
// pixels within 2 r + 2 of the line there (a pixel within r of the segment is within r sqrt(2) of
// the line along the minor axis, or within 2 r of its end beyond the segment's ends); each is
// tested in double as 4 cross^2 <= width^2 |d|^2 (no division), or against the nearer endpoint.
void draw_thick_line(const OverlayTarget& t, const TileRect& rect, const LineRecord& r,
                     bool orthographic, Ref ref) {
  const double ax = r.x[0], ay = r.y[0];
  const double dx = r.x[1] - ax, dy = r.y[1] - ay;
  const double len2 = dx * dx + dy * dy;
  const double w2 = double(r.width) * double(r.width);
  const bool x_major = std::fabs(dx) >= std::fabs(dy);
  const double a_major = x_major ? ax : ay, a_minor = x_major ? ay : ax;
  const double d_major = x_major ? dx : dy, d_minor = x_major ? dy : dx;
  const double radius = double(r.width) * 0.5;
  const double major_min = std::min(a_major, a_major + d_major);
  const double major_max = std::max(a_major, a_major + d_major);
  const int64_t lo = std::max<int64_t>(x_major ? rect.x0 : rect.y0,
                                       int64_t(std::floor(major_min - radius)) - 1);
  const int64_t hi = std::min<int64_t>((x_major ? rect.x1 : rect.y1) - 1,
                                       int64_t(std::floor(major_max + radius)) + 1);
  const int64_t min_lo = x_major ? rect.y0 : rect.x0, min_hi = x_major ? rect.y1 : rect.x1;
  const auto inside = [&](double ux, double uy) {
    const double dot = ux * dx + uy * dy;
    if (dot <= 0.0 || len2 == 0.0) return 4.0 * (ux * ux + uy * uy) <= w2;
    if (dot >= len2) {
      const double vx = ux - dx, vy = uy - dy;
      return 4.0 * (vx * vx + vy * vy) <= w2;
    }
    const double cross = ux * dy - uy * dx;
    return 4.0 * cross * cross <= w2 * len2;
  };
  for (int64_t major = lo; major <= hi; ++major) {
    const double along = std::clamp(double(major) + 0.5, major_min, major_max);
    const double centre = d_major == 0.0 ? a_minor
                                         : a_minor + (along - a_major) * (d_minor / d_major);
    const int64_t v0 = std::max<int64_t>(min_lo, int64_t(std::floor(centre - 2.0 * radius - 2.0)));
    const int64_t v1 = std::min<int64_t>(min_hi - 1, int64_t(std::ceil(centre + 2.0 * radius + 2.0)));
    for (int64_t minor = v0; minor <= v1; ++minor) {
      const int64_t x = x_major ? major : minor, y = x_major ? minor : major;
      if (inside(double(x) + 0.5 - ax, double(y) + 0.5 - ay))
        line_fragment(t, rect, r, orthographic, int(x), int(y), ref);
    }
  }
}

}  // namespace

void validate_primitive(const PrimitiveDraw& d, const std::string& where) {
  const char* kind = d.points ? "Points" : "Lines";
  if (d.positions.size() > std::size_t(INT32_MAX))
    throw std::invalid_argument(where + " positions: too many");
  if (!all_finite(d.positions))  // (then find the row)
    for (std::size_t i = 0; i < d.positions.size(); ++i)
      if (!finite3(d.positions[i]))
        throw std::invalid_argument(where + " positions contains NaN or inf at row " +
                                    std::to_string(i));
  for (std::size_t s = 0; s < d.segments.size(); ++s)
    for (int e = 0; e < 2; ++e)
      if (uint32_t(d.segments[s][e]) >= d.positions.size())
        throw std::invalid_argument(where + " segments: index " + std::to_string(d.segments[s][e]) +
                                    " in segment " + std::to_string(s) + " is outside [0, " +
                                    std::to_string(d.positions.size()) + ")");
  if (!d.colors.empty() && d.colors.size() != d.positions.size())
    throw std::invalid_argument(where + " colors must have one row per position");
  if (!all_finite(d.colors)) throw std::invalid_argument(where + " colors contains NaN or inf");
  if (!finite3(d.color)) throw std::invalid_argument(where + " color is not finite");
  if (!(d.depth_bias >= 0.0f && d.depth_bias < 1.0f))
    throw std::invalid_argument(where + " depth_bias must be in [0, 1)");
  // (At most 1e6 px: pixel boxes stay far inside int32.)
  if (!(std::isfinite(d.width) && d.width > 0.0f && d.width <= kMaxPrimitiveWidthPx))
    throw std::invalid_argument(where + (d.points ? " size" : " width") +
                                " must be finite, > 0 and at most 1e6 (" + kind + ")");
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(d.model[c][r])) throw std::invalid_argument(where + " pose is not finite");
}

void PrimitiveSetup::build(const std::vector<PrimitiveDraw>& draws, const CameraParams& camera,
                           const Viewport& viewport, LineAlgorithm line_algorithm,
                           bool need_world, ThreadPool& pool) {
  algorithm = line_algorithm;
  orthographic = camera.orthographic;
  this->need_world = need_world;
  num_blocks = 0;
  if (draws.empty()) return;  // a scene without lines or points: any() is false for every tile
  const ClipPlanes planes(camera, viewport.width, viewport.height);
  std::vector<DrawContext> contexts;
  struct Range { std::size_t draw, begin, end; };
  std::vector<Range> ranges;
  for (std::size_t d = 0; d < draws.size(); ++d) {
    const DrawTransform xf = make_draw_transform(draws[d].model, camera);
    // (A singular pose has no eye: clip_far_segment then starts from the first endpoint.)
    const dvec3 eye(glm::inverse(xf.model_view_d)[3]);
    contexts.push_back({&draws[d], xf, &planes, &viewport, camera.orthographic, need_world, eye,
                        0x1p-50 * std::max(viewport.width, viewport.height)});
    const std::size_t n = draws[d].points ? draws[d].positions.size() : draws[d].segments.size();
    for (std::size_t b = 0; b < n; b += kPrimitiveBlock)
      ranges.push_back({d, b, std::min(n, b + kPrimitiveBlock)});
  }
  num_blocks = ranges.size();
  if (blocks.size() < num_blocks) blocks.resize(num_blocks);
  pool.parallel_for(num_blocks, [&](std::size_t item, int) {
    const Range& range = ranges[item];
    PrimitiveBlock& block = blocks[item];
    block.points = draws[range.draw].points;
    block.one_pixel = block.points && draws[range.draw].width <= 1.0f;
    block.draw = draws[range.draw];
    block.lines.clear();
    block.dots.clear();
    if (block.one_pixel) setup_pixels(contexts[range.draw], range.begin, range.end, block);
    else if (block.points) setup_points(contexts[range.draw], range.begin, range.end, block);
    else setup_lines(contexts[range.draw], range.begin, range.end, block);
    bin_block(viewport, block);
  });
  tile_used.assign(std::size_t(viewport.num_tiles()), 0);
  for (std::size_t b = 0; b < num_blocks; ++b)
    for (std::size_t t = 0; t < tile_used.size(); ++t)
      tile_used[t] |= uint8_t(blocks[b].tile_begin[t + 1] > blocks[b].tile_begin[t]);
}

void draw_primitives_tile(const PrimitiveSetup& setup, const TileRect& rect, int tile,
                          const OverlayTarget& target) {
  // The depth test: each winner's key and record.
  for (std::size_t b = 0; b < setup.num_blocks; ++b) {
    const PrimitiveBlock& block = setup.blocks[b];
    const uint32_t begin = block.tile_begin[tile], end = block.tile_begin[tile + 1];
    if (block.one_pixel) {
      // rect is the tile's: a record's pixel offset has the tile's row stride. The colour a
      // winner will read is fetched now (the draw's colours are far from cache, read by index).
      const vec3* colors = block.draw.colors.empty() ? nullptr : block.draw.colors.data();
      for (uint32_t i = begin; i < end; ++i) {
        const DotRecord& p = block.binned_pixels[i];
        if (plot(target, int(p.pixel), p.key, p.key, Ref{uint32_t(b), p.index}) && colors)
          __builtin_prefetch(colors + p.index);
      }
      continue;
    }
    if (block.points) {
      for (uint32_t i = begin; i < end; ++i) {
        const PointRecord& p = block.binned_dots[i];
        const int x0 = std::max(p.x0, rect.x0), x1 = std::min(p.x1, rect.x1 - 1);
        const int y0 = std::max(p.y0, rect.y0), y1 = std::min(p.y1, rect.y1 - 1);
        for (int y = y0; y <= y1; ++y)
          for (int x = x0; x <= x1; ++x)
            plot(target, (y - rect.y0) * kTileSizePx + (x - rect.x0), p.key, p.key,
                 Ref{uint32_t(b), i});
      }
      continue;
    }
    for (uint32_t i = begin; i < end; ++i) {
      const uint32_t index = block.tile_records[i];
      const LineRecord& r = block.lines[index];
      const Ref ref{uint32_t(b), index};
      if (r.width > 1.0f) draw_thick_line(target, rect, r, setup.orthographic, ref);
      else draw_thin_line(target, rect, r, setup.algorithm, setup.orthographic, ref);
    }
  }
  // Each pixel a primitive won: its colour (unlit, linear), normal 0, instance id and position.
  const OverlayTarget& t = target;
  for (int y = rect.y0; y < rect.y1; ++y) {
    const int row = (y - rect.y0) * kTileSizePx;
    for (int x = rect.x0; x < rect.x1; ++x) {
      const int i = row + (x - rect.x0);
      if (t.visible[i] != kPrimitivePixel) continue;
      const PrimitiveBlock& block = setup.blocks[t.pixels->block[i]];
      const uint32_t record = t.pixels->record[i];
      vec3 color, world;
      if (block.one_pixel) {  // setup_points' colour and world point, for the winner only
        const PrimitiveDraw& d = block.draw;
        color = d.colors.empty() ? d.color : d.colors[record];
        world = setup.need_world ? vec3(dvec3(d.model * dvec4(dvec3(d.positions[record]), 1.0)))
                                 : vec3(0.0f);
        t.pixels->instance[i] = d.instance_id;
      } else if (block.points) {
        const PointRecord& p = block.binned_dots[record];
        color = p.color;
        world = p.world;
        t.pixels->instance[i] = p.instance_id;
      } else {
        const LineRecord& r = block.lines[record];
        float key;
        const float u = float(line_parameter(r, x, y, setup.orthographic, key));
        color = r.color[0] + (r.color[1] - r.color[0]) * u;
        world = r.world[0] + (r.world[1] - r.world[0]) * u;
        t.pixels->instance[i] = r.instance_id;
      }
      for (int c = 0; c < 3; ++c) {
        t.rgb[c][i] = color[c];
        t.normal[c][i] = 0.0f;
        t.pixels->position[c][i] = world[c];
      }
      if (t.alpha) {  // anti-aliased: the resolved alpha and premultiplied radiance too
        t.alpha[i] = 1.0f;
        for (int c = 0; c < 3; ++c) t.radiance[c][i] = color[c];
      }
    }
  }
}

}  // namespace sr
