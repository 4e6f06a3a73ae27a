// Clip stage: homogeneous clipping against the near and far planes and the guard band.
#pragma once

#include "pipeline.hpp"

namespace sr {

enum ClipPlaneBit : uint8_t {
  kClipNear = 1u << 0,
  kClipFar = 1u << 1,
  kClipLeft = 1u << 2,  // guard band, x_window >= -kGuardBandPx
  kClipRight = 1u << 3,
  kClipTop = 1u << 4,  // guard band, y_window >= -kGuardBandPx (y points down)
  kClipBottom = 1u << 5,
};
constexpr int kNumClipPlanes = 6;
// A convex polygon gains at most one vertex per plane; rounding can make a sliver non-convex,
// so the buffers have room to spare and a polygon that would overflow them is dropped.
constexpr int kMaxClipPoints = 32;

// The six planes as signed distances, inside >= 0.
struct ClipPlanes {
  double near, far;
  double ndc_x_min, ndc_x_max;  // guard band in NDC
  double ndc_y_min, ndc_y_max;

  ClipPlanes(const CameraParams& camera, int width, int height);

  double distance(int plane, const vec4& p_clip, float depth_view) const {
    return distance(plane, dvec4(p_clip), double(depth_view));
  }
  double distance(int plane, const dvec4& p_clip, double depth_view) const {
    switch (plane) {
      case 0: return depth_view - near;
      case 1: return far - depth_view;
      case 2: return p_clip.x - ndc_x_min * p_clip.w;
      case 3: return ndc_x_max * p_clip.w - p_clip.x;
      case 4: return ndc_y_max * p_clip.w - p_clip.y;  // NDC y up = window y down
      default: return p_clip.y - ndc_y_min * p_clip.w;
    }
  }

  // Bit set per plane the point is outside of (the same tests as distance() >= 0; NaN => out).
  uint8_t outcode(const vec4& p_clip, float depth_view) const {
    const double x = p_clip.x, y = p_clip.y, w = p_clip.w, d = depth_view;
    return uint8_t((!(d - near >= 0.0) ? kClipNear : 0) | (!(far - d >= 0.0) ? kClipFar : 0) |
                   (!(x - ndc_x_min * w >= 0.0) ? kClipLeft : 0) |
                   (!(ndc_x_max * w - x >= 0.0) ? kClipRight : 0) |
                   (!(ndc_y_max * w - y >= 0.0) ? kClipTop : 0) |
                   (!(y - ndc_y_min * w >= 0.0) ? kClipBottom : 0));
  }
};

// nvdiffrast's clip volume, for positions given in clip space (clip_raster.hpp, softrast.nv):
// near -w <= z and far z <= w (OpenGL's depth range, on the clip position itself, not on a view
// depth), and ClipPlanes' guard band. The same bit per plane as ClipPlanes' (ClipPlaneBit).
struct ClipSpacePlanes {
  ClipPlanes band;  // the guard band (its near and far planes are not read)

  double distance(int plane, const vec4& p_clip, float depth_view) const {
    return distance(plane, dvec4(p_clip), double(depth_view));
  }
  double distance(int plane, const dvec4& p_clip, double depth_view) const {
    switch (plane) {
      case 0: return p_clip.z + p_clip.w;
      case 1: return p_clip.w - p_clip.z;
      default: return band.distance(plane, p_clip, depth_view);
    }
  }
  // Bit set per plane the point is outside of: exactly distance() >= 0 (NaN => out), so the
  // vertex pass and clip_triangle decide every side alike.
  uint8_t outcode(const vec4& p_clip) const {
    uint8_t code = 0;
    for (int plane = 0; plane < kNumClipPlanes; ++plane)
      if (!(distance(plane, p_clip, 0.0f) >= 0.0)) code = uint8_t(code | (1u << plane));
    return code;
  }
};

// Clips the triangle `in` against the planes in `planes_mask` (Sutherland-Hodgman). Returns the
// number of polygon vertices written to `out` (0 or 3..kMaxClipPoints), in the input's winding.
// A new vertex on an edge shared by two triangles is computed from the edge's endpoints in a
// canonical order, so both triangles get bit-identical vertices: clipping keeps meshes watertight.
// Which side of a plane a point is on is decided on its float position (as the vertex pass
// decided which faces to clip); where a new point lies, on the double positions.
// `Planes`: ClipPlanes (a render's camera) or ClipSpacePlanes (clip_raster.cpp).
template <typename Planes>
int clip_triangle(const ClipPoint in[3], uint8_t planes_mask, const Planes& planes,
                  ClipPoint out[kMaxClipPoints]);

}  // namespace sr
