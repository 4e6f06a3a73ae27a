// Vertex stage: transform, project and snap every mesh vertex once per render.
#pragma once

#include "clip.hpp"
#include "pipeline.hpp"
#include "simd.hpp"
#include "transform.hpp"
#include "viewport.hpp"

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
