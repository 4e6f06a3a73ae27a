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
  float dx, dy;     // unsnapped - snapped window coordinates in fixed-point units, in [-1/2, 1/2]
  float key;        // depth key (pipeline.hpp)
  float inv_w;      // 1 / w_clip
  uint8_t outcode;  // ClipPlaneBit set; kInvalidVertex if not finite
};
constexpr uint8_t kInvalidVertex = 0x80;

// Snaps one vertex (vertex.cpp). With `snap_outside`, a vertex outside some plane is snapped too
// (clipping output: setup.cpp).
void project(const vec4& p_clip, float depth_view, const ClipPlanes& planes,
             const Viewport& viewport, bool orthographic, bool snap_outside, ProjectedVertex& v);

// Transforms and projects the draw's vertices [begin, end) into out[begin, end), eight at a time
// with the kernel for `isa` (the same bits for either).
void project_vertices(const MeshData& mesh, const DrawTransform& xf, std::size_t begin,
                      std::size_t end, const ClipPlanes& planes, const Viewport& viewport,
                      bool orthographic, Isa isa, ProjectedVertex* out);

}  // namespace sr
