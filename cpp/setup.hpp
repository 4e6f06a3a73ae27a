// Setup stage: snap to the fixed-point grid, cull, orient, build edge and depth equations, bin.
#pragma once

#include "clip.hpp"
#include "pipeline.hpp"
#include "scratch.hpp"
#include "simd.hpp"
#include "transform.hpp"

#include <vector>

namespace sr {

// Image size and tiling; the scissor is the whole image.
struct Viewport {
  int width = 0, height = 0;
  int tiles_x = 0, tiles_y = 0;
  Viewport() = default;
  Viewport(int w, int h)
      : width(w), height(h),
        tiles_x((w + kTileSizePx - 1) / kTileSizePx),
        tiles_y((h + kTileSizePx - 1) / kTileSizePx) {}
  int num_tiles() const { return tiles_x * tiles_y; }
};

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

// Transforms and projects the draw's vertices [begin, end) into out[begin, end), eight at a time
// with the kernel for `isa` (the same bits for either).
void project_vertices(const MeshData& mesh, const DrawTransform& xf, std::size_t begin,
                      std::size_t end, const ClipPlanes& planes, const Viewport& viewport,
                      bool orthographic, Isa isa, ProjectedVertex* out);

// The triangles one chunk of a draw produced, binned to tiles. Records keep primitive order.
// Cache-line aligned: neighbouring chunks are set up by different threads, and every push_back
// writes an array's end (sharing a line made the setup pass scale 1.1x on 2 threads).
struct alignas(64) SetupChunk {
  GrowingArray<TriangleSetup> records;   // (grown without copies: a first frame grows them all)
  GrowingArray<TriangleShading> shading; // records[i]'s in shading[i]; empty unless SetupParams::shade
  std::vector<vec3> clip_bary;           // 3 per clipped record: source weights of its vertices
  std::vector<uint32_t> tile_begin;      // num_tiles + 1 offsets into tile_records
  std::vector<uint32_t> tile_records;    // record indices, grouped by tile, ascending
  GrowingArray<uint32_t> record_tiles;   // scratch: tiles each record overlaps (setup.cpp)
  std::vector<float> tile_area;          // per tile: records' area in it, px^2 (an estimate);
                                         // empty unless SetupParams::estimate_overdraw
};

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
  bool shade;              // fill SetupChunk::shading (else nothing shades)
  Isa isa;                 // kernels for eight faces at a time (the same records for either)
};

// Sets up faces [begin, end) of one draw and bins them (out is cleared first).
void setup_chunk(const SetupParams& params, std::size_t begin, std::size_t end, SetupChunk& out);

}  // namespace sr
