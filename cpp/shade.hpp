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
};

struct ShadeParams {
  const ShadeDraw* draws;
  Shading shading;
  vec3 to_light_world;  // unit vector toward the headlight (= toward the camera)
  float ambient;
  uint8_t background[3];
  bool orthographic;
  Framebuffer* framebuffer;
};

// A triangle visible in the tile being shaded, prepared once for all its pixels.
struct ShadeTriangle {
  int64_t edge_origin[3];  // E_k at the tile's first pixel centre (exact, fixed-point units^2)
  int64_t edge_step_x[3], edge_step_y[3];  // E_k change per pixel
  float persp[3];          // 1 / (w_k * area2): E_k * persp[k] ~ perspective-correct weight
  vec3 normal[3];          // world-space normal at each vertex (the face normal if flat), facing
                           // the camera's side for back faces
  vec3 color[3];           // base colour at each vertex
};

// Per-thread scratch for shade_tile.
struct ShadeScratch {
  std::vector<uint32_t> slot;  // binned-triangle index -> index in `triangles`, or kNoTriangle
  std::vector<ShadeTriangle> triangles;
};

// Writes every pixel of `tile` in each requested output. Each visible pixel is shaded once.
void shade_tile(const ShadeParams& params, const Viewport& viewport, int tile,
                const TileScratch& raster, ShadeScratch& scratch);

}  // namespace sr
