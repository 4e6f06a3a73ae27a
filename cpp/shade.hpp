// Shade stage: resolve each tile's visibility buffer into the requested outputs.
#pragma once

#include "framebuffer.hpp"
#include "rasterize.hpp"

namespace sr {

// What shading needs of one draw.
struct ShadeDraw {
  const MeshData* mesh;
  dmat3 normal_to_world;  // inverse-transpose of the model matrix (double: see prepare())
  vec4 color;            // material colour (used when the mesh has no vertex colours)
  int32_t instance_id;
  const vec3* world_normals;  // per vertex (world_normals()), or null: flat face normals
};

// World-space unit normals of vertices [begin, end) of a mesh with vertex normals, once per
// render rather than once per triangle corner and tile.
void world_normals(const MeshData& mesh, const dmat3& normal_to_world, std::size_t begin,
                   std::size_t end, Isa isa, vec3* out);

struct ShadeParams {
  const ShadeDraw* draws;
  Shading shading;
  vec3 to_light_world;  // unit vector toward the headlight (= toward the camera)
  float ambient;
  uint8_t background[3];
  bool orthographic;
  bool stream;  // write depth and colour with non-temporal stores (frames larger than caches)
  Framebuffer* framebuffer;
};
// Frames of at least this many output bytes are written with non-temporal stores: measured here
// (benchmarks/RESULTS.md), they spare a 16 MB depth frame the read of every line it overwrites
// (ico7 at 2048x2048 depth-only: -13% at 2 threads), while a 4 MB frame, which stays in cache
// from one render to the next, gets slower (+15%).
constexpr std::size_t kStreamFrameBytes = std::size_t(12) << 20;

// A triangle visible in the tile being shaded, prepared once for all its pixels.
// What varies across it picks the work per pixel (shade_group); each output is decided on its
// own, so an output's bits do not depend on which other outputs were requested:
//   colour  kConstantColor  one base colour, unlit or lit with one normal: a precomputed value;
//           kUniformLit     one base colour, lit, normals varying (smooth shading): the Lambert
//                           term dot(n, L) / |n| of the unnormalised interpolated normal, without
//                           normalising the weights (both are scale-invariant) or interpolating
//                           colours;
//           kVaryingColor   vertex colours: normalised weights, every attribute interpolated;
//   normal  one_normal: the precomputed unit normal, else the normalised interpolated normal.
struct ShadeTriangle {
  enum ColorKind : uint8_t { kVaryingColor, kUniformLit, kConstantColor };
  float persp[3];   // 1 / (w_k * area2) / max_k(1 / w_k): E_k * persp[k] ~ perspective-correct
                    // weight, scaled so that the largest is about 1 (no float underflow)
  vec3 normal[3];   // world-space normal at each vertex (the face normal if flat), facing the
                    // camera's side for back faces
  vec3 color[3];    // base colour at each vertex (only color[0] set where all are equal)
  ColorKind color_kind;
  bool one_normal;     // the three normals are equal
  uint32_t rgb;        // kConstantColor: the packed colour of every pixel (r | g << 8 | b << 16)
  vec3 unit_normal;    // one_normal: the unit normal of every pixel (zero if the normal is zero)
  float light_dot[3];  // kUniformLit: dot(normal[k], to_light_world)
  vec3 color255;       // kUniformLit: the base colour clamped to [0, 1], times 255
};

// Per-thread scratch for shade_tile: which binned triangles own a pixel, and the tile's shaded
// values (row stride kTileSizePx, padded like TileScratch) before they go to the framebuffer.
// Allocate default-initialised (new ShadeScratch): `normal` is then left untouched, which spares
// a first frame its page faults unless normals are an output (read only where shaded).
struct ShadeScratch {
  std::vector<uint8_t> used;  // per binned-triangle index: owns at least one pixel of the tile
  std::vector<uint32_t> large;  // forward shading: int64-path triangles left to a deferred pass
  uint32_t rgb[kTileScratchPixels] = {};  // packed 8-bit colour, r | g << 8 | b << 16 (whole
                                          // rows are read, background pixels' values discarded)
  float normal[3][kTileScratchPixels];
};

// Forward shading: rasterizes `tile` (as rasterize_tile) and shades each fragment as it wins the
// depth test, then writes the outputs as shade_tile does. The same bits as rasterize_tile +
// shade_tile; faster without overdraw (no second walk over each triangle), slower with much.
// Only when can_shade_forward(): colour or normals requested.
bool can_shade_forward(const ShadeParams& params);
void rasterize_and_shade_tile(const ShadeParams& params, const Viewport& viewport, int tile,
                              const std::vector<SetupChunk>& chunks, std::size_t num_chunks,
                              bool want_coverage, Isa isa, TileScratch& raster,
                              ShadeScratch& scratch);

// Writes every pixel of `tile` in each requested output. Each visible pixel is shaded once, by
// the kernel for `isa` (the same bits for either).
void shade_tile(const ShadeParams& params, const Viewport& viewport, int tile,
                const TileScratch& raster, Isa isa, ShadeScratch& scratch);

}  // namespace sr
