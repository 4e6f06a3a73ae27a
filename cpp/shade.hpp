// Shade stage: resolve each tile's visibility buffer into the requested outputs.
#pragma once

#include "framebuffer.hpp"
#include "rasterize.hpp"
#include "plan.hpp"
#include "shade_models.hpp"
#include "surface.hpp"

namespace sr {

struct LitKernels;

// What shading needs of one draw: its geometry, material and model, and what its triangles read
// (the plan's choices, made once per draw: renderer.cpp, shade_draw).
struct ShadeDraw {
  const MeshData* mesh;
  dmat3 normal_to_world;  // inverse-transpose of the model matrix (double: see prepare())
  vec4 color;            // material colour (used when the mesh has no vertex colours)
  Material material;
  Brdf brdf;             // its model in this render (the plan's choice)
  uint8_t needs;         // DrawNeeds bits (shade_models.hpp)
  int32_t instance_id;
  const vec3* world_normals;  // per vertex (world_normals()), or null: flat face normals
  dmat4 model_to_world;       // for models that read world positions
  dmat4 model_view;           // model -> view, double: the exact surface step (surface.hpp)
  // Everything its triangles interpolate takes the exact weights (its model reads world positions
  // or uvs: lights, textures, the uv and depth views); else only the normal output does
  // (normal_kind="interpolated"; "shading" gives the normal shading read, with its weights).
  bool exact_shading = false;
};

// What each group of a visible triangle's pixels does (shade_kernels.hpp, Prepared::work), decided
// once per triangle: the render's shaded outputs are run-time choices folded in here, not kernel
// axes (benchmarks/RESULTS.md, "What each kernel axis is worth").
enum ShadeWork : uint16_t {
  kWorkVaryingColor = 1,    // the colour output, interpolated (ShadeTriangle::kVaryingColor)
  kWorkVaryingNormal = 2,   // the normal output, interpolated
  kWorkUnitNormal = 4,      // the normal output, one for the whole triangle
  kWorkColor = 8,           // the colour output                     } the render's bits
  kWorkNormalOut = 16,      // the normal output (normalised here)   } (ShadeParams::work)
  kWorkLitCode = 32,        // colour, with codes for the light pass }
  kWorkShadingNormal = 64,  // the normal output with the normal or bump map applied (lit kernel)
  // The exact weights (ShadeTriangle::exact; interpolate.hpp, exact_weights) instead of the
  // snapped triangle's: for everything the triangle interpolates (its draw reads positions or
  // uvs: ShadeDraw::exact_shading), or for the normal output alone (the colour keeps its bits
  // whichever outputs are requested).
  kWorkExactWeights = 128,
  kWorkExactNormal = 256,
};
struct ShadeParams {
  const ShadeDraw* draws;
  bool color, normal;  // shaded outputs requested: colour (or radiance), normals
  uint16_t work;       // the render's ShadeWork bits
  ShadeInputs in;  // what shading reads (shade_models.hpp)
  const LitKernels* lit;  // lighting and textures out of line, for the render's instruction set
  uint8_t background[3];  // the colour output's background, as given (not encoded)
  bool orthographic;
  bool stream;  // write depth and colour with non-temporal stores (frames larger than caches)
  bool srgb;    // the colour output is sRGB-encoded (else linear), 8 bits
  Framebuffer* framebuffer;
  // Written outputs only (outputs.cpp):
  const mat3* normal_rotation;   // normals to camera space (normal_space="camera"), or null
  dvec3 camera_centre;           // world space (ray_depth of a perspective camera)
  ViewRays rays;                 // the exact surface step's rays (surface.hpp)
  dmat4 view_to_world;
  int32_t sample_x, sample_y;    // the pixels' sample (viewport.hpp): where surfaces are read
};
// The most raster passes one call of deferred shading takes (TileKernels::Deferred).
constexpr int kMaxShadePasses = 4;

// Per-thread scratch for shade_tile: which binned triangles own a pixel, and the tile's shaded
// values (row stride kTileSizePx, padded like TileScratch) before they go to the framebuffer.
// Allocate default-initialised (new ShadeScratch): `normal` is then left untouched, which spares
// a first frame its page faults unless normals are an output (read only where shaded).
struct ShadeScratch {
  std::vector<uint8_t> used;  // per binned-triangle index, kMaxShadePasses bytes: owns a pixel
                              // in that pass (deferred shading, ShadeVisible)
  std::vector<uint32_t> large;  // forward shading: int64-path triangles left to a deferred pass
  float rgb[3][kTileScratchPixels] = {};  // linear radiance, one plane per channel (whole rows
                                          // are read, background pixels' values discarded)
  float normal[3][kTileScratchPixels];
  // The lit model's light pass (shade_kernels.hpp, light_tile): a pixel whose lighting is left to
  // it holds its base colour in `rgb`, and here its lit normal, world position and a code naming
  // its draw (4 (draw + 1), + 2 if the normal is still to be normalised, + 1 if lighting reads
  // positions; 0: `rgb` is already the radiance).
  // Lighting full groups of eight pixels of the tile, whichever triangles they belong to, costs
  // less than lighting each small triangle's partly filled groups. Zeroed once (a group's unused
  // lanes are read).
  float lit_normal[3][kTileScratchPixels] = {};
  float lit_position[3][kTileScratchPixels] = {};
  int32_t lit_code[kTileScratchPixels] = {};
  bool lit_pending = false;  // some pixel of the tile waits for the light pass
};

// The tile kernels for one render's choices (instruction set, sample pattern, shading model,
// colour and normal outputs, coverage counting), picked once per render (dispatch.hpp);
// `forward` and `deferred` are null when nothing is shaded (RenderPlan::shade false).
struct TileKernels {
  RasterizeFn raster = nullptr;
  RasterizeSamplesFn raster_samples = nullptr;  // a pattern of several samples (multisample.cpp)
  // Shades `passes` (<= kMaxShadePasses) raster passes of a tile, each into its own scratch
  // (msaa's samples; one pass otherwise).
  using Deferred = void (*)(const ShadeParams&, const TileRect&, const TileScratch* const*,
                            ShadeScratch* const*, int passes);
  using Forward = void (*)(const ShadeParams&, const TileRect&, int, const std::vector<SetupChunk>&,
                           std::size_t, TileScratch&, ShadeScratch&);
  Deferred deferred = nullptr;
  Forward forward = nullptr;
  Isa isa = Isa::Generic;
  bool coverage = false;
};
// kind: the plan's choice of shading kernel (shade_models.hpp, KernelKind).
TileKernels select_tile_kernels(const RenderPlan& plan, const Viewport& viewport, Isa isa,
                                KernelKind kind);

// Deferred shading of one raster pass (kernels.deferred not null).
inline void shade_deferred(const TileKernels& kernels, const ShadeParams& params,
                           const TileRect& rect, const TileScratch& raster, ShadeScratch& out) {
  const TileScratch* rasters[1] = {&raster};
  ShadeScratch* outs[1] = {&out};
  kernels.deferred(params, rect, rasters, outs, 1);
}

// Forward shading: rasterizes `tile` (as rasterize_tile) and shades each fragment as it wins the
// depth test. The same bits as rasterize_tile + shade_deferred; faster without overdraw (no
// second walk over each triangle), slower with much. Only when the plan shades.
inline void shade_forward(const TileKernels& kernels, const ShadeParams& params,
                          const TileRect& rect, int tile, const std::vector<SetupChunk>& chunks,
                          std::size_t num_chunks, TileScratch& raster, ShadeScratch& out) {
  raster.clear(kernels.coverage, rect.y1 - rect.y0);
  kernels.forward(params, rect, tile, chunks, num_chunks, raster, out);
}

}  // namespace sr
