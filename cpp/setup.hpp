// Setup stage: cull, orient, build edge and depth equations, bin (vertices come snapped: vertex.hpp).
#pragma once

#include "bin.hpp"
#include "clip.hpp"
#include "pipeline.hpp"
#include "simd.hpp"
#include "transform.hpp"
#include "vertex.hpp"

#include <vector>

namespace sr {

struct SetupParams {
  const MeshData* mesh;
  const DrawTransform* transform;
  const ProjectedVertex* vertices;  // of this draw
  uint32_t draw;
  bool orthographic;
  Cull cull;
  const ClipPlanes* planes;
  Viewport viewport;
  bool estimate_overdraw;  // fill SetupChunk::tile_area (the "auto" shading path's choice)
  bool shade;              // fill SetupChunk::shading (shading, or an alpha test, reads it)
  const AlphaTest* alpha;  // the draw's alpha test, or null (opaque)
  Isa isa;                 // kernels for eight faces at a time (the same records for either)
  bool exact_weights = false;  // fill SetupChunk::exact (with shade: the draw's shading or the
                               // normal output reads the exact weights)
};

// Builds the records for one snapped triangle whose corners are the mesh's vertices `vertex` (or
// null for a piece of a clipped face), `a` only if params.shade (its clip_ref left to the caller),
// `e` only if params.exact_weights; `positive_area2` receives twice its area (> 0). Returns
// false if it is culled, degenerate, or has no sample centre in its box or covers none of the
// one or two there; those integer tests come before any floating-point work. (Also the setup of
// triangles given in clip space: clip_raster.cpp.)
bool setup_triangle(const ProjectedVertex* const v[3], const SetupParams& params, uint32_t prim,
                    const int32_t* vertex, TriangleSetup& t, TriangleShading& a, ExactWeights& e,
                    int64_t& positive_area2);

// A clipped face's polygon (n corners `poly`, snapped as `projected`) set up and binned as a fan
// from its first corner; with params.shade, each piece's shading records and clip-space weights.
// (setup.cpp's clipped faces, and clip_raster.cpp's triangles given in clip space.)
void setup_fan(const ProjectedVertex* projected, const ClipPoint* poly, int n, const SetupParams& params,
               uint32_t prim, SetupChunk& out);

// Sets up faces [begin, end) of one draw and bins them (out is cleared first).
void setup_chunk(const SetupParams& params, std::size_t begin, std::size_t end, SetupChunk& out);

// Between setup.cpp (one face at a time, clipping) and setup_lanes.cpp (eight at a time):
// faces [begin, end) appended to `out` by the kernel for params.isa; and one face on its own.
void setup_faces(const SetupParams& params, std::size_t begin, std::size_t end, SetupChunk& out);
void setup_face(const SetupParams& params, std::size_t f, SetupChunk& out);

}  // namespace sr
