// Clip stage: Sutherland-Hodgman in homogeneous clip space.
#include "clip.hpp"

#include <algorithm>
#include <tuple>
#include <utility>

namespace sr {

ClipPlanes::ClipPlanes(const CameraParams& camera, int width, int height)
    : near(camera.near),
      far(camera.far),
      ndc_x_min(-2.0 * kGuardBandPx / width - 1.0),
      ndc_x_max(2.0 * kGuardBandPx / width - 1.0),
      ndc_y_min(1.0 - 2.0 * kGuardBandPx / height),
      ndc_y_max(1.0 + 2.0 * kGuardBandPx / height) {}

namespace {

bool precedes(const ClipPoint& a, const ClipPoint& b) {
  return std::tie(a.p_clip.x, a.p_clip.y, a.p_clip.z, a.p_clip.w, a.depth_view) <
         std::tie(b.p_clip.x, b.p_clip.y, b.p_clip.z, b.p_clip.w, b.depth_view);
}

// Point where the segment a-b crosses `plane` (da, db: the float positions' signed distances,
// which decided that it does). The crossing is found on the double positions, whose distances
// are exact to double rounding; should they put it outside the segment (an endpoint within float
// rounding of the plane), it is clamped to the endpoint.
template <typename Planes>
ClipPoint intersect(const ClipPoint& a_in, const ClipPoint& b_in, double da_in, double db_in, int plane,
                    const Planes& planes) {
  const bool swap = precedes(b_in, a_in);  // canonical order => same bits from either triangle
  const ClipPoint& a = swap ? b_in : a_in;
  const ClipPoint& b = swap ? a_in : b_in;
  const double da_f = swap ? db_in : da_in;
  const double db_f = swap ? da_in : db_in;
  const double da = planes.distance(plane, a.p_clip_d, a.depth_view_d);
  const double db = planes.distance(plane, b.p_clip_d, b.depth_view_d);
  double t = da / (da - db);
  if (!(t >= 0.0 && t <= 1.0)) t = da_f / (da_f - db_f);  // same side in double, or not finite
  t = std::clamp(t, 0.0, 1.0);
  auto lerp = [t](double u, double v) { return u + t * (v - u); };
  ClipPoint p;
  for (int k = 0; k < 4; ++k) {
    p.p_clip_d[k] = lerp(a.p_clip_d[k], b.p_clip_d[k]);
    p.p_clip[k] = float(p.p_clip_d[k]);
  }
  p.depth_view_d = lerp(a.depth_view_d, b.depth_view_d);
  p.depth_view = float(p.depth_view_d);
  for (int k = 0; k < 3; ++k) p.bary_source[k] = float(lerp(a.bary_source[k], b.bary_source[k]));
  return p;
}

}  // namespace

template <typename Planes>
int clip_triangle(const ClipPoint in[3], uint8_t planes_mask, const Planes& planes,
                  ClipPoint out[kMaxClipPoints]) {
  ClipPoint buffer[2][kMaxClipPoints];
  ClipPoint* poly = buffer[0];
  ClipPoint* next = buffer[1];
  int n = 3;
  for (int k = 0; k < 3; ++k) poly[k] = in[k];

  for (int plane = 0; plane < kNumClipPlanes && n > 0; ++plane) {
    if (!(planes_mask & (1u << plane))) continue;
    int m = 0;
    for (int i = 0; i < n; ++i) {
      const ClipPoint& cur = poly[i];
      const ClipPoint& nxt = poly[(i + 1) % n];
      const double d_cur = planes.distance(plane, cur.p_clip, cur.depth_view);
      const double d_nxt = planes.distance(plane, nxt.p_clip, nxt.depth_view);
      const bool in_cur = d_cur >= 0.0, in_nxt = d_nxt >= 0.0;
      if (m + 2 > kMaxClipPoints) return 0;  // pathological sliver => drop
      if (in_cur) next[m++] = cur;
      if (in_cur != in_nxt) next[m++] = intersect(cur, nxt, d_cur, d_nxt, plane, planes);
    }
    std::swap(poly, next);
    n = m < 3 ? 0 : m;
  }
  for (int i = 0; i < n; ++i) out[i] = poly[i];
  return n;
}

template int clip_triangle(const ClipPoint[3], uint8_t, const ClipPlanes&, ClipPoint[kMaxClipPoints]);
template int clip_triangle(const ClipPoint[3], uint8_t, const ClipSpacePlanes&,
                           ClipPoint[kMaxClipPoints]);

}  // namespace sr
