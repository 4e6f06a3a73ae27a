// Vertex stage: transform, project and snap every mesh vertex once per render.
#pragma once

#include "clip.hpp"
#include "pipeline.hpp"
#include "simd.hpp"
#include "transform.hpp"
#include "viewport.hpp"

#include <cmath>

namespace sr {

// A vertex in window space, snapped; computed once per mesh vertex (and per clipping vertex).
// Kept to 32 bytes, two to a cache line: the setup pass fetches three per face, in index order.
// Clip-space position and view depth are not stored: only the rare clipped triangle needs them,
// and it recomputes them from the mesh (transform_point gives the same bits).
struct alignas(32) ProjectedVertex {
  int32_t x, y;     // window coordinates, fixed point, valid when outcode == 0
  float dx, dy;     // unsnapped - snapped window coordinates in fixed-point units, about
                    // [-1/2, 1/2], the unsnapped position in double (transform.hpp, ExactClip)
  float key;        // depth key (pipeline.hpp), from the view depth in double
  float inv_w;      // 1 / w_clip
  uint8_t outcode;  // ClipPlaneBit set; kInvalidVertex if not finite
};
constexpr uint8_t kInvalidVertex = 0x80;

// How snapping moved a triangle's vertices, in the unsnapped triangle's own barycentric terms:
// for snapped vertex k (fixed point x[k], y[k]; unsnapped x + dx, y + dy), the change mu of its
// barycentric coordinates in the unsnapped triangle (mu[0] + mu[1] + mu[2] = 0). An affine
// function of window position is then exact at the snapped vertices when its value there is the
// vertex's own plus mu applied to the three (setup.cpp: the depth plane, and the exact weights
// shading and the normal output interpolate with, pipeline.hpp ExactWeights).
struct SnapShift {
  static constexpr double kMinArea = 1e-6 * kSubpixelOne * kSubpixelOne;  // 1e-6 px^2
  double ex1, ey1, ex2, ey2;  // the unsnapped triangle's edges from vertex 0, fixed-point units
  double area;                // twice its signed area
  SnapShift(const int32_t* x, const int32_t* y, const float* dx, const float* dy)
      : ex1(double(x[1] - x[0]) + (double(dx[1]) - double(dx[0]))),
        ey1(double(y[1] - y[0]) + (double(dy[1]) - double(dy[0]))),
        ex2(double(x[2] - x[0]) + (double(dx[2]) - double(dx[0]))),
        ey2(double(y[2] - y[0]) + (double(dy[2]) - double(dy[0]))),
        area(ex1 * ey2 - ey1 * ex2) {}
  bool degenerate() const { return !(std::fabs(area) > kMinArea); }
  // Vertex k's mu, with inv_area = 1 / area; the snap moved it by (-dx, -dy).
  void shift(double inv_area, float dx, float dy, double* mu) const {
    const double sx = -double(dx), sy = -double(dy);
    mu[1] = (sx * ey2 - sy * ex2) * inv_area;
    mu[2] = (ex1 * sy - ey1 * sx) * inv_area;
    mu[0] = -(mu[1] + mu[2]);
  }
};

// Snaps one vertex (vertex.cpp). With `snap_outside`, a vertex outside some plane is snapped too
// (clipping output: setup.cpp). The snapped position and the outcode come from the float32
// clip position (coverage: every path computes the same bits), the residuals dx, dy and the key
// from the same point in double, `exact` (where it has a finite position in front of the camera;
// else from the float one too).
void project(const vec4& p_clip, float depth_view, const ExactClip& exact,
             const ClipPlanes& planes, const Viewport& viewport, bool orthographic,
             bool snap_outside, ProjectedVertex& v);

// Transforms and projects the draw's vertices [begin, end) into out[begin, end), eight at a time
// with the kernel for `isa` (the same bits for either).
void project_vertices(const MeshData& mesh, const DrawTransform& xf, std::size_t begin,
                      std::size_t end, const ClipPlanes& planes, const Viewport& viewport,
                      bool orthographic, Isa isa, ProjectedVertex* out);

}  // namespace sr
